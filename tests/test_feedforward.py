"""The feed-forward task-space scheme (``controller.mode: feedforward``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.analysis import lifted as an
from controllers.geometry import nominal_geometry
from controllers.kinematics import inverse_kinematics, jacobian
from controllers.task_space import TaskSpaceController
from simpro_mj.commands.main import main
from simpro_mj.config.scenario import load_scenario

HOME = nominal_geometry().home


def _ctl(**kw):
    return TaskSpaceController(mode="feedforward", gains=2.0, period=0.06, inner_dt=0.001, **kw)


def test_setpoint_goes_through_the_ik_every_step():
    ctl = _ctl()
    ctl.reset(HOME)
    ref = (HOME + np.array([0.01, -0.02, 0.005])).tolist()
    # between outer steps q_d follows the set-point at once (no outer loop in the path)
    q = ctl.feedforward(ref)
    assert np.allclose(q, inverse_kinematics(np.array(ref)), atol=1e-12)


def test_correction_is_the_i_law_on_the_error_one_period_late():
    ctl = _ctl()
    ctl.reset(HOME)
    ref = HOME.tolist()
    meas = (HOME - np.array([0.0, 0.001, 0.0])).tolist()  # 1 mrad below on pitch
    ctl.update(ref, meas)  # c[0] = 0 applied, c[1] = T g e integrated
    assert np.allclose(ctl.correction, 0.0)
    q1 = ctl.update(ref, meas)  # c[1] applied now
    assert ctl.correction[1] == pytest.approx(0.06 * 2.0 * 0.001, rel=1e-12)
    assert np.allclose(q1, inverse_kinematics(HOME + ctl.correction), atol=1e-12)
    # hold (a valve at its rail during the period): the pending step is applied,
    # no new one is integrated
    ctl.update(ref, meas, hold=True)
    c2 = ctl.correction[1]
    assert c2 == pytest.approx(2 * 0.06 * 2.0 * 0.001, rel=1e-12)
    ctl.update(ref, meas)
    assert ctl.correction[1] == pytest.approx(c2, rel=1e-12)


def test_reference_model_removes_the_expected_lag_only():
    """With M a 100 ms lag, a measured pose that follows M y_d exactly leaves c at 0;
    without the model the same pose is integrated as an error."""
    tau, dt = 0.1, 0.001
    step = HOME + np.array([0.0, 0.02, 0.0])
    for model_tau, expect_zero in ((tau, True), (0.0, False)):
        ctl = _ctl(model_tau=model_tau)
        ctl.reset(HOME)
        m = HOME.copy()
        for k in range(600):
            if k % 60 == 0:
                ctl.update(step.tolist(), m.tolist())
            else:
                ctl.feedforward(step.tolist())
            m = m + (1 - math.exp(-dt / tau)) * (step - m)  # the pose the model expects
        assert np.allclose(ctl.correction, 0.0, atol=1e-12) == expect_zero


def _leg_lag_run(**kw):
    """A pitch step at 4 s on legs that follow ``q_d`` with a 150 ms lag, the pose
    measured through the Jacobian at home with an as-built error ``delta``: the
    correction's history and the final measured error."""
    ctl = _ctl(**kw)
    ctl.reset(HOME)
    jinv = np.linalg.inv(jacobian(HOME))
    q_home = inverse_kinematics(HOME)
    delta = np.array([0.002, -0.003, 0.004])
    step = HOME + np.array([0.0, 0.02, 0.0])
    q, alpha = q_home.copy(), -math.expm1(-0.001 / 0.15)
    corr = []
    for k in range(9000):
        y = HOME + jinv @ (q - q_home) - delta
        ref = (HOME if k < 4000 else step).tolist()
        if k % 60 == 0:
            qd = ctl.update(ref, y.tolist(), q_meas=q.tolist())
        else:
            qd = ctl.feedforward(ref, y.tolist(), q.tolist())
        corr.append(ctl.correction)
        q = q + alpha * (np.array(qd) - q)
    return np.array(corr), np.array(ref) - y, delta


@pytest.mark.parametrize("average", [False, True])
def test_joint_lag_is_measured_not_integrated(average):
    """lag="joints": the correction integrates y_d - y - J^-1 (q_d - q_meas), so it
    removes the as-built error exactly and does not move while the legs lag behind a
    step (only by the IK's curvature between the two poses, a few % of delta); the
    reference model it replaces (200 ms for a 150 ms leg lag) winds it up."""
    corr, err, delta = _leg_lag_run(lag="joints", average=average)
    assert np.abs(err).max() < 1e-8  # integral action: no steady-state error
    assert np.all(np.abs(corr[4000:] - corr[-1]).max(axis=0) < 0.05 * np.abs(delta))
    corr, err, _ = _leg_lag_run(lag="model", model_tau=0.2)
    assert np.abs(err).max() < 1e-8
    assert np.abs(corr[4000:, 1] - corr[-1, 1]).max() > 0.3 * abs(delta[1])


def test_joint_lag_needs_the_joints():
    ctl = _ctl(lag="joints")
    ctl.reset(HOME)
    with pytest.raises(ValueError, match="q_meas"):
        ctl.update(HOME.tolist(), HOME.tolist())
    with pytest.raises(ValueError, match="allowed"):
        _ctl(lag="legs")


def test_same_stability_limit_as_the_i_law():
    """The correction closes the I loop: the linear feed-forward step is stable below the
    I law's limit around the real inner loops and grows above it."""
    jac = jacobian(HOME)
    lim = an.real_inner_limit("I", 0.06, jac=jac)
    for g, stable in ((0.9 * lim, True), (1.1 * lim, False)):
        t, y = an.real_inner_step("feedforward", g, 0.06, 12.0, jac=jac, axis=1)
        late = np.abs(y[t > 9.0, 1] - 1.0).max()
        early = np.abs(y[(t > 3.0) & (t < 6.0), 1] - 1.0).max()
        assert (late < early) == stable


def test_model_tau_is_validated(capsys):
    code = main(["run", "step_pitch", "--set", "controller.feedforward.model_tau_ms=-1"])
    err = capsys.readouterr().err
    assert code == 2 and "controller.feedforward.model_tau_ms" in err and err.count("\n") == 1


@pytest.fixture(scope="module")
def ff_step():
    """Fig. 15's pitch step on the default plant with the feed-forward scheme, 8 s."""
    from simpro_mj.analysis.metrics import compute_metrics
    from simpro_mj.sim.build import simulate

    sc = load_scenario("step_pitch", ["controller.mode=feedforward", "duration_s=8.0"])
    res = simulate(sc)
    assert res.status == "ok"
    return res, compute_metrics(res.columns, res.scenario)


def test_step_on_the_default_plant_meets_the_floors(ff_step):
    """The feed-forward floors on a short step (final window 6.4-8 s, 5.4 s after the step):
    overshoot <= 10 %; the steady-state error of the true pose below the sensor floor
    the plant's sensors define (:meth:`simpro_mj.plant.sensors.SensorConfig.resolution_floor`:
    the IMU's noise averaged over 1 s, the height encoder's resolution)."""
    res, met = ff_step
    assert met["axes"]["pitch"]["overshoot_pct"] <= 10.0
    for axis in ("roll", "pitch", "heave"):
        err = abs(met["axes"][axis]["steady_state_error"])
        assert err < res.sensor_floor[axis], (axis, err, res.sensor_floor[axis])
