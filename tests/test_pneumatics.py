"""Tests of simpro_mj.plant.pneumatics: flow law, equilibrium, integration, MuJoCo coupling."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from scipy.signal import lti, step

from simpro_mj.core.errors import UserInputError
from simpro_mj.plant.model import PlantIndex, assemble, check_physics, load_model
from simpro_mj.plant.pneumatics.factory import make_actuators
from simpro_mj.plant.pneumatics.flow import RHO_REF, iso6358_mass_flow, iso6358_phi
from simpro_mj.plant.pneumatics.linear import LinearActuators
from simpro_mj.plant.pneumatics.nonlinear import NonlinearActuators
from simpro_mj.plant.pneumatics.params import PneumaticParams, pneumatic_params
from simpro_mj.plant.pneumatics.statics import holding_forces, slide_mass_matrix

DT = 1e-3
HOME = np.full(3, 0.25)


@pytest.fixture(scope="module")
def plant():
    m = load_model()
    d = mujoco.MjData(m)
    idx = PlantIndex.of(m)
    assemble(m, d, HOME, index=idx)
    return m, d, idx, holding_forces(m, d, idx)


def _fresh(plant):
    m, _, idx, fh = plant
    d = mujoco.MjData(m)
    assemble(m, d, HOME, index=idx)
    return m, d, idx, fh


# ------------------------------------------------------------------ flow law


def test_flow_is_continuous_across_choked_subsonic_laminar():
    b, rl = 0.3, 0.999
    C, pu, T = 7.87e-8, 7e5, 293.15
    eps = 1e-9
    for r in (b, rl):  # both branch points
        lo = iso6358_mass_flow(C, pu, (r - eps) * pu, T, b, rl)
        hi = iso6358_mass_flow(C, pu, (r + eps) * pu, T, b, rl)
        assert abs(hi - lo) < 1e-4 * abs(lo)  # a jump would be O(1); slope-limited here
    # choked value is C rho0 p_u (ISO 6358 at T = T_ref)
    assert iso6358_mass_flow(C, pu, 0.1 * pu, T, b, rl) == pytest.approx(C * RHO_REF * pu)
    # no flow without a pressure drop, finite slope at r -> 1 (laminar region)
    assert iso6358_mass_flow(C, pu, pu, T, b, rl) == 0.0
    slope = iso6358_mass_flow(C, pu, pu * (1 - 1e-7), T, b, rl) / (pu * 1e-7)
    k_lam = math.sqrt(1 - ((rl - b) / (1 - b)) ** 2) / (1 - rl)
    assert slope == pytest.approx(C * RHO_REF * k_lam, rel=1e-6)
    # monotone decreasing in r, reverse flow antisymmetric
    r = np.linspace(0, 1, 20001)
    assert np.all(np.diff(iso6358_phi(r, b, rl)) <= 1e-15)
    assert iso6358_mass_flow(C, 3e5, 5e5, T, b, rl) == pytest.approx(
        -iso6358_mass_flow(C, 5e5, 3e5, T, b, rl)
    )


def test_step_flow_table_matches_formula():
    act = NonlinearActuators()
    P = act.params
    r = np.concatenate([np.linspace(0.0, 0.9999, 5001), [0.99995, 1.0]])
    phi_tab = act.psi(r) * (1 - r)
    phi = iso6358_phi(r, P.b_crit, P.r_laminar)
    assert np.max(np.abs(phi_tab - phi)) < 2e-4


# -------------------------------------------------------------- parameters


def test_unknown_kind_and_keys_are_rejected():
    with pytest.raises(UserInputError, match=r"allowed values are \['nonlinear', 'linear'\]"):
        make_actuators("hydraulic", None)
    with pytest.raises(UserInputError, match="pneumatics.valve.spool_bandwith_hz"):
        PneumaticParams.from_tree({"valve": {"spool_bandwith_hz": 50}})
    with pytest.raises(UserInputError, match="supply_pressure_bar_gauge"):
        PneumaticParams.from_tree({"supply_pressure_bar_gauge": -1})
    with pytest.raises(TypeError):
        NonlinearActuators(None, bogus=1)
    tree = pneumatic_params(["supply_pressure_bar_gauge=5"])
    assert PneumaticParams.from_tree(tree).p_supply == pytest.approx(5e5 + 101325)


# -------------------------------------------------------------- equilibrium


def test_static_equilibrium_carries_the_legs_share(plant):
    m, d, idx, fh = _fresh(plant)
    # the brief's shares: leg 1 about 2640 N (half the weight), legs 2, 3 about 1080 N
    assert fh[0] == pytest.approx(2640, rel=0.05)
    assert fh[1:] == pytest.approx([1080, 1080], rel=0.05)
    act = NonlinearActuators()
    act.reset(HOME, np.zeros(3), force=fh)
    P = act.params
    net = act.p1 * P.area_cap - act.p2 * P.area_rod_side - P.p_atm * P.area_rod
    np.testing.assert_allclose(net, fh, rtol=1e-6)
    assert np.all(act.p1 > act.p2)  # the cap side carries the load
    # zero net flow into every chamber at the holding spool
    for ch, p in ((1, act.p1), (2, act.p2)):
        assert np.all(np.abs(act.chamber_net_flow(p, act.spool, ch)) < 1e-8)
    # in MuJoCo, open loop at the holding voltage: the platform stays put
    d.ctrl[idx.actuators] = fh
    warn = d.warning.number.copy()
    for _ in range(2000):
        f = act.step(act.u_hold, d.qpos[idx.slide_qpos], d.qvel[idx.slide_dof], DT)
        d.ctrl[idx.actuators] = f
        mujoco.mj_step(m, d)
    check_physics(m, d, warn, loop_bound=1e-3, index=idx)
    drift = np.abs(d.qpos[idx.slide_qpos] - HOME)
    assert drift.max() < 2e-3, drift  # bound: 2 mm in 2 s


def test_centred_valve_holds_a_balanced_piston():
    """5 V, pressures at the centred equilibrium, balanced load: drift < 0.5 mm in 5 s."""
    act = NonlinearActuators()
    act.reset(HOME, np.zeros(3))
    P = act.params
    assert np.all(act.u_hold == 5.0)
    f0 = act.force_now(np.zeros(3)).copy()  # balanced by an external load -f0
    mass, q, v = 200.0, HOME.copy(), np.zeros(3)
    p_start = act.p1.copy()
    for _ in range(5000):
        f = act.step(np.full(3, 5.0), q, v, DT)
        v += (f - f0) / mass * DT
        q += v * DT
    assert np.max(np.abs(q - HOME)) < 5e-4
    assert np.max(np.abs(act.p1 - p_start)) < 0.01 * (P.p_supply - P.p_atm)


# ---------------------------------------------------------------- integration


def test_pressure_update_is_accurate_and_bounded_in_a_small_chamber():
    """Charging a nearly empty cap chamber (q = 2 mm) with full-scale voltage.

    The 1 ms linearly implicit step is compared with the same model
    sub-stepped 200 times (reference): the pressure stays in [pa, ps], rises
    monotonically without overshoot, and follows the reference within 3 % of
    the supply span.
    """
    q = np.full(3, 0.002)
    fine = NonlinearActuators(pneumatic_params(["integration.substeps=200"]))
    coarse = NonlinearActuators()
    for a in (fine, coarse):
        a.reset(q, np.zeros(3))
    P = coarse.params
    err, prev, p2_start = 0.0, coarse.p1.copy(), coarse.p2.copy()
    for _ in range(200):
        for a in (fine, coarse):
            a.step(np.full(3, 10.0), q, np.zeros(3), DT)
        assert np.all(coarse.p1 >= P.p_atm) and np.all(coarse.p1 <= P.p_supply)
        assert np.all(coarse.p1 >= prev - 1e-6)
        prev = coarse.p1.copy()
        err = max(err, np.max(np.abs(np.concatenate([coarse.p1 - fine.p1, coarse.p2 - fine.p2]))))
    assert err < 0.03 * (P.p_supply - P.p_atm)
    assert coarse.p1.min() > 0.99 * P.p_supply  # the small chamber fills up
    assert np.all(coarse.p2 < p2_start - 1e5)  # the (large) rod side empties


def test_full_scale_steps_into_both_end_stops_keep_pressures_physical(plant):
    m, d, idx, fh = _fresh(plant)
    act = make_actuators("nonlinear")
    act.reset(HOME, np.zeros(3), force=fh)
    P = act.params
    d.ctrl[idx.actuators] = fh
    warn = d.warning.number.copy()
    qs, lo, hi = [], np.inf, -np.inf
    for k in range(4000):
        u = np.full(3, 10.0 if k < 2000 else 0.0)
        f = act.step(u, d.qpos[idx.slide_qpos], d.qvel[idx.slide_dof], DT)
        d.ctrl[idx.actuators] = f
        mujoco.mj_step(m, d)
        lo = min(lo, act.p1.min(), act.p2.min())
        hi = max(hi, act.p1.max(), act.p2.max())
        qs.append(d.qpos[idx.slide_qpos].copy())
        if k % 100 == 0:
            check_physics(m, d, warn, index=idx)
    qs = np.array(qs)
    # no clipping: a little vacuum in the expanding chamber (3 %), nothing above the
    # supply beyond rounding (the open supply edge equalises at the stop)
    assert 0.95 * P.p_atm <= lo and hi <= 1.001 * P.p_supply
    assert np.all(qs[1999] > 0.49)  # reached the upper stops
    assert np.all(qs[-1] < 0.01)  # and the lower ones
    assert np.all(act.p2 > 0.98 * P.p_supply) and np.all(act.p1 < 1.05 * P.p_atm)


def test_closed_chamber_is_compressed_adiabatically_above_the_supply():
    """With both metering edges closed, pushing the piston in compresses
    the cap chamber as p V^n = const (n = 1.4), far above the supply: 4.45 times
    smaller volume from 5.6 bar gives ~45 bar, not the 7 bar of a supply clip."""
    act = make_actuators(
        "nonlinear",
        {"valve": {"underlap_fraction": 0.0, "leakage_fraction": 1e-9}},
    )
    P = act.params
    q0, q1, n = 0.25, 0.05, 2000
    act.reset(np.full(3, q0), np.zeros(3), force=np.full(3, 1500.0))
    p0 = act.p1.copy()
    v = (q1 - q0) / (n * DT)
    u = act.u_hold.copy()
    for k in range(n):
        q = np.full(3, q0 + v * (k + 1) * DT)
        act.step(u, q, np.full(3, v), DT)
    vol = lambda q: P.dead_cap + P.area_cap * q  # noqa: E731
    want = p0 * (vol(q0) / vol(q1)) ** P.n_poly
    assert np.all(act.p1 > 5 * P.p_supply)
    np.testing.assert_allclose(act.p1, want, rtol=0.05)
    assert np.all(np.isfinite(act.p2)) and np.all(act.p2 > 0)


# ------------------------------------------------------------------- linear


def test_linear_option_reproduces_eq19_step_response(plant):
    m, d, idx, fh = _fresh(plant)
    from controllers.design import paper_coefficients

    with pytest.raises(UserInputError, match="pneumatics.linear.b_m_per_s3_v"):
        make_actuators("linear", None, model=m)  # the plant knows no paper reading
    # eqs. (34)-(35) under the metres reading: the slide motion of the original test
    act = make_actuators("linear", None, model=m, linear_plants=paper_coefficients("metres"))
    assert isinstance(act, LinearActuators)
    np.testing.assert_allclose(act.mass_matrix, slide_mass_matrix(m, d, idx), rtol=1e-6)
    act.reset(HOME, np.zeros(3), force=fh)
    P = act.params
    du = np.array([0.02, 0.0, 0.004])  # a small step on legs 1 and 3, leg 2 at rest
    d.ctrl[idx.actuators] = fh
    n = 600
    q = np.empty((n, 3))
    for k in range(n):
        f = act.step(act.u_hold + du, d.qpos[idx.slide_qpos], d.qvel[idx.slide_dof], DT)
        d.ctrl[idx.actuators] = f
        mujoco.mj_step(m, d)
        q[k] = d.qpos[idx.slide_qpos]
    t = (np.arange(n) + 1) * DT
    for leg in (0, 2):
        sys = lti([P.lin_b[leg]], [1.0, P.lin_a1[leg], P.lin_a0[leg], 0.0])
        _, y = step(sys, T=t - DT)  # the force acts one step later
        y *= du[leg]
        err = np.max(np.abs(q[:, leg] - HOME[leg] - y))
        assert err < 0.03 * np.max(np.abs(y)), (leg, err, np.max(np.abs(y)))
    assert np.max(np.abs(q[:, 1] - HOME[1])) < 0.02 * np.max(np.abs(q[:, 2] - HOME[2]))
