"""The ``simpro-sim`` console script (:func:`simpro_mj.commands.main.cli`): the command,
then the objects left frozen so that the interpreter's exit does not collect them."""

import gc
import sys

from simpro_mj.commands.main import cli


def test_the_script_returns_the_commands_code_and_freezes_what_is_left(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["simpro-sim", "--version"])
    try:
        assert gc.get_freeze_count() == 0
        assert cli() == 0
        assert gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()
    assert capsys.readouterr().out.startswith("simpro-sim ")
    monkeypatch.setattr(sys, "argv", ["simpro-sim", "no-such-command"])
    try:
        assert cli() == 2  # a mistake's code, as main() returns it
    finally:
        gc.unfreeze()
