"""``--help`` stays quick: counted in modules imported, not timed.

``simpro-sim --help`` reads each command's one-line ``HELP`` from its source and
imports none of them; a command's own ``--help`` imports its module only, and no
module imports the heavy numerical libraries (scipy, MuJoCo, matplotlib, numba,
pandas, python-control) before the command runs. Each case starts from a fresh
interpreter that has imported the command table (where the platform forks, a fork of
one interpreter per test: the same state without a start-up per command), so what the
test process or an earlier case imported does not count. The heavy-numerics case also
has the scenario's modules imported first (numpy, pydantic, PyYAML: 0.6 s of each
command's import otherwise): a module imported there that imported a heavy library
would put it in every case's modules, so the check holds as it does without them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from simpro_mj.commands.main import COMMANDS

HEAVY = ("scipy", "mujoco", "matplotlib", "numba", "pandas", "control", "osqp")

PROBE = r"""
import contextlib, io, json, os, sys
from simpro_mj.commands.main import main


def case(argv):
    with contextlib.redirect_stdout(io.StringIO()) as out:
        code = main(argv)
    return {"code": code, "help": out.getvalue(), "modules": sorted(sys.modules)}


for name in json.loads(sys.argv[1]):  # imported before any case
    __import__(name)
cases = [json.loads(a) for a in sys.argv[2:]]
if not hasattr(os, "fork"):
    print(json.dumps([case(cases[0])]))
    sys.exit()
found = []
for argv in cases:  # each in a child: this interpreter as it is before any command
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        try:
            os.close(r)
            with os.fdopen(w, "w") as f:
                json.dump(case(argv), f)
        finally:
            os._exit(0)
    os.close(w)
    with os.fdopen(r) as f:
        found.append(json.loads(f.read() or "null"))
    os.waitpid(pid, 0)
print(json.dumps(found))
"""


def _helps(*cases: list[str], preload: tuple[str, ...] = ()) -> list[dict]:
    """What ``simpro-sim <case> --help`` printed and imported, each case from the same
    fresh interpreter state, with the modules ``preload`` imported (module docstring)."""
    argvs = [json.dumps([*words, "--help"]) for words in cases]
    groups = [argvs] if hasattr(os, "fork") else [[a] for a in argvs]
    found = []
    for group in groups:
        r = subprocess.run([sys.executable, "-c", PROBE, json.dumps(preload), *group],
                           capture_output=True, text=True, timeout=120)  # fmt: skip
        assert r.returncode == 0, r.stderr
        found += json.loads(r.stdout)
    assert None not in found, r.stderr  # a case whose child wrote nothing
    return found


def _help(*words: str) -> dict:
    return _helps(list(words))[0]


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
    found = _helps(*([name] for name in COMMANDS), preload=("simpro_mj.config.scenario",))
    for name, got in zip(COMMANDS, found, strict=True):
        assert got["code"] == 0 and "usage: simpro-sim " + name in got["help"], name
        modules = set(got["modules"])
        assert not set(HEAVY) & modules, (name, sorted(set(HEAVY) & modules))


def test_the_first_commands_help_imports_no_numerics():
    """The README's commands: their --help reads as quickly as the top level's."""
    names = ("run", "compare", "list")
    for name, got in zip(names, _helps(*([name] for name in names)), strict=True):
        modules = set(got["modules"])
        assert not {"numpy", "pydantic", "yaml"} & modules, (name, modules & {"numpy"})
