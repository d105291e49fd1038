"""Outer task-space loop: discrete form of Fig. 7 / eq. (24), sampling, workspace."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.errors import WorkspaceError
from controllers.geometry import nominal_geometry
from controllers.kinematics import forward_kinematics, inverse_kinematics, reachable
from controllers.task_space import SamplingError, TaskSpaceController

GEOM = nominal_geometry()
HOME = GEOM.home


def _delay_loop(ctrl, ref, n, plant_geometry=GEOM):
    """Inner loop as one outer sample of delay (eq. 21): y[k] = FK(q_d[k-1])."""
    ctrl.reset(HOME)
    q_prev = inverse_kinematics(HOME, GEOM)
    ys = []
    for _ in range(n):
        y = forward_kinematics(q_prev, plant_geometry, initial_pose=HOME)
        ys.append(y)
        q_prev = ctrl.update(ref, y)
    return np.array(ys)


def test_period_must_be_multiple_of_inner_step():
    with pytest.raises(SamplingError):
        TaskSpaceController(period=0.0605)
    with pytest.raises(ValueError):
        TaskSpaceController(period=0.0005)
    assert TaskSpaceController(period=0.06).ratio == 60
    c30 = TaskSpaceController(period=0.03)
    assert c30.ratio == 30 and c30.is_due(90) and not c30.is_due(91)


@pytest.mark.parametrize("mode", ["I", "PI"])
def test_discrete_form_matches_eq_25(mode):
    """Heave step with the delay model follows the hand recursion of eq. (25) / the PI law."""
    g, T, c, n = 3.0, 0.06, 0.2, 40
    dh = 0.01
    ys = _delay_loop(TaskSpaceController(mode, gains=g, period=T), HOME + [0, 0, dh], n)
    y = (ys[:, 2] - HOME[2]) / dh
    gt = g * T
    ref = np.zeros(n)
    if mode == "I":  # y(k+2) = y(k+1) - gT y(k) + gT y_d(k), y(0) = y(1) = 0
        for k in range(n - 2):
            ref[k + 2] = ref[k + 1] - gt * ref[k] + gt
    else:  # y(k+1) = y(k) + gT (1 - y(k)) + c gT (1 - y(k-1)), y(1) = gT
        ref[1] = gt
        for k in range(1, n - 1):
            ref[k + 1] = ref[k] + gt * (1 - ref[k]) + c * gt * (1 - ref[k - 1])
    np.testing.assert_allclose(y, ref, atol=1e-8)
    np.testing.assert_allclose(ys[:, :2], 0.0, atol=1e-9)  # decoupled axes


def test_thirty_ms_variant_runs_and_converges():
    ref = HOME + [0.02, -0.01, 0.01]
    ys = _delay_loop(TaskSpaceController("I", period=0.03), ref, 200)
    np.testing.assert_allclose(ys[-1], ref, atol=1e-6)


def test_integral_action_removes_model_error_joint_only_does_not():
    """Fig. 15: with an as-built geometry off by 5 mm in leg 1, only task control reaches y_d."""
    true = GEOM.replace(retracted_length=GEOM.retracted_length + np.array([0.005, 0, 0]))
    ref = HOME + [0.0, 0.03, 0.0]
    y_i = _delay_loop(TaskSpaceController("I"), ref, 150, true)[-1]
    y_j = _delay_loop(TaskSpaceController("joint_only"), ref, 5, true)[-1]
    np.testing.assert_allclose(y_i, ref, atol=1e-6)
    assert np.max(np.abs(y_j - ref)) > 1e-3


def test_joint_only_is_ik_of_setpoint():
    ctrl = TaskSpaceController("joint_only")
    ref = HOME + [0.05, 0.02, -0.03]
    q = ctrl.update(ref, HOME + [1.0, 1.0, 1.0])  # measurement ignored
    np.testing.assert_allclose(q, inverse_kinematics(ref, GEOM), atol=1e-12)


def test_unreachable_setpoint_rejected_or_clamped():
    bad = HOME + [0.0, 0.0, 0.6]
    with pytest.raises(WorkspaceError, match="allowed"):
        TaskSpaceController().update(bad, HOME)
    ctrl = TaskSpaceController("joint_only", clamp=True)
    q = ctrl.update(bad, HOME)
    assert np.all((q >= -1e-12) & (q <= GEOM.stroke + 1e-12))
    assert reachable(ctrl.pose_command)
    assert ctrl.pose_command[2] > HOME[2] + 0.05  # clamped on the boundary, not at home


@pytest.mark.parametrize("mode", ["I", "PI"])
@pytest.mark.parametrize("seed", range(4))
def test_integrator_never_leaves_workspace(mode, seed):
    """Platform stuck at home (no motion), set-points near the boundary: x_c winds up."""
    rng = np.random.default_rng(seed)
    ctrl = TaskSpaceController(mode, gains=rng.uniform(1, 15, 3), clamp=True)
    ctrl.reset(HOME)
    direction = rng.normal(size=3) * [0.3, 0.3, 0.2]
    ref = HOME + direction
    for _ in range(150):
        q = ctrl.update(ref, HOME)
        assert reachable(ctrl.pose_command)
        assert np.all((q >= -1e-9) & (q <= GEOM.stroke + 1e-9))
    # it did wind up to the boundary: a further nudge outward leaves the workspace
    step = ctrl.pose_command - HOME
    assert not reachable(HOME + 1.02 * step) or np.allclose(ctrl.pose_command, ref, atol=1e-3)


def test_reset_and_bad_arguments():
    with pytest.raises(WorkspaceError):
        TaskSpaceController().reset(HOME + [0, 0, 1.0])
    with pytest.raises(ValueError):
        TaskSpaceController(mode="PID")
    with pytest.raises(ValueError):
        TaskSpaceController(gains=(-1, 3, 3))
    with pytest.raises(TypeError):
        TaskSpaceController(bogus=True)


def _lagging_legs(ctrl, ref, n, plant_geometry=GEOM, alpha=0.25):
    """Legs that close a fraction ``alpha`` of their lag each outer period (a first-order
    joint loop of time constant -T / ln(1 - alpha), about 0.2 s at T = 60 ms), as the
    cabin's slow leg 1 does: returns the true pose of every period."""
    ctrl.reset(HOME)
    q_d = q = inverse_kinematics(HOME, GEOM)
    ys = []
    for _ in range(n):
        q = q + alpha * (q_d - q)
        y = forward_kinematics(q, plant_geometry, initial_pose=HOME)
        ys.append(y)
        q_d = ctrl.update(ref, y, q_meas=q)
    return np.array(ys)


