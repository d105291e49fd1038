"""A plain (non-editable) install is a working tool.

The wheel is built from the tracked files (a copy, so the checkout is not
touched), must contain the MJCF and every shipped scenario, and, installed
into an empty folder on its own, runs the main job from another empty folder.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _tracked_files() -> list[str]:
    try:
        out = subprocess.run(
            ["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: the wheel is built from the tracked files")
    return [line for line in out.splitlines() if (ROOT / line).is_file()]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    src = tmp_path_factory.mktemp("src")
    for name in _tracked_files():
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, src / name)
    dist = tmp_path_factory.mktemp("dist")
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
         "--no-index", "-q", "-w", str(dist), str(src)],
        capture_output=True, text=True,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    (whl,) = dist.glob("simpro_sim-*.whl")
    return whl


def test_the_wheel_holds_the_model_and_every_shipped_scenario(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    assert "simpro_mj/models/simpro_platform.xml" in names
    assert "simpro_mj/models/README.md" in names
    # the top-level data folders, mapped into the package by setup.py
    shipped = [
        p.relative_to(ROOT).as_posix()
        for folder in ("scenarios", "scenarios/telemetry", "scenarios/presets", "scenarios/rigs")
        for p in (ROOT / folder).iterdir()
        if p.suffix in (".yaml", ".csv")
    ]
    assert "scenarios/step_pitch.yaml" in shipped
    assert "scenarios/presets/paper.yaml" in shipped
    assert "scenarios/rigs/wide_base.yaml" in shipped
    assert "scenarios/telemetry/braking_100kmh.csv" in shipped
    missing = [s for s in shipped if f"simpro_mj/{s}" not in names]
    assert not missing, missing
    assert not [n for n in names if n.startswith("tests/")]


def test_the_wheel_holds_every_package(wheel):
    """Every tracked package (a folder with ``__init__.py``) of simpro_mj and
    controllers is in the wheel: a subpackage missing from the package list would
    be supplied from the checkout by the test venv's editable install and go
    unseen by the run below."""
    names = set(zipfile.ZipFile(wheel).namelist())
    packages = sorted(
        f for f in _tracked_files() if f.endswith("/__init__.py") and not f.startswith("tests/")
    )
    assert "controllers/analysis/__init__.py" in packages
    missing = [f for f in packages if f not in names]
    assert not missing, missing


def test_the_installed_wheel_runs_the_main_job_from_an_empty_folder(wheel, tmp_path):
    site = tmp_path / "site"
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "-q",
         "--target", str(site), str(wheel)],
        capture_output=True, text=True,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    work = tmp_path / "empty"
    work.mkdir()
    # the installed copy, not the checkout: PYTHONPATH comes before the editable finder
    # the interpreted step: the same source files as the compiled one, which would
    # otherwise be compiled afresh for this copy (about 25 s) to test what the
    # checkout's runs already test
    env = dict(os.environ, PYTHONPATH=str(site), MPLBACKEND="Agg", SIMPRO_KERNEL="python")
    env.pop("SIMPRO_MODEL", None)
    env.pop("SIMPRO_SCENARIOS", None)
    code = (
        # without the test venv's editable finder, which would supply any module the
        # wheel lacks from the checkout (it is consulted after PYTHONPATH's folder)
        "import sys; "
        "sys.meta_path[:] = [f for f in sys.meta_path if '__editable__' not in "
        "getattr(f, '__module__', '') and '__editable__' not in getattr(f, '__name__', '')]; "
        "import simpro_mj, controllers; "
        "print(simpro_mj.__file__); print(controllers.__file__); "
        "from simpro_mj.commands.main import main; sys.exit(main())"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code, "run", "step_pitch.yaml", "--no-plots",
         "--set", "duration_s=0.3"],
        cwd=work, env=env, capture_output=True, text=True,
    )  # fmt: skip
    # 0.3 s ends before the pose has settled from its start: the verdict may say so (exit 1)
    metrics = work / "results" / "step_pitch+duration_s=0.3" / "metrics.json"
    status = json.loads(metrics.read_text())["status"]
    assert status in ("ok", "not_settled"), proc.stderr[-2000:]
    assert proc.returncode == (0 if status == "ok" else 1), proc.stderr[-2000:]
    first, second = proc.stdout.splitlines()[:2]
    assert first.startswith(str(site)) and second.startswith(str(site)), proc.stdout


def test_the_data_folders_are_tracked_once_at_the_top_level():
    """The design card's layout: ``models/`` and ``scenarios/`` at the top, one copy
    in git (the wheel's copy is made by the build), and no symlink in the tree."""
    tracked = subprocess.run(
        ["git", "ls-files", "-s"], cwd=ROOT, capture_output=True, text=True
    ).stdout.splitlines()
    if not tracked:
        pytest.skip("not a git checkout")
    paths = {line.split("\t", 1)[1]: line.split()[0] for line in tracked}
    assert "models/simpro_platform.xml" in paths
    assert "scenarios/step_pitch.yaml" in paths
    names = [Path(p).name for p in paths if p.endswith((".xml", ".yaml", ".csv"))]
    twice = sorted({n for n in names if n.startswith(("simpro_platform", "step_pitch"))})
    assert [n for n in names if n in twice] == twice, "a second copy of the model or a scenario"
    assert not [p for p in paths if p.startswith(("simpro_mj/models/", "simpro_mj/scenarios/"))]
    links = [p for p, mode in paths.items() if mode == "120000"]
    assert not links, links
