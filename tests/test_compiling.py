"""The compiled step is what a plain install runs, and its compile is said and timed apart.

numba is a dependency of the package (not an extra), so the README's first command
runs the compiled step. A first compile is announced on one line and kept out of the
run's ``realtime_factor``; ``metrics.json`` records it under ``sim.wall_clock``.
The compile of the real step takes 40-45 s, so the announcing is tested on a
module of one small function compiled the same way (numba's ``numba:compile`` events).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from simpro_mj.sim import compiling

ROOT = Path(__file__).resolve().parents[1]

PROBE = """
from numba import njit


@njit
def plus_one(x):
    return x + 1


@njit
def twice_plus_one(x):
    return 2 * plus_one(x)


VALUE = twice_plus_one(20)
"""


def test_numba_is_a_dependency_not_an_extra():
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = [d.split(">")[0].split("=")[0].split("[")[0].strip() for d in project["dependencies"]]
    assert "numba" in names
    for extra, deps in project.get("optional-dependencies", {}).items():
        assert not any(d.startswith("numba") for d in deps), extra


@pytest.fixture
def probe(tmp_path, monkeypatch):
    """A module that numba compiles when imported (no cache: it compiles every time)."""
    name = f"simpro_probe_{tmp_path.name.replace('-', '_')}"
    (tmp_path / f"{name}.py").write_text(PROBE)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield name
    sys.modules.pop(name, None)


def test_a_compile_is_announced_and_counted(probe):
    said: list[str] = []
    got = compiling.load_module(probe, said.append, False, lambda: 2, (probe,))
    assert sys.modules[probe].VALUE == 42
    assert said[0] == compiling.COMPILE_NOTE
    assert said[1].startswith("compiled the step in ") and said[1].endswith("(2 functions)")
    assert len(said) == 2
    assert got["kernel_compiled"] is True and got["kernel_load_s"] > 0


def test_a_loaded_module_is_not_compiled_again(probe):
    compiling.load_module(probe, None, False, lambda: 2, (probe,))
    said: list[str] = []
    got = compiling.load_module(probe, said.append, False, lambda: 2, (probe,))
    assert said == [] and got["kernel_compiled"] is False


def test_nothing_said_without_a_compile(tmp_path, monkeypatch):
    name = f"simpro_plain_{tmp_path.name.replace('-', '_')}"
    (tmp_path / f"{name}.py").write_text("VALUE = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    said: list[str] = []
    try:
        got = compiling.load_module(name, said.append, False, lambda: None, (name,))
    finally:
        sys.modules.pop(name, None)
    assert said == [] and got["kernel_compiled"] is False


def test_a_run_records_the_load_apart_from_its_realtime_factor(tmp_path, monkeypatch):
    from simpro_mj.commands.main import main

    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    out = tmp_path / "r"
    args = ["run", "step_pitch.yaml", "--set", "duration_s=0.3", "--no-plots", "--quiet"]
    assert main([*args, "--out", str(out)]) in (0, 1)  # 0.3 s: settled or not, it ran
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["versions"]["kernels"].startswith("numba ")
    wall = doc["sim"]["wall_clock"]
    assert wall["kernel_load_s"] >= 0 and isinstance(wall["kernel_compiled"], bool)
    assert "simpro_mj.sim.callback" in sys.modules  # loaded before the run stepped
