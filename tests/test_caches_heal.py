"""Caches keyed by everything they depend on, verified on load, healed with a notice.

Each damaged cache file (not JSON, NaN, nested past the parser's depth, the
wrong shape, a FIFO) is computed again with one ``notice:`` line, and the
answer equals a fresh cache's. The MJCF's bytes are in the identification key
and in the scenario hash; ``SIMPRO_MODEL`` that is not the platform's MJCF is
a one-line refusal."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

import simpro_mj.identification.auto as ai
from simpro_mj.analysis import stability
from simpro_mj.analysis.preflight import stability_limit
from simpro_mj.config.scenario import load_scenario, scenario_hash
from simpro_mj.core import cache
from simpro_mj.core.shipped import MODEL_DIR
from simpro_mj.report import marker

IDENT = ["controller.inner.design_plant=identified", "plant.payload.mass_kg=80"]
DAMAGES = {
    "not JSON": "{not json",
    "NaN": json.dumps(
        {f"actuator{i}": {"b": 11.0, "a1": 20.0, "a0": 180.0} for i in (1, 2, 3)}
    ).replace("180.0", "NaN", 1),
    "nested": "[" * 100_000,
    "wrong shape": '{"actuator1": [1, 2, 3]}',
}


@pytest.fixture
def fake_identify(fake_identify, tmp_path, monkeypatch):
    """The shared fake experiment, in an empty cache of its own."""
    monkeypatch.setenv("SIMPRO_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(ai, "_memo", {})
    return fake_identify


@pytest.mark.parametrize("damage", DAMAGES)
def test_a_damaged_identification_is_identified_again_with_a_notice(fake_identify, capsys, damage):
    sc = load_scenario("step_pitch", IDENT)
    fresh, _ = ai.identified_models(sc)
    (path,) = ai.cache_dir().glob("*.json")
    path.write_text(DAMAGES[damage])
    ai._memo.clear()
    capsys.readouterr()
    models, source = ai.identified_models(sc)
    notice = capsys.readouterr().err.strip().splitlines()
    assert source == "identified" and models == fresh and len(fake_identify) == 2
    assert len(notice) == 1 and notice[0].startswith(f"notice: cache file {path} is damaged")
    ai._memo.clear()
    assert ai.identified_models(sc) == (fresh, "cache")  # healed: read back, no notice
    assert capsys.readouterr().err == ""


def test_a_fifo_at_a_cache_path_is_never_waited_on(tmp_path):
    """In a child with a timeout: a regression fails rather than hangs."""
    code = (
        "import os, sys\n"
        "from simpro_mj.core import cache\n"
        f"path = {str(tmp_path / 'x.json')!r}\n"
        "os.mkfifo(path)\n"
        "assert cache.read_json(path) is None\n"
        "cache.write_json(path, {'limit': 1.5})\n"
        "assert cache.read_json(path) == {'limit': 1.5}\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stderr.startswith("notice: cache file") and "a FIFO (named pipe)" in r.stderr


def test_a_nan_stability_limit_is_computed_again(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("SIMPRO_CACHE_DIR", str(tmp_path))
    sc = load_scenario("step_pitch")
    stability._analysed.cache_clear()
    fresh = stability_limit(sc)["limit"]
    (path,) = cache.cache_dir("stability").glob("*.json")
    doc = json.loads(path.read_text())
    path.write_text(json.dumps({**doc, "limit": float("nan")}))
    stability._analysed.cache_clear()
    capsys.readouterr()
    assert stability_limit(sc)["limit"] == fresh  # the gain refusal keeps its limit
    assert "is damaged (NaN)" in capsys.readouterr().err
    stability._analysed.cache_clear()


def _edited_copy(tmp_path: Path) -> Path:
    text = (MODEL_DIR / "simpro_platform.xml").read_text()
    path = tmp_path / "edited.xml"
    path.write_text(text.replace("<mujoco", "<!-- edited -->\n<mujoco", 1))
    return path


def test_the_mjcf_is_in_the_identification_key_and_the_scenario_hash(
    fake_identify, tmp_path, monkeypatch
):
    sc = load_scenario("step_pitch", IDENT)
    h, key = scenario_hash(sc), ai.plant_hash(ai.plant_tree(sc))
    copy = tmp_path / "same.xml"
    copy.write_bytes((MODEL_DIR / "simpro_platform.xml").read_bytes())
    monkeypatch.setenv("SIMPRO_MODEL", str(copy))  # the same bytes elsewhere: the same run
    assert (scenario_hash(sc), ai.plant_hash(ai.plant_tree(sc))) == (h, key)
    monkeypatch.setenv("SIMPRO_MODEL", str(_edited_copy(tmp_path)))
    assert scenario_hash(sc) != h and ai.plant_hash(ai.plant_tree(sc)) != key


def test_nested_json_in_a_result_is_not_ours_and_not_complete(tmp_path):
    r = tmp_path / "r"
    r.mkdir()
    (r / marker.RESULT_MARKER).write_text("[" * 100_000)
    assert marker.result_kind(r) is None and not marker.is_complete(r)
    assert marker.result_hash(r) is None


def _cpu() -> float:
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


@pytest.mark.parametrize("case", ["missing", "broken", "another MJCF", "FIFO", "/dev/zero"])
def test_simpro_model_that_is_not_the_platform_is_refused_in_one_line(tmp_path, case):
    path = {
        "missing": tmp_path / "none.xml",
        "broken": tmp_path / "broken.xml",
        "another MJCF": tmp_path / "other.xml",
        "FIFO": tmp_path / "fifo.xml",
        "/dev/zero": Path("/dev/zero"),
    }[case]
    (tmp_path / "broken.xml").write_text("<mujoco><worldbody>")
    (tmp_path / "other.xml").write_text("<mujoco><worldbody><body name='x'/></worldbody></mujoco>")
    os.mkfifo(tmp_path / "fifo.xml")
    env = dict(os.environ, SIMPRO_MODEL=str(path))
    cpu0 = _cpu()
    r = subprocess.run(
        [sys.executable, "-m", "simpro_mj.commands.main", "run", "step_pitch.yaml",
         "--no-plots", "--out", str(tmp_path / "o")],
        capture_output=True, text=True, timeout=60, env=env,
    )  # fmt: skip
    assert r.returncode == 2, r.stderr
    (line,) = r.stderr.splitlines()
    assert line.startswith("error: invalid value at SIMPRO_MODEL: ")
    assert _cpu() - cpu0 < 2.0 and not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "env, argv, said",
    [
        ({"NUMBA_NUM_THREADS": "0"}, ["run", "step_pitch"], "at NUMBA_NUM_THREADS: '0'"),
        ({}, ["run", "~nouser_simpro/s.yaml"], "unknown user at scenario"),
        ({}, ["run", "step_pitch", "--out", "~nouser_simpro/r"], "unknown user at --out"),
        (
            {},
            ["run", "step_pitch", "--set", "plant.preset=~nouser_simpro/p.yaml"],
            "unknown user at plant.preset",
        ),
        ({}, ["batch", "step_pitch", "--scheduler", "tls://127.0.0.1:1"], "scheme 'tls'"),
        ({}, ["batch", "step_pitch", "--scheduler", "ucx://127.0.0.1:1"], "scheme 'ucx'"),
    ],
    ids=["numba-threads-0", "user-scenario", "user-out", "user-preset", "tls", "ucx"],
)
def test_the_environment_and_user_paths_are_checked_in_one_line(tmp_path, env, argv, said):
    cpu0 = _cpu()
    r = subprocess.run(
        [sys.executable, "-m", "simpro_mj.commands.main", *argv, "--no-plots"],
        capture_output=True, text=True, timeout=60, cwd=tmp_path, env={**os.environ, **env},
    )  # fmt: skip
    assert r.returncode == 2, r.stderr
    (line,) = r.stderr.splitlines()
    assert line.startswith("error: ") and said in line
    assert _cpu() - cpu0 < 2.0 and list(tmp_path.iterdir()) == []
