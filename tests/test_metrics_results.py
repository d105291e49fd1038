"""Metrics against analytic step responses; results folder written atomically."""

import io
import json
import math

import numpy as np
import pytest

from controllers.geometry import H0
from simpro_mj.analysis.metrics import SETTLING_FLOOR, compute_metrics
from simpro_mj.config.reference import reference
from simpro_mj.config.scenario import load_scenario, scenario_hash
from simpro_mj.core.errors import UserInputError
from simpro_mj.report import results as results_mod
from simpro_mj.report.marker import record
from simpro_mj.report.results import print_summary, read_timeseries, write_results

DT = 0.001
T_STEP = 1.0


def _columns(scenario, y_fn, duration=15.0):
    """Synthetic log: reference from the scenario, true pose = y_fn(t, ref)."""
    t = np.arange(int(round(duration / DT)) + 1) * DT
    ref = reference(scenario, t)
    y = y_fn(t, ref)
    cols = {"time_s": t}
    for j, (name, unit) in enumerate((("roll", "rad"), ("pitch", "rad"), ("heave", "m"))):
        cols[f"{name}_ref_{unit}"] = ref[:, j]
        cols[f"{name}_{unit}"] = y[:, j]
        cols[f"{name}_meas_{unit}"] = y[:, j] + 1e-4
    return cols


def _first_order(tau):
    def fn(t, ref):
        home = ref[0]
        s = np.where(t >= T_STEP, 1.0 - np.exp(-(t - T_STEP) / tau), 0.0)
        return home + (ref[-1] - home) * s[:, None]

    return fn


def _second_order(zeta, wn):
    wd = wn * math.sqrt(1 - zeta**2)
    phi = math.acos(zeta)

    def fn(t, ref):
        home = ref[0]
        tau = np.maximum(t - T_STEP, 0.0)
        s = 1.0 - np.exp(-zeta * wn * tau) / math.sqrt(1 - zeta**2) * np.sin(wd * tau + phi)
        s = np.where(t >= T_STEP, s, 0.0)
        return home + (ref[-1] - home) * s[:, None]

    return fn


@pytest.fixture(scope="module")
def step_all():
    # roll 2 deg, pitch 3 deg, heave 50 mm at 1 s; the resolved document the metrics read
    return load_scenario("step_all").model_dump()


def test_first_order_rise_settling_iae(step_all):
    tau = 0.4
    m = compute_metrics(_columns(step_all, _first_order(tau)), step_all)
    sizes = {"roll": math.radians(2.0), "pitch": math.radians(3.0), "heave": 0.05}
    for axis, size in sizes.items():
        a = m["axes"][axis]
        assert a["rise_time_s"] == pytest.approx(math.log(9.0) * tau, rel=1e-3)  # 2.197 tau
        band = max(0.02 * size, SETTLING_FLOOR[axis])
        assert a["settling_time_s"] == pytest.approx(tau * math.log(size / band), rel=2e-3)
        assert a["overshoot_pct"] == pytest.approx(0.0, abs=1e-9)
        # ∫ A e^{-t/tau} dt = A tau; the trapezoid spreads the jump over one sample (+A dt/2)
        assert a["iae"] == pytest.approx(size * tau, rel=0.6 * DT / tau)
        assert a["steady_state_error"] == pytest.approx(0.0, abs=1e-12 + 1e-9 * size)
        assert a["steady_state_error_measured"] == pytest.approx(-1e-4, rel=1e-6)
        assert a["step"]["time_s"] == T_STEP
        assert a["step"]["reference_change"] == pytest.approx(size, rel=1e-12)
    assert m["final_window_s"] == pytest.approx([12.0, 15.0])


@pytest.mark.parametrize("zeta", [0.3, 0.5, 0.7])
def test_second_order_overshoot(step_all, zeta):
    m = compute_metrics(_columns(step_all, _second_order(zeta, 10.0)), step_all)
    expect = 100.0 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    for axis in ("roll", "pitch", "heave"):
        assert m["axes"][axis]["overshoot_pct"] == pytest.approx(expect, rel=2e-3)


def test_steady_state_error_is_signed_reference_minus_true(step_all):
    offset = np.array([math.radians(0.1), -math.radians(0.2), 0.003])
    m = compute_metrics(
        _columns(step_all, lambda t, ref: _first_order(0.3)(t, ref) - offset), step_all
    )
    for j, axis in enumerate(("roll", "pitch", "heave")):
        assert m["axes"][axis]["steady_state_error"] == pytest.approx(offset[j], rel=1e-9)
        # transient figures are relative to the output's own change: unaffected
        assert m["axes"][axis]["rise_time_s"] == pytest.approx(math.log(9.0) * 0.3, rel=1e-3)


def test_axes_without_a_step_have_null_step_figures():
    s = load_scenario("step_pitch").model_dump()
    m = compute_metrics(_columns(s, _first_order(0.3)), s)
    assert m["axes"]["pitch"]["rise_time_s"] is not None
    for axis in ("roll", "heave"):
        a = m["axes"][axis]
        assert a["rise_time_s"] is None and a["settling_time_s"] is None
        assert a["overshoot_pct"] is None and a["step"] is None
        assert a["iae"] == pytest.approx(0.0, abs=1e-12)


