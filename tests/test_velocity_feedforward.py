"""Leg velocity feed-forward (``controller.feedforward.leg_velocity``)."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.design import Plant
from controllers.geometry import nominal_geometry
from controllers.joint import JointControllers
from controllers.kinematics import inverse_kinematics
from controllers.velocity_feedforward import leg_rates, leg_velocity_feedforward, velocity_gains
from simpro_mj.analysis.response import measure, plan_response
from simpro_mj.analysis.response_summary import loop_model, summary
from simpro_mj.config.scenario import load_scenario

HOME = nominal_geometry().home


def test_velocity_gain_is_the_inverse_of_the_plants_b_over_a0():
    # eq. 19 at a constant voltage u: the leg settles to the speed (b / a0) u
    plants = [Plant(b=12.51, a1=15.78, a0=78.92), Plant(b=95.66, a1=17.37, a0=467.7)] * 2
    kv = velocity_gains(plants[:3])
    assert kv == pytest.approx([78.92 / 12.51, 467.7 / 95.66, 78.92 / 12.51], rel=1e-12)
    with pytest.raises(ValueError, match="a0 > 0"):
        velocity_gains([Plant(b=1.0, a1=1.0, a0=0.0)] * 3)
    with pytest.raises(ValueError, match="3 plants"):
        velocity_gains(plants[:2])


def test_leg_rates_are_the_ik_derivative_along_the_trajectory():
    dt = 1e-3
    t = np.arange(2000) * dt
    ref = HOME + np.column_stack(
        [0.02 * np.sin(2 * np.pi * t), 0.03 * np.sin(3 * t), 0.01 * np.sin(5 * t)]
    )
    rates = leg_rates(ref, dt)
    # the IK's own backward difference along the same trajectory: J(y_d[k]) instead
    # of the chord's slope differs by J's change over one step, O(dt)
    q = inverse_kinematics(ref)
    q_dot = np.diff(q, axis=0) / dt
    assert np.abs(rates[1:] - q_dot).max() < 1e-3 * np.abs(q_dot).max()
    assert np.all(rates[0] == 0.0)


def test_a_step_is_clipped_to_the_valve_span():
    ref = np.tile(HOME, (10, 1))
    ref[5:, 1] += np.radians(3.0)
    plants = [Plant(b=95.66, a1=17.37, a0=467.7)] * 3
    u = leg_velocity_feedforward(ref, 1e-3, plants, u_limit=5.0)
    assert np.abs(u).max() == pytest.approx(5.0)  # one sample of delta/dt, clipped
    assert np.count_nonzero(np.abs(u).sum(axis=1)) == 1


def test_the_setpoint_filter_turns_a_step_into_the_ramps_rate():
    """Through the 60 ms ramp filter a 3 deg pitch step's rate is delta/60 ms for 60
    samples: the voltage of the filtered reference's speed, whose integral is the
    step's leg displacement."""
    from controllers.setpoint_filter import SetpointFilter

    ref = np.tile(HOME, (200, 1))
    ref[50:, 1] += np.radians(3.0)
    plants = [Plant(b=1.0, a1=1.0, a0=1.0)] * 3  # 1 V per m/s
    filt = SetpointFilter("ramp", dt=1e-3, time=0.06)
    u = leg_velocity_feedforward(ref, 1e-3, plants, u_limit=5.0, setpoint_filter=filt)
    dq = inverse_kinematics(ref[-1]) - inverse_kinematics(ref[0])
    moving = np.abs(u).sum(axis=1) > 0
    assert np.count_nonzero(moving) == 60 and moving[50:110].all()
    # J at the end pose instead of the chord: first order in delta, 1.1 % for 3 deg
    assert np.allclose(u.sum(axis=0) * 1e-3, dq, rtol=2e-2)
    assert np.abs(u).max() < 5.0  # no clipping needed


def test_joint_controllers_add_the_feedforward_before_saturation():
    a, b = JointControllers(), JointControllers()
    q = [0.1, 0.2, 0.3]
    ua = a.update(q, q)
    ub = b.update(q, q, [1.5, -2.0, 7.0])
    assert ub[0] - ua[0] == pytest.approx(1.5) and ub[1] - ua[1] == pytest.approx(-2.0)
    assert ub[2] == b.u_max  # 5 V + 7 V: at the rail


@pytest.fixture(scope="module")
def pitch_1hz():
    """Pitch at 1 Hz, 0.5 deg, on the default (non-linear) plant in the feed-forward
    mode, without and with the leg velocity feed-forward."""
    out = {}
    for on in ("false", "true"):
        sc = load_scenario("track_cues", [f"controller.feedforward.leg_velocity={on}"])
        plan = plan_response(
            sc.model_dump(), periods_ms=[1000], axes=("pitch",), settle_s=3.0, periods=1
        )
        doc = summary(plan, measure(plan, jobs=1), loop_model(sc))
        assert not doc.failed
        (row,) = [
            r for r in doc.rows if r.signal == "true" and r.input_axis == r.output_axis == "pitch"
        ]
        out[on] = row
    return out


def test_velocity_feedforward_removes_most_of_the_lag_at_1_hz(pitch_1hz):
    """The joint loops lag about 40 deg at 1 Hz: the voltage that the leg speed needs,
    supplied in advance, takes most of it away (measured: -40 -> -10 deg), and the
    prediction with the same term agrees within 15 deg and 2 dB."""
    off, on = pitch_1hz["false"], pitch_1hz["true"]
    assert off.phase_deg < -30.0
    assert on.phase_deg > off.phase_deg + 20.0
    for r in (off, on):
        assert r.saturated_pct == 0.0
        assert abs(r.diff_deg) < 15.0 and abs(r.diff_db) < 2.0, r
