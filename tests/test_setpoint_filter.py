"""The set-point filter of Fig. 13 (controllers.setpoint_filter) and its place in the loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.setpoint_filter import (
    KINDS,
    PAPER_KI,
    SetpointFilter,
    filter_state_space,
    leg_times,
)
from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.sim.build import simulate

DT = 1e-3


def _run_filter(kind, x, time=0.06):
    f = SetpointFilter(kind, dt=DT, time=time)
    f.reset([0.0, 0.0, 0.0])
    return np.array([f.update([v, -v, 2 * v]) for v in x])


def test_ramp_turns_an_outer_step_into_a_linear_ramp_over_the_period():
    y = _run_filter("ramp", np.r_[np.zeros(5), np.ones(100)])
    ramp = np.clip((np.arange(105) - 4) / 60.0, 0.0, 1.0)
    np.testing.assert_allclose(y[:, 0], ramp, atol=1e-12)
    np.testing.assert_allclose(y[:, 1], -ramp, atol=1e-12)
    np.testing.assert_allclose(y[:, 2], 2 * ramp, atol=1e-12)


def test_first_order_and_zero_cancel_are_exact_lags():
    k = np.arange(1, 201)
    y = _run_filter("first_order", np.ones(200), time=0.03)[:, 0]
    np.testing.assert_allclose(y, 1 - np.exp(-k * DT / 0.03), rtol=1e-12)
    y = _run_filter("zero_cancel", np.ones(200))[:, 0]
    np.testing.assert_allclose(y, 1 - np.exp(-k * DT * PAPER_KI), rtol=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_state_space_for_the_analysis_is_the_same_filter(kind):
    rng = np.random.default_rng(3)
    x = np.repeat(rng.normal(size=20), 60)  # a staircase, as the outer loop gives
    want = _run_filter(kind, x, time=0.04)[:, 0]
    a, b, c, d = filter_state_space(kind, DT, 0.04)
    s = np.zeros(a.shape[0])
    got = []
    for v in x:
        got.append((c @ s + d[:, 0] * v)[0] if a.size else d[0, 0] * v)
        s = a @ s + b[:, 0] * v
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_per_leg_times_filter_each_leg_with_its_own_ramp():
    """time = 3 values: leg i averages over its own window; the analysis' per-leg
    state space is the same arithmetic."""
    f = SetpointFilter("ramp", dt=DT, time=[0.06, 0.03, 0.01])
    f.reset([0.0, 0.0, 0.0])
    x = np.r_[np.zeros(5), np.ones(100)]
    y = np.array([f.update([v, v, v]) for v in x])
    for i, n in enumerate((60, 30, 10)):
        np.testing.assert_allclose(y[:, i], np.clip((np.arange(105) - 4) / n, 0, 1), atol=1e-12)
    assert leg_times(0.05) == [0.05] * 3
    with pytest.raises(ValueError, match="1 or 3"):
        leg_times([0.06, 0.03])


def test_scenario_takes_one_time_or_three_multiples_of_the_step():
    one = load_scenario("step_pitch", ["controller.setpoint_filter.time_ms=40"])
    assert one.controller.setpoint_filter.time_ms == [40.0, 40.0, 40.0]
    with pytest.raises(UserInputError, match="one number or a list of 3"):
        load_scenario("step_pitch", ["controller.setpoint_filter.time_ms=[60, 30]"])
    with pytest.raises(UserInputError, match="multiples of the 1 ms"):
        load_scenario("step_pitch", ["controller.setpoint_filter.time_ms=[60, 30.5, 30]"])


def test_rejects_bad_arguments():
    with pytest.raises(ValueError, match="ramp"):
        SetpointFilter("smooth", dt=DT, time=0.06)
    with pytest.raises(ValueError, match="time"):
        SetpointFilter("ramp", dt=DT, time=0.0)


def test_the_filter_keeps_the_valve_off_its_rails_at_kki_3():
    """K K_I = 3, T = 60 ms, 3 deg pitch step: the first outer update moves leg 1's
    set-point by J x g T e = 0.528 x 3 x 0.06 x 0.0524 = 5.0 mm; through eq. (36)'s
    k_p = 5.3 kV/m (volts reading) that is a 26 V kick, 5 times the valve's half
    range. The ramp filter spreads it over the period: leg 1's valve stays off the
    rails; without it valve 1 hits a rail."""
    dq = 0.528 * 3.0 * 0.06 * math.radians(3.0)
    assert 5300.0 * dq > 5.0 * 5  # the unfiltered kick, V
    base = ["controller.outer.gains=[3, 3, 3]", "duration_s=2.5"]
    on = simulate(load_scenario("step_pitch", base))
    off = simulate(load_scenario("step_pitch", base + ["controller.setpoint_filter.type=none"]))
    u_on, u_off = on.columns["u1_v"], off.columns["u1_v"]
    assert 0.5 < u_on.min() and u_on.max() < 9.5
    assert u_off.max() == 10.0 or u_off.min() == 0.0