def test_no_response_and_divergence(step_all):
    cols = _columns(step_all, lambda t, ref: np.broadcast_to(ref[0], ref.shape).copy())
    m = compute_metrics(cols, step_all)
    assert m["axes"]["pitch"]["rise_time_s"] is None
    assert "no step-response" in m["axes"]["pitch"]["note"]
    cols = _columns(step_all, _first_order(0.3))
    cols["pitch_rad"][8000:] = np.nan  # diverged at 8 s
    m = compute_metrics(cols, step_all)
    assert m["n_samples"] == 8000
    assert m["final_window_s"][1] == pytest.approx(7.999)
    assert math.isfinite(m["axes"]["pitch"]["iae"])


# ---------------------------------------------------------------- results folder


def _full_columns(scenario, n_extra=True):
    cols = _columns(scenario, _first_order(0.3))
    t = cols["time_s"]
    for i in (1, 2, 3):
        cols[f"q{i}_ref_m"] = 0.25 + 0.01 * np.sin(t + i)
        cols[f"q{i}_m"] = cols[f"q{i}_ref_m"] - 1e-4
        cols[f"u{i}_v"] = 5.0 + np.sin(3 * t + i)
        cols[f"p{i}a_pa"] = 4e5 + 1e4 * np.sin(t)
        cols[f"p{i}b_pa"] = 3e5 + 1e4 * np.cos(t)
    return cols


def test_write_results_complete_and_round_trips(tmp_path, step_all):
    cols = _full_columns(step_all)
    assert len(cols) == 1 + 9 + 15  # ~25 columns
    metrics = compute_metrics(cols, step_all)
    extra = {"sim": {"steps": 15000, "physics_dt_s": 0.001, "realtime_factor": 3.2}}
    out = write_results(tmp_path / "run", cols, metrics, step_all, extra)
    assert out == (tmp_path / "run").absolute()
    names = {p.name for p in out.iterdir()}
    assert {"timeseries.csv", "metrics.json", "scenario.yaml", "task_space.png"} <= names
    assert {"joints.png", "valves.png", "pressures.png"} <= names
    # CSV: header with units, one row per sample, values round-trip
    back = read_timeseries(out / "timeseries.csv")
    assert list(back)[0] == "time_s" and set(back) == set(cols)
    for k, v in cols.items():
        np.testing.assert_allclose(back[k], v, rtol=1e-11, atol=1e-15)
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["status"] == "ok" and doc["reason"] is None
    assert set(doc["axes"]) == {"roll", "pitch", "heave"}
    assert doc["axes"]["pitch"]["rise_time_s"] == pytest.approx(
        metrics["axes"]["pitch"]["rise_time_s"]
    )
    assert doc["sim"]["steps"] == 15000
    assert doc["sim"]["wall_clock"] == {"realtime_factor": 3.2}  # apart from deterministic ones
    v = doc["versions"]
    for key in ("simpro-sim", "mujoco", "numpy", "python-control", "scenario_hash"):
        assert key in v
    assert v["scenario_hash"] == scenario_hash(step_all) == doc["scenario"]["hash"]
    # the resolved scenario loads back to the same scenario
    assert scenario_hash(load_scenario(str(out / "scenario.yaml"))) == scenario_hash(step_all)
    # nothing left behind next to it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    # summary
    buf = io.StringIO()
    print_summary(doc, out, file=buf)
    text = buf.getvalue()
    assert "pitch" in text and "deg" in text and "mm" in text and str(out) in text


