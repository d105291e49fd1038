"""The float fast paths of the 1 ms loop equal their array APIs bit for bit.

``tests/test_reference_metrics.py`` checks whole runs; these check each
component on its own, including the paths the shipped scenarios do not take.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from controllers.errors import WorkspaceError
from controllers.geometry import nominal_geometry
from controllers.joint import ANTI_WINDUP, JointControllers
from controllers.kinematics import PoseKinematics, inverse_kinematics, reachable
from controllers.task_space import TaskSpaceController, _segment_limit
from simpro_mj.config.scenario import load_scenario
from simpro_mj.plant.model import StateReader, loop_closure_error, measured_pose
from simpro_mj.plant.pneumatics.nonlinear import NonlinearActuators
from simpro_mj.plant.sensors import SensorConfig, Sensors
from simpro_mj.sim.loop import CoSimulation


@pytest.fixture(scope="module")
def moving():
    """A co-simulation stopped mid-motion (pitch step under way)."""
    cs = CoSimulation(load_scenario("step_pitch", ["duration_s=1.3"]))
    cs.run()
    return cs


def test_state_reader_equals_the_array_helpers(moving):
    m, d, idx = moving.model, moving.data, moving.idx
    r = StateReader(m, d, idx)
    q, qd = r.slides()
    assert q == d.qpos[idx.slide_qpos].tolist() and qd == d.qvel[idx.slide_dof].tolist()
    assert r.pose() == measured_pose(d, idx.site_p).tolist()
    assert r.loop_closure_max() == float(loop_closure_error(m, d, idx).max())
    d2 = mujoco.MjData(m)  # a NaN propagates as in ndarray.max
    d2.site_xpos[idx.connect_sites[1, 0], 0] = np.nan
    assert np.isnan(StateReader(m, d2, idx).loop_closure_max())


def test_state_reader_read_is_live_and_equal(moving):
    """read() and loop_closure_max(xpos) equal the array helpers, step after step."""
    m, d, idx = moving.model, moving.data, moving.idx
    r = StateReader(m, d, idx)
    d.ctrl[:] = 0.0
    for _ in range(20):  # the views follow the state (no stale copies)
        mujoco.mj_step(m, d)
        mujoco.mj_step1(m, d)
        q, qd, pose, xpos = r.read()
        assert q == d.qpos[idx.slide_qpos].tolist() and qd == d.qvel[idx.slide_dof].tolist()
        assert pose == measured_pose(d, idx.site_p).tolist()
        worst = float(loop_closure_error(m, d, idx).max())
        assert r.loop_closure_max(xpos) == worst == r.loop_closure_max()


def _poses(rng, n, home):
    """Poses around home: most reachable, some outside the strokes or the guide arc."""
    x = home + rng.normal(0, 1, (n, 3)) * [0.15, 0.15, 0.1]
    x[::50] = home + rng.normal(0, 1, (len(x[::50]), 3)) * [0.6, 0.6, 1.5]
    return x


@pytest.mark.parametrize("perturb", [False, True])
def test_pose_kinematics_equals_batched(perturb):
    """PoseKinematics.solve == (inverse_kinematics(check=False), reachable) bit for bit.

    The perturbed geometry has no zero coordinates, so R PB_k is a full
    3x3 product (where BLAS/einsum rounding with FMA shows).
    """
    g = nominal_geometry()
    rng = np.random.default_rng(7)
    if perturb:
        g = g.replace(
            platform_points=g.platform_points + rng.normal(0, 0.03, (3, 3)),
            base_points=g.base_points + rng.normal(0, 0.03, (3, 3)),
            bracket_c1=g.bracket_c1 + rng.normal(0, 0.01, 3),
        )
    kin = PoseKinematics(g)
    n_ok = 0
    for margin in (0.0, 0.02):
        for x in _poses(rng, 1500, g.home):
            ok = bool(reachable(x, g, margin))
            q, ok_fast = kin.solve(x.tolist(), margin)
            assert ok_fast == ok
            n_ok += ok
            if q is not None:
                assert q == inverse_kinematics(x, g, check=False).tolist()
            try:
                want = inverse_kinematics(x, g, check=False).tolist()
            except WorkspaceError:
                with pytest.raises(WorkspaceError):
                    kin.solve(x.tolist(), margin, arc_check=False)
            else:
                assert kin.solve(x, margin, arc_check=False)[0] == want  # array input too
    assert 1000 < n_ok < 6000  # both outcomes exercised
    assert kin.solve([np.nan, 0.0, 1.2]) == (None, False)


class _ArrayTaskLoop:
    """The outer loop as it was written on arrays (before the float path), for comparison."""

    def __init__(self, mode, gains, clamp, margin=0.0):
        self.g, self.mode, self.clamp, self.margin = nominal_geometry(), mode, clamp, margin
        self.tg = 0.06 * np.asarray(gains, dtype=float)
        self.xc = self.g.home.copy()
        self.e_prev = np.zeros(3)

    def setpoint(self, ref):
        if reachable(ref, self.g, self.margin):
            return ref
        assert self.clamp
        home = self.g.home
        return home + _segment_limit(home, ref, self.g, self.margin) * (ref - home)

    def integrate(self, step):
        new = self.xc + step
        if reachable(new, self.g, self.margin):
            self.xc = new
        else:
            self.xc = self.xc + _segment_limit(self.xc, new, self.g, self.margin) * step

    def update(self, ref, meas):
        ref = self.setpoint(np.asarray(ref, dtype=float))
        if self.mode == "joint_only":
            self.xc = ref.copy()
            return inverse_kinematics(ref, self.g, check=False)
        e = ref - meas
        if self.mode == "I":
            q = inverse_kinematics(self.xc, self.g, check=False)
            self.integrate(self.tg * e)
        else:
            self.integrate(self.tg * (e + 0.2 * self.e_prev))
            self.e_prev = e
            q = inverse_kinematics(self.xc, self.g, check=False)
        return q


@pytest.mark.parametrize("mode", ["I", "PI", "joint_only"])
def test_task_loop_floats_equal_arrays(mode):
    """update_floats (single-pose IK, IK of x_c reused) == the array formulation.

    Large gains and set-points beyond the workspace make the integrator run
    into the boundary, so the shortened steps (_segment_limit) are taken too.
    """
    rng = np.random.default_rng(11)
    gains = [9.0, 7.0, 12.0]
    fast = TaskSpaceController(mode, gains=gains, clamp=True)
    ref_loop = _ArrayTaskLoop(mode, gains, clamp=True)
    home = fast.geometry.home
    shortened = 0
    for k in range(400):
        if k % 40 == 0:  # a new set-point, sometimes unreachable (clamped)
            ref = home + rng.normal(0, 1, 3) * [0.25, 0.25, 0.2]
        meas = home + rng.normal(0, 0.01, 3)
        want = ref_loop.update(ref, meas)
        got = fast.update_floats(ref.tolist(), meas.tolist())
        assert got == want.tolist()
        assert fast.pose_command.tolist() == ref_loop.xc.tolist()
        shortened += fast._q_xc is None
    if mode != "joint_only":
        assert shortened > 5  # the boundary was hit


def test_sensors_floats_equal_arrays():
    tree = load_scenario("step_pitch")["sensors"]
    cfg = SensorConfig.from_tree(tree, 1e-3)
    a, b = Sensors(cfg, np.random.default_rng(3)), Sensors(cfg, np.random.default_rng(3))
    rng = np.random.default_rng(0)
    q0, p0 = np.array([0.25, 0.24, 0.26]), np.array([0.01, -0.02, 0.95])
    a.reset(q0, p0)
    b.reset(q0, p0)
    for k in range(1, 9000):  # crosses a noise block
        q = q0 + rng.normal(0, 1e-3, 3)
        p = p0 + rng.normal(0, 1e-3, 3)
        qa, pa = a.sample(k, q, p)
        qb, pb = b.sample_floats(k, q.tolist(), p.tolist())
        assert qa.tolist() == qb and pa.tolist() == pb
    qn, _ = a.sample(9000, np.array([np.nan, np.inf, 0.2]), p0)
    assert np.isnan(qn[0]) and qn[1] == cfg.pot_range_m[1]  # as np.round + np.clip


@pytest.mark.parametrize("anti_windup", ANTI_WINDUP)
def test_joint_floats_equal_arrays(anti_windup):
    a = JointControllers(anti_windup=anti_windup)
    b = JointControllers(anti_windup=anti_windup)
    rng = np.random.default_rng(1)
    for _ in range(3000):
        qr = rng.uniform(0.2, 0.3, 3)
        qm = qr + rng.normal(0, 0.02, 3)  # large errors: the valves saturate
        va = a.update(qr, qm)
        vb = b.update_floats(qr.tolist(), qm.tolist())
        assert va.tolist() == vb
        assert np.array_equal(a.state, b.state)
    assert np.array_equal(a.last_unsaturated, b.last_unsaturated)


@pytest.mark.parametrize(
    "overrides", [{}, {"valve": {"spool_order": 2}, "integration": {"substeps": 3}}]
)
def test_pneumatics_array_and_list_inputs_agree(overrides):
    a, b = NonlinearActuators(overrides), NonlinearActuators(overrides)
    rng = np.random.default_rng(2)
    for _ in range(2000):
        u = rng.uniform(-1, 11, 3)  # beyond the 0-10 V range too
        q = rng.uniform(-0.01, 0.51, 3)
        qd = rng.normal(0, 0.3, 3)
        fa = a.step(u, q, qd, 1e-3)
        fb = b.step(u.tolist(), q.tolist(), qd.tolist(), 1e-3)
        assert np.array_equal(fa, fb)
    assert np.array_equal(a._p, b._p) and np.array_equal(a.spool, b.spool)
    assert np.all(a._p >= a.params.p_atm) and np.all(a._p <= a.params.p_supply)


def test_pneumatics_scalar_broadcast():
    a, b = NonlinearActuators(), NonlinearActuators()
    assert np.array_equal(
        a.step(6.0, 0.25, 0.0, 1e-3), b.step([6.0] * 3, [0.25] * 3, [0.0] * 3, 1e-3)
    )


def test_interrupt_returns_the_partial_result():
    cs = CoSimulation(load_scenario("step_pitch", ["duration_s=3"]))

    def stop(k):
        if k == 1000:
            raise KeyboardInterrupt

    res = cs.run(progress=stop)
    assert res.status == "interrupted"
    assert res.reason == "interrupted by signal (SIGINT/SIGTERM) at t = 1.000 s"
    assert res.sim["steps"] == 1000 and len(res.columns["time_s"]) == 1001


def test_profile_fills_the_stages():
    cs = CoSimulation(load_scenario("step_pitch", ["duration_s=0.2"]))
    prof: dict = {}
    res = cs.run(profile=prof)
    assert set(prof) == {"physics", "sensors", "controllers", "pneumatics", "logging", "steps"}
    assert prof["steps"] == 201 and all(prof[s] > 0 for s in prof)
    plain = CoSimulation(load_scenario("step_pitch", ["duration_s=0.2"])).run()
    for name, col in res.columns.items():  # instrumenting does not change the run
        assert np.array_equal(col, plain.columns[name], equal_nan=True)
