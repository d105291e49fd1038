"""A run's verdict: a pose that still oscillates or drifts at its end is never ``ok``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from simpro_mj.analysis.metrics import SETTLING_FLOOR
from simpro_mj.analysis.verdict import MIN_CYCLES, verdict

DEG = math.pi / 180.0
RNG = np.random.default_rng(7)


def _columns(t, refs=None, errors=None, noise=None):
    """Columns of a run: references and true pose = reference - error (SI)."""
    refs = refs or {}
    errors = errors or {}
    cols = {"time_s": t}
    for a, (r, y) in {
        "roll": ("roll_ref_rad", "roll_rad"),
        "pitch": ("pitch_ref_rad", "pitch_rad"),
        "heave": ("heave_ref_m", "heave_m"),
    }.items():
        ref = refs.get(a, np.zeros_like(t))
        e = errors.get(a, np.zeros_like(t))
        if noise:
            e = e + RNG.normal(0.0, noise[a], t.size)
        cols[r], cols[y] = ref, ref - e
    return cols


T = np.arange(0.0, 20.0 + 1e-9, 1e-3)
#: the residual the shipped step scenarios leave: about 0.003 deg and 0.015 mm
QUIET = {"roll": 0.002 * DEG, "pitch": 0.002 * DEG, "heave": 0.01e-3}


def test_a_settled_run_with_sensor_jitter_is_ok():
    step = np.where(T >= 1.0, 3.0 * DEG, 0.0)
    out = verdict(_columns(T, {"pitch": step}, noise=QUIET))
    assert out["status"] == "ok" and out["reason"] is None
    assert out["window_s"] == pytest.approx([17.0, 20.0])


def test_a_held_oscillation_is_a_limit_cycle_with_its_amplitude_frequency_axis():
    cycle = 0.25 * DEG * np.sin(2 * math.pi * 1.0 * T)  # the friction hunting: 1 Hz, 0.25 deg
    out = verdict(_columns(T, errors={"pitch": cycle}, noise=QUIET))
    assert out["status"] == "limit_cycle"
    assert out["axis"] == "pitch"
    assert out["amplitude"] == pytest.approx(0.25 * DEG, rel=0.05)
    assert out["frequency_hz"] == pytest.approx(1.0, abs=0.05)
    assert "limit cycle on pitch" in out["reason"] and "1 Hz" in out["reason"]


def test_an_oscillation_just_above_the_settling_floor_is_caught_and_just_below_is_not():
    for factor, want in ((1.5, "limit_cycle"), (0.5, "ok")):
        a = factor * SETTLING_FLOOR["heave"]
        out = verdict(_columns(T, errors={"heave": a * np.sin(2 * math.pi * 3.0 * T)}))
        assert out["status"] == want, (factor, out)


def test_a_slow_oscillation_or_a_drift_is_not_settled():
    # fewer than MIN_CYCLES periods in the 3 s window: not a cycle, but not settled
    f = 0.5 * MIN_CYCLES / 3.0
    slow = verdict(_columns(T, errors={"roll": 0.1 * DEG * np.sin(2 * math.pi * f * T)}))
    assert slow["status"] == "not_settled" and slow["axis"] == "roll"
    drift = verdict(_columns(T, errors={"heave": 0.5e-3 * (T - 17.0).clip(0.0)}))
    assert drift["status"] == "not_settled" and "drifts by 1.5 mm" in drift["reason"]


def test_a_tracked_moving_setpoint_is_judged_by_its_error_not_the_pose_motion():
    # a 1 Hz sine followed with a first-order lag of 50 ms: the pose moves by 16 mm
    # and the error by about 2.5 mm at the reference's frequency: that is tracking
    w, tau = 2 * math.pi, 0.05
    ref = 8e-3 * np.sin(w * T)
    g = 1.0 / complex(1.0, w * tau)
    y = 8e-3 * abs(g) * np.sin(w * T + math.atan2(g.imag, g.real))
    out = verdict(_columns(T, {"heave": ref}, {"heave": ref - y}, noise=QUIET))
    assert out["status"] == "ok", out["reason"]
    # the same run with a 4 Hz cycle of 2.5 mm on top is not (the threshold of a
    # moving set-point: 10 % of its 16 mm excursion, 1.6 mm)
    bad = ref - y + 2.5e-3 * np.sin(2 * math.pi * 4.0 * T)
    out = verdict(_columns(T, {"heave": ref}, {"heave": bad}, noise=QUIET))
    assert out["status"] == "limit_cycle" and out["frequency_hz"] == pytest.approx(4.0, abs=0.1)


def test_outer_gains_far_above_the_limit_are_never_ok(tmp_path):
    """K K_I = 25 on every axis (limit 11.8): the step ends in a held cycle, exit 1."""
    from simpro_mj.commands.main import main

    out = tmp_path / "g25"
    code = main(
        [
            "run",
            "step_pitch",
            "--no-plots",
            "--out",
            str(out),
            "--set",
            "controller.outer.gains=[25,25,25]",
            "--set",
            "duration_s=10",
        ]
    )
    assert code == 1
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["status"] == "limit_cycle"
    v = doc["metrics"]["verdict"]
    assert v["axis"] in ("roll", "pitch", "heave")
    assert v["amplitude"] > 10 * v["thresholds"][v["axis"]]
    assert 1.0 <= v["frequency_hz"] <= 1.0 / (2 * 0.06)  # below the outer loop's Nyquist rate
    assert doc["reason"].startswith("limit cycle on")


@pytest.mark.slow
def test_a_static_imu_bias_does_not_raise_the_oscillation_threshold():
    """A 0.5 deg IMU bias shifts where the loop settles; the verdict's roll threshold
    stays at its noise-and-quantisation floor (0.02 deg here), not 3 x (noise + bias)
    = 1.5 deg, at which a 2 deg peak-to-peak cycle would read ok."""
    import math

    import simpro_mj as s

    r = s.run("step_pitch", {"duration_s": 4, "sensors.imu.bias_deg": [0.5, 0.0]})
    assert r.metrics["sensor_floor"]["roll"] > math.radians(0.5)  # the floor a user reads
    assert r.metrics["verdict"]["thresholds"]["roll"] < math.radians(0.05)
