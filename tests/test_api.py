"""The Python API (``import simpro_mj as s; s.run(...)``)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import simpro_mj as s
from simpro_mj.config.scenario import load_scenario
from simpro_mj.sim.build import simulate

ROOT = Path(__file__).resolve().parents[1]


def _python(code: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    return subprocess.run(
        [sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True
    )


def test_importing_the_package_the_controllers_or_the_actuator_params_skips_mujoco(tmp_path):
    proc = _python(
        "import sys, simpro_mj, controllers, controllers.kinematics, controllers.analysis; "
        # the scenario room too: loading and validating a scenario (its typed models, a
        # sweep's variants) reads defaults and checks values, it builds no plant
        "import simpro_mj.config.scenario as sc, simpro_mj.config.variants as va; "
        "sc.load_scenario('step_pitch'); sc.scenario_model(sc.load_scenario('cue_braking')); "
        "va.load_sweep('sweep_outer_gain'); "
        # the actuator parameters: the scenario validates actuator.pneumatics with them
        "import simpro_mj.plant.pneumatics.params; "
        "before = 'mujoco' in sys.modules; "
        # the check sees MuJoCo when it is loaded: the actuator factory needs it
        "import simpro_mj.plant.pneumatics.factory; "
        "print(before, 'mujoco' in sys.modules)",
        tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "False True"


def test_the_readme_example_runs_from_any_folder(tmp_path):
    proc = _python(
        "import simpro_mj as s; print(s.run('step_pitch', {'duration_s': 2}).metrics)",
        tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    # the 3 deg step at 1 s settles in about 1.5 s: at 2 s the pose still moves
    assert "'status': 'not_settled'" in proc.stdout
    assert list(tmp_path.iterdir()) == []  # nothing written without out=


def test_run_is_the_simulation_of_the_resolved_scenario():
    r = s.run("step_pitch", {"duration_s": 0.5, "controller.outer.type": "PI"})
    assert r.scenario.controller.outer.type == "PI"
    # 0.5 s: the outer loop is still removing the as-built error; the verdict says so
    assert r.status == r.metrics["verdict"]["status"] and r.reason == r.metrics["verdict"]["reason"]
    direct = simulate(load_scenario("step_pitch", ["duration_s=0.5", "controller.outer.type=PI"]))
    assert r.columns.keys() == direct.columns.keys()
    for k, v in direct.columns.items():
        assert np.array_equal(r.columns[k], v), k
    assert r.columns["time_s"][-1] == pytest.approx(0.5)
    json.dumps(r.metrics)  # plain JSON types, as metrics.json


def test_a_mapping_scenario_and_compare():
    doc = {"duration_s": 0.4, "setpoint": {"pitch_deg": [{"type": "step", "time_s": 0.1,
                                                          "value": 1.0}]}}  # fmt: skip
    both = s.compare(doc)
    assert set(both) == {"joint_only", "task_space"}
    assert both["joint_only"].scenario.controller.mode == "joint_only"
    assert both["task_space"].scenario.controller.mode == "task_space"
    # the same plant and seed: the two runs differ only by the controller
    a, b = both["joint_only"].columns, both["task_space"].columns
    assert np.array_equal(a["pitch_ref_rad"], b["pitch_ref_rad"])
    assert not np.array_equal(a["q1_ref_m"], b["q1_ref_m"])


def test_out_writes_the_result_folder(tmp_path):
    r = s.run("step_pitch", {"duration_s": 0.3}, out=tmp_path / "r")
    assert r.out == tmp_path / "r"
    doc = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert doc["status"] == r.status == doc["metrics"]["verdict"]["status"]


@pytest.mark.parametrize(
    "overrides, words",
    [
        ({"duration_s": "long"}, ["duration_s", "allowed"]),
        ({"no_such.key": 1}, ["unknown key", "allowed keys"]),
        ({"duration_s": float("nan")}, ["duration_s", "allowed"]),
        ([("duration_s", 1)], ["overrides", "mapping"]),
    ],
)
def test_mistakes_raise_one_line_user_input_errors(overrides, words):
    with pytest.raises(s.UserInputError) as info:
        s.run("step_pitch", overrides)
    msg = str(info.value)
    assert "\n" not in msg and all(w in msg for w in words), msg
    assert isinstance(info.value, ValueError)


def test_result_to_frame():
    pd = pytest.importorskip("pandas")
    r = s.run("step_pitch", {"duration_s": 0.05})
    df = r.to_frame()
    assert isinstance(df, pd.DataFrame) and df.index.name == "time_s"
    assert len(df) == len(r.columns["time_s"])


def test_load_scenario_is_load():
    over = {"duration_s": 2}
    assert s.load_scenario("step_pitch", over) == s.load("step_pitch", over)


def test_plot_draws_the_run_and_refuses_an_unknown_figure(tmp_path):
    r = s.run("step_pitch", {"duration_s": 1.2})
    fig = r.plot()  # task space, Fig. 16's layout: roll, pitch (deg), height (mm)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 3
    lines = {ln.get_label(): ln for ln in axes[1].get_lines()}
    # the pitch panel's desired and output lines are the logged columns in degrees
    np.testing.assert_allclose(lines["desired"].get_ydata(), np.degrees(r.columns["pitch_ref_rad"]))
    np.testing.assert_allclose(lines["output"].get_ydata(), np.degrees(r.columns["pitch_rad"]))
    assert max(lines["desired"].get_ydata()) == pytest.approx(3.0)  # the 3 deg step at 1 s
    png = tmp_path / "valves.png"
    r.plot("valves", png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(s.UserInputError) as info:
        r.plot("valvs")
    msg = str(info.value)
    assert "\n" not in msg and "allowed: task_space, joints, valves, pressures" in msg
    assert "did you mean 'valves'?" in msg


def test_sweep_runs_each_variant_as_run_would(tmp_path):
    f = tmp_path / "gains.yaml"
    f.write_text(
        "name: gains\nduration_s: 0.4\n"
        "setpoint:\n  pitch_deg:\n    - {type: step, time_s: 0.1, value: 1.0}\n"
        "sweep:\n  grid:\n    controller.outer.gains: [2, 3, -1]\n"
    )
    sw = s.sweep(f)
    assert len(sw.values) == 3 and len(sw.results) == 2 and len(sw.errors) == 1
    (bad,) = sw.errors.values()
    assert "\n" not in bad and "controller.outer.gains" in bad
    rows = {r["variant"]: r for r in sw.rows()}
    statuses = sorted(r["status"] for r in rows.values())
    assert statuses[0] == "invalid" and set(statuses[1:]) <= {"ok", "not_settled"}
    for name, res in sw.results.items():
        gain = rows[name]["controller.outer.gains"]
        alone = s.run(f, {"controller.outer.gains": [gain] * 3})
        alone_cols = alone.columns
        for k in ("pitch_rad", "q1_m", "u1_v"):
            assert np.array_equal(res.columns[k], alone_cols[k]), (name, k)
        assert rows[name]["pitch_overshoot_pct"] == res.metrics["axes"]["pitch"]["overshoot_pct"]
    assert list(tmp_path.iterdir()) == [f]  # nothing written
    with pytest.raises(s.UserInputError):
        s.sweep(f, jobs=0)


def test_sweep_on_threads_equals_the_serial_sweep(tmp_path, monkeypatch):
    """jobs=2 runs the variants on threads of this process (no pool), with the serial bits."""
    from simpro_mj.sim import executors

    f = tmp_path / "gains.yaml"
    f.write_text(
        "name: gains\nduration_s: 0.4\n"
        "setpoint:\n  pitch_deg:\n    - {type: step, time_s: 0.1, value: 1.0}\n"
        "sweep:\n  grid:\n    controller.outer.gains: [2, 3, 4]\n"
    )
    serial = s.sweep(f)

    def no_pool(*args, **kwargs):
        raise AssertionError("a process pool started")

    monkeypatch.setattr(executors, "run_pool", no_pool)
    threaded = s.sweep(f, jobs=2)
    assert sorted(threaded.results) == sorted(serial.results) and len(serial.results) == 3
    for name, res in serial.results.items():
        other = threaded.results[name]
        assert res.columns.keys() == other.columns.keys()
        for k, x in res.columns.items():
            assert np.array_equal(x, other.columns[k], equal_nan=True), (name, k)
        assert other.metrics["axes"] == res.metrics["axes"]
    # the gains differ, so do the runs: the comparison sees the variants apart
    a, b = (serial.results[n].columns["pitch_rad"] for n in sorted(serial.results)[:2])
    assert not np.array_equal(a, b)
    with pytest.raises(s.UserInputError, match="invalid processes"):
        s.sweep(f, jobs=2, processes="yes")


def test_the_docs_example_runs(tmp_path):
    """docs/examples/quickstart.py, the API's walk-through, runs from any folder and
    writes only into the folder it is given."""
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, str(ROOT / "docs" / "examples" / "quickstart.py"), str(out)],
        cwd=tmp_path,
        env=dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg"),
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    assert "step_pitch: ok, overshoot" in text and "K K_I = 2: overshoot" in text
    assert "joint_only: pitch steady-state error" in text
    # the two variants of the sweep, each with the verdict on its end
    assert len(re.findall(r"^\S+ (ok|not_settled) pitch overshoot ", text, re.M)) == 2
    assert (out / "step_pitch.png").stat().st_size > 10_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_no_command_loads_mujoco_before_it_runs(tmp_path):
    """Each command module imports without MuJoCo (0.35 s of import, more under
    load), so that a mistake on the command line is refused within a second;
    MuJoCo loads when a plant is built."""
    from simpro_mj.commands.main import COMMANDS

    code = (
        "import importlib, sys; "
        f"[importlib.import_module(p) for p in {sorted(COMMANDS.values())!r}]; "
        "print('mujoco' in sys.modules)"
    )
    proc = _python(code, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "False"


def test_identify_and_calibrate_refuse_their_settings_before_loading_mujoco(tmp_path):
    """The identification tree is built and checked without MuJoCo or SciPy's optimiser,
    so a mistyped preset or key is refused (exit 2) before the experiment's imports.

    The three refusals run one after the other in one process: modules only accumulate,
    so after each one neither import has happened yet."""
    argvs = [
        ["calibrate", "--start", "nosuch"],
        ["calibrate", "--set", "pneumatics.nosuch=1"],
        ["identify", "--set", "identify.duration_s=-1"],
    ]
    code = (
        "import sys; from simpro_mj.commands.main import main\n"
        f"for argv in {argvs!r}:\n"
        "    rc = main(argv)\n"
        "    print(rc, 'mujoco' in sys.modules, 'scipy.optimize' in sys.modules, flush=True)\n"
        "    print('--', file=sys.stderr, flush=True)\n"
    )
    # without MUJOCO_GL: with it set, main() loads MuJoCo first to check the GL backend
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    env.update(PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    said = proc.stdout + proc.stderr
    assert proc.stdout.splitlines() == ["2 False False"] * len(argvs), said
    errors = proc.stderr.split("--\n")
    assert len(errors) == len(argvs) + 1 and errors[-1] == "", said
    for err in errors[:-1]:  # one line each
        assert len(err.strip().splitlines()) == 1 and err.startswith("error: "), said
