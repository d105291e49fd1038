"""The paper's floors: its closed loop (K K_I = 3, T = 60 ms, eqs. 36-37
corrected under the volts reading, I law) on the default plant behaves as Figs.
14-16 show: smooth steps. The numbers are acceptance floors; the measured values
are in docs/paper-notes.md (closed loop)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.task_space import outer_law
from simpro_mj.analysis.metrics import compute_metrics
from simpro_mj.config.scenario import load_scenario
from simpro_mj.sim.build import simulate


def _axes(name, *sets, duration=6.0):
    sc = load_scenario(name, [f"duration_s={duration}", *sets])
    res = simulate(sc)
    assert res.status == "ok", res.reason
    m = compute_metrics(res.columns, sc.model_dump())
    m["sensor_floor"] = res.sensor_floor
    return sc, res.columns, m


def test_backward_integrator_is_the_pi_law_with_its_zero_at_the_origin():
    assert outer_law("I", "backward", 0.2) == ("PI", 0.0)
    assert outer_law("I", "forward", 0.2) == ("I", 0.2)
    assert outer_law("PI", "backward", 0.2) == ("PI", 0.2)
    with pytest.raises(ValueError, match="forward, backward"):
        outer_law("I", "trapezoid")


def test_step_pitch_meets_the_paper_floors():
    """Pitch overshoot <= 8 %, 2 % settling <= 3 s after the step, heave within 2 mm
    of its set-point, steady-state error below the sensor floor (IMU)."""
    sc, c, m = _axes("step_pitch", duration=12.0)  # 2.4 s of final window
    pitch = m["axes"]["pitch"]
    assert sc.controller.outer.gains == [3.0, 3.0, 3.0]
    assert sc.controller.outer.period_ms == 60
    assert pitch["overshoot_pct"] <= 8.0
    assert pitch["settling_time_s"] <= 3.0
    after = c["time_s"] >= 1.0
    assert np.abs(c["heave_m"][after] - c["heave_ref_m"][after]).max() <= 2e-3
    assert abs(pitch["steady_state_error"]) < m["sensor_floor"]["pitch"]
    # the first outer update's kick stays off valve 1's rails (the ramp filter)
    assert np.abs(c["u1_v"][after] - 5.0).max() < 5.0


@pytest.mark.parametrize(
    "name,axes", [("step_roll", ("roll",)), ("step_all", ("roll", "pitch", "heave"))]
)
def test_other_steps_overshoot_at_most_ten_percent(name, axes):
    _, _, m = _axes(name)
    for ax in axes:
        a = m["axes"][ax]
        assert a["overshoot_pct"] <= 10.0, (ax, a["overshoot_pct"])
        assert a["settling_time_s"] <= 4.0, (ax, a["settling_time_s"])


def test_forward_integrator_overshoots_more_as_its_extra_period_predicts():
    """Fig. 7's forward reading delays the newest error by one more outer period:
    with the ramp filter the analysis gives 11.8 % against 0 %; the simulation
    shows the same order (the reading is kept as a parameter)."""
    _, _, back = _axes("step_pitch")
    _, _, fwd = _axes("step_pitch", "controller.outer.integrator=forward")
    assert fwd["axes"]["pitch"]["overshoot_pct"] > back["axes"]["pitch"]["overshoot_pct"] + 5.0
    assert math.isfinite(fwd["axes"]["pitch"]["settling_time_s"])