def test_write_results_is_atomic(tmp_path, step_all, monkeypatch):
    cols = _full_columns(step_all)
    metrics = compute_metrics(cols, step_all)
    out = tmp_path / "run"
    write_results(out, cols, metrics, step_all, {"plots": False, "sim": {"tag": "first"}})
    import simpro_mj.report.plots as plots

    seen = {}

    def spy(columns, scenario, folder):
        # while the new folder is being written, the old one is intact and complete
        seen["old"] = json.loads((out / "metrics.json").read_text())["sim"]["tag"]
        seen["folder"] = folder
        raise RuntimeError("disk full")

    monkeypatch.setattr(plots, "plot_run", spy)
    with pytest.raises(RuntimeError, match="disk full"):
        write_results(out, cols, metrics, step_all, {"sim": {"tag": "second"}})
    assert seen["old"] == "first" and seen["folder"] != out
    # the failed write left the old results as they were, and no temporary folder
    assert json.loads((out / "metrics.json").read_text())["sim"]["tag"] == "first"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    # a successful write replaces the folder as a whole (a file simpro-sim wrote there
    # and listed in its marker goes with it; one it did not write is refused instead)
    monkeypatch.undo()
    (out / "stale.txt").write_text("from an older run")
    with pytest.raises(UserInputError, match="did not write stale.txt"):
        write_results(out, cols, metrics, step_all, {"plots": False, "sim": {"tag": "third"}})
    record(out, ["stale.txt"], "run")
    write_results(out, cols, metrics, step_all, {"plots": False, "sim": {"tag": "third"}})
    assert json.loads((out / "metrics.json").read_text())["sim"]["tag"] == "third"
    assert not (out / "stale.txt").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_diverged_status_and_nan_as_null(tmp_path, step_all):
    cols = _full_columns(step_all)
    cols["heave_m"][5000:] = np.nan
    metrics = compute_metrics(cols, step_all)
    extra = {"status": "diverged", "reason": "PhysicsError: loop opened at t = 5.0 s"}
    out = write_results(tmp_path / "d", cols, metrics, step_all, extra)
    doc = json.loads((out / "metrics.json").read_text())  # strict JSON: no NaN
    assert doc["status"] == "diverged" and "loop opened" in doc["reason"]
    back = read_timeseries(out / "timeseries.csv")
    assert np.isnan(back["heave_m"][-1])
    # the status may also come with the metrics (as cmd_run passes it)
    metrics = dict(metrics, status="diverged", reason="non-finite state")
    out = write_results(tmp_path / "d2", cols, metrics, step_all, {"plots": False})
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["status"] == "diverged" and doc["reason"] == "non-finite state"
    assert "status" not in doc["metrics"]
    with pytest.raises(ValueError, match="status"):
        write_results(tmp_path / "e", cols, metrics, step_all, {"status": "meh"})


def test_csv_round_trips_every_column_to_its_printed_precision(tmp_path, step_all):
    """``%.12g`` keeps 12 significant digits: each value comes back within half a
    unit of the 12th digit (relative 5e-12), time first, names in order. (How
    long the write takes is a speed figure: ``simpro-sim bench`` reports it as
    ``timeseries_write_s``.)"""
    cols = _full_columns(step_all)
    path = results_mod.write_timeseries(tmp_path / "ts.csv", cols)
    back = results_mod.read_timeseries(path)
    assert list(back)[0] == "time_s" and set(back) == set(cols)
    for name, values in cols.items():
        np.testing.assert_allclose(back[name], values, rtol=5e-12, atol=1e-300, err_msg=name)


def test_plot_compare_writes_one_figure(tmp_path, step_all):
    from simpro_mj.report.plots import plot_compare

    joint_only = _columns(step_all, lambda t, ref: _first_order(0.3)(t, ref) - 0.002)
    task = _columns(step_all, _first_order(0.5))
    paths = plot_compare(joint_only, task, step_all, tmp_path)
    assert [p.name for p in paths] == ["compare.png"]
    assert paths[0].stat().st_size > 10_000
    assert reference(step_all, np.array([0.0]))[0, 2] == pytest.approx(H0)


def test_metrics_record_the_kernel_and_the_model_file(tmp_path):
    """SIMPRO_KERNEL and SIMPRO_MODEL change a run: metrics.json says which, with the
    MJCF's digest (a copy of the shipped model with one comment more: another digest)."""
    import hashlib
    import os
    import subprocess
    import sys
    from pathlib import Path

    from simpro_mj.core.shipped import MODEL_DIR

    shipped = MODEL_DIR / "simpro_platform.xml"
    mjcf = tmp_path / "platform.xml"
    mjcf.write_bytes(shipped.read_bytes() + b"<!-- a copy -->\n")
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, SIMPRO_KERNEL="python", SIMPRO_MODEL=str(mjcf), PYTHONPATH=str(root))
    cmd = [sys.executable, "-m", "simpro_mj.commands.main", "run", "step_pitch",
           "--set", "duration_s=0.05", "--no-plots", "--quiet", "--out", "run"]  # fmt: skip
    proc = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    v = json.loads((tmp_path / "run" / "metrics.json").read_text())["versions"]
    assert v["SIMPRO_KERNEL"] == "python" and v["kernels"] == "python"
    assert v["model"] == {
        "file": str(mjcf),
        "sha256": hashlib.sha256(mjcf.read_bytes()).hexdigest(),
    }
    assert v["model"]["sha256"] != hashlib.sha256(shipped.read_bytes()).hexdigest()


def test_dataclass_records_become_json(capsys):
    """A dataclass record goes into metrics.json or --json as its fields, numpy and
    non-finite numbers converted, without a to_json of its own."""
    from dataclasses import dataclass

    from simpro_mj.core.jsonout import emit_json

    @dataclass
    class Row:
        name: str
        gain: float
        poles: np.ndarray

    row = Row("pitch", np.float64(math.inf), np.array([0.5, 0.25]))
    assert results_mod.jsonable({"rows": [row]}) == {
        "rows": [{"name": "pitch", "gain": None, "poles": [0.5, 0.25]}]
    }
    emit_json({"row": Row("roll", 2.0, np.array([1.0]))})
    assert json.loads(capsys.readouterr().out) == {
        "row": {"name": "roll", "gain": 2.0, "poles": [1.0]}
    }
