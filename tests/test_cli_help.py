"""``--help`` stays quick: counted in modules imported, not timed.

``simpro-sim --help`` reads each command's one-line ``HELP`` from its source and
imports none of them; a command's own ``--help`` imports its module only, and no
module imports the heavy numerical libraries (scipy, MuJoCo, matplotlib, numba,
pandas, python-control) before the command runs. Each case is a fresh interpreter,
so what the test process imported before does not count.
"""

from __future__ import annotations

import json
import subprocess
import sys

from simpro_mj.commands.main import COMMANDS

HEAVY = ("scipy", "mujoco", "matplotlib", "numba", "pandas", "control", "osqp")

PROBE = r"""
import contextlib, io, json, sys
from simpro_mj.commands.main import main
with contextlib.redirect_stdout(io.StringIO()) as out:
    code = main(sys.argv[1:])
print(json.dumps({"code": code, "help": out.getvalue(), "modules": sorted(sys.modules)}))
"""


def _help(*words: str) -> dict:
    r = subprocess.run([sys.executable, "-c", PROBE, *words, "--help"], capture_output=True,
                       text=True, timeout=120)  # fmt: skip
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def test_the_top_level_help_imports_no_command_and_no_numerics():
    got = _help()
    assert got["code"] == 0
    for name in COMMANDS:  # every command listed with its one line
        assert f"    {name}" in got["help"], name
    modules = set(got["modules"])
    commands = {m for m in modules if m.startswith("simpro_mj.commands.")}
    assert commands == {"simpro_mj.commands.main"}
    assert not {"numpy", "pydantic", "yaml", *HEAVY} & modules


def test_no_command_help_imports_the_heavy_numerics():
    for name in COMMANDS:
        got = _help(name)
        assert got["code"] == 0 and "usage: simpro-sim " + name in got["help"], name
        modules = set(got["modules"])
        assert not set(HEAVY) & modules, (name, sorted(set(HEAVY) & modules))


def test_the_first_commands_help_imports_no_numerics():
    """The README's commands: their --help reads as quickly as the top level's."""
    for name in ("run", "compare", "list"):
        modules = set(_help(name)["modules"])
        assert not {"numpy", "pydantic", "yaml"} & modules, (name, modules & {"numpy"})