def test_joint_lag_stops_the_wind_up_and_keeps_the_integral_action():
    """I law K K_I = 3 around legs that lag: integrating the whole error overshoots a
    3 deg pitch step (the law winds up on the legs' lag); less the lag it does not,
    and both remove a 5 mm as-built error in leg 1."""
    true = GEOM.replace(retracted_length=GEOM.retracted_length + np.array([0.005, 0, 0]))
    ref = HOME + [0.0, np.radians(3.0), 0.0]
    none = _lagging_legs(TaskSpaceController("I"), ref, 300, true)
    lag = _lagging_legs(TaskSpaceController("I", joint_lag="joints"), ref, 300, true)
    step = ref[1] - none[0, 1]
    assert (none[:, 1].max() - ref[1]) / step > 0.05  # the paper's law: > 5 % overshoot
    assert (lag[:, 1].max() - ref[1]) / step < 0.005  # less the lag: none to speak of
    np.testing.assert_allclose(none[-1], ref, atol=1e-6)
    np.testing.assert_allclose(lag[-1], ref, atol=1e-6)
    with pytest.raises(ValueError, match="q_meas"):
        TaskSpaceController("I", joint_lag="joints").update(ref, HOME)
    with pytest.raises(ValueError, match="allowed"):
        TaskSpaceController("I", joint_lag="model")
