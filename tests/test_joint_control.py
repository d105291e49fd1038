"""Joint loops: pole placement, printed/corrected controllers, discretisation, anti-windup."""

from __future__ import annotations

import subprocess
import sys

import control
import numpy as np
import pytest

from controllers.analysis.inner import companion, tf_step
from controllers.design import (
    ACTUATORS,
    PLANTS,
    Plant,
    closed_loop_poles,
    closed_loop_tf,
    corrected_design,
    damping,
    design_for,
    nondominant_poles_from_denominator,
    paper_plant,
    paper_scale,
    place_poles,
    printed_design,
    redesigned_design,
    reduced_polynomial,
)
from controllers.errors import DesignError
from controllers.joint import JointControllers, discretise, expm, split_integrator

P = np.polymul


def _match(a, b):
    """Max distance between two root sets, matched greedily."""
    a, b = list(np.asarray(a, complex)), list(np.asarray(b, complex))
    worst = 0.0
    for x in a:
        j = int(np.argmin([abs(x - y) for y in b]))
        worst = max(worst, abs(x - b.pop(j)))
    return worst


# --------------------------------------------------------------------------
# pole placement
# --------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(25))
def test_pole_placement_places_requested_poles(seed):
    rng = np.random.default_rng(seed)
    plant = Plant(b=rng.uniform(10, 5000), a1=rng.uniform(1, 60), a0=rng.uniform(20, 3000))
    zeta, wn = rng.uniform(0.3, 1.2), rng.uniform(2, 40)
    p1, p2 = rng.uniform(2, 12, size=2) * zeta * wn
    des = place_poles(plant, zeta, wn, p1, p2)
    # independent: full characteristic polynomial den_C den_G + num_C num_G
    num_c = des.kp * P([1, des.ki], [1, des.n1, des.n0])
    den_c = [1, des.c1, des.c0, 0]
    char = np.polyadd(P(den_c, [1, plant.a1, plant.a0, 0]), P(num_c, [plant.b]))
    want = P(P([1, p1], [1, p2]), [1, 2 * zeta * wn, wn**2])
    np.testing.assert_allclose(char, P(want, [1, plant.a1, plant.a0]), rtol=1e-9)
    # and the roots of the reduced loop are the requested poles
    red = np.polyadd([1, des.c1, des.c0, 0, 0], des.kp * plant.b * np.array([1, des.ki]))
    spec = np.r_[-p1, -p2, np.roots([1, 2 * zeta * wn, wn**2])]
    assert _match(np.roots(red), spec) < 1e-6 * max(p1, p2, wn)
    # eq. (29): the zero -k_i is fixed by the poles, 1/k_i = 1/p1 + 1/p2 + 2 zeta/wn
    assert des.ki == pytest.approx(1 / (1 / p1 + 1 / p2 + 2 * zeta / wn), rel=1e-9)


@pytest.mark.parametrize(
    "plant, spec",
    [
        (Plant(0.0, 10, 100), (0.7, 10, 50, 60)),  # b = 0
        (Plant(100, -1.0, 100), (0.7, 10, 50, 60)),  # unstable cancelled quadratic
        (Plant(100, 10, 100), (0.0, 10, 50, 60)),  # zeta = 0
        (Plant(100, 10, 100), (0.7, -10, 50, 60)),  # wn < 0
        (Plant(100, 10, 100), (0.7, 10, -5, 60)),  # unstable non-dominant pole
        (Plant(100, 10, np.nan), (0.7, 10, 50, 60)),
    ],
)
def test_pole_placement_infeasible_raises(plant, spec):
    with pytest.raises(DesignError):
        place_poles(plant, *spec)
    assert issubclass(DesignError, ValueError)


# --------------------------------------------------------------------------
# the paper's controllers
# --------------------------------------------------------------------------
def test_printed_poles_match_hand_multiplied_polynomial():
    # eq. (34) with eq. (36) as printed; eq. (35) (with its missing s) with eq. (37)
    cases = {
        "actuator1": ([1, 27.72, 253], 245.94, 265.0, [1, 7.726, 253]),
        "actuator2": ([1, 7.276, 1349], 2008.3, 32.0, [1, 7.726, 1349]),
    }
    for act, (quad, b, kp, numq) in cases.items():
        char = np.polyadd(
            P(P([1, 0], quad), P([1, 0], [1, 146.7, 6267])), b * kp * P([1, 3.03], numq)
        )
        assert char.size == 7  # 6th order: nothing cancels
        poles = closed_loop_poles(printed_design(act), PLANTS[act])
        assert _match(poles, np.roots(char)) < 1e-6


def test_paper_spec_not_met_by_printed_or_corrected():
    """The paper claims zeta = 0.7, wn = 10 rad/s; neither printed reading gives it."""
    for act in ("actuator1", "actuator2"):
        for des in (printed_design(act), corrected_design(act)):
            poles = closed_loop_poles(des, PLANTS[act])
            wn, zeta = damping(poles)
            near = np.abs(poles - complex(-7.0, 7.1414)) < 1.0
            assert not near.any()
    # corrected: reduced loop s^4 + 146.7 s^3 + 6267 s^2 + kp b s + kp b 3.03
    wn, zeta = damping(closed_loop_poles(corrected_design("actuator1"), PLANTS["actuator1"]))
    slow = np.argsort(wn)[:2]
    assert np.all(zeta[slow] > 0.99)  # a (nearly) double real pole, not zeta = 0.7
    # printed actuator 1: the uncancelled plant modes leave a zeta ~ 0.24 pair
    wn, zeta = damping(closed_loop_poles(printed_design("actuator1"), PLANTS["actuator1"]))
    assert zeta.min() < 0.3


def test_printed_denominator_implies_p1_p2_and_redesign_meets_spec():
    # c1 = p1 + p2 + 2 zeta wn, c0 = p1 p2 + 2 zeta wn (p1 + p2) + wn^2 with 146.7, 6267
    p1, p2 = nondominant_poles_from_denominator(146.7, 6267.0, 0.7, 10.0)
    assert (p1, p2) == (pytest.approx(76.0, abs=1e-6), pytest.approx(56.7, abs=1e-6))
    for act in ("actuator1", "actuator2"):
        des = redesigned_design(act)
        assert des.c1 == pytest.approx(146.7) and des.c0 == pytest.approx(6267.0)
        # k_p b = 14 * 76 * 56.7 + 100 * (76 + 56.7); k_i = 100 * 76 * 56.7 / (k_p b)
        kpb = 14 * 76 * 56.7 + 100 * 132.7
        assert des.kp * PLANTS[act].b == pytest.approx(kpb, rel=1e-9)
        assert des.ki == pytest.approx(100 * 76 * 56.7 / kpb, rel=1e-9)
        poles = closed_loop_poles(des, PLANTS[act])
        wn, zeta = damping(poles)
        pair = np.abs(poles - complex(-7.0, 7.0 * np.sqrt(1 / 0.49 - 1))) < 1e-6
        assert pair.sum() == 1 and np.isclose(wn[pair][0], 10.0)


# --------------------------------------------------------------------------
# discrete implementation
# --------------------------------------------------------------------------
def _ss(plant):
    s = control.tf2ss(plant.num, plant.den)
    return s.A, s.B, s.C, s.D


def _simulate(jc, step, t_end=3.0, q0=0.25):
    """Legs = plants eqs. (34)-(35) in SI under the controllers' units reading,
    discretised by ZOH (exact for the held volts)."""
    dt = jc.dt
    plants = [paper_plant(a, jc.reading) for a in ("actuator1", "actuator2", "actuator3")]
    mats = [discretise(*_ss(p), dt, "zoh") for p in plants]
    xs = [np.zeros(3) for _ in range(3)]
    ref = q0 + np.asarray(step, float)
    n = int(round(t_end / dt))
    q_log, v_log, i_log = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    for k in range(n):
        q = q0 + np.array([(m[2] @ x)[0] for m, x in zip(mats, xs, strict=True)])
        v = jc.update(ref, q)
        xs = [
            m[0] @ x + m[1][:, 0] * (vi - jc.u_offset) for m, x, vi in zip(mats, xs, v, strict=True)
        ]
        q_log[k], v_log[k], i_log[k] = q - q0, v, jc.integrator
    return np.arange(n) * dt, q_log, v_log, i_log


@pytest.mark.parametrize("reading", ["volts", "metres"])
@pytest.mark.parametrize("variant", ["printed", "corrected", "redesigned"])
def test_tustin_preserves_continuous_step_response(variant, reading):
    """Tustin at 1 ms: the sampled loop follows the continuous one within 1 % of the step;
    under either units reading of eqs. (34)-(37) (k_p b, hence the loop, is the same)."""
    step = 0.5e-3  # small: no saturation (k_p = 5.3 kV/m for actuator 1, volts reading)
    jc = JointControllers(variant, dt=1e-3, method="tustin", reading=reading)
    t, q, v, _ = _simulate(jc, [step] * 3)
    assert np.all((v > 0) & (v < 10))
    for leg, act in enumerate(("actuator1", "actuator2", "actuator3")):
        des = design_for(act, variant, reading=reading)
        yc = tf_step(*closed_loop_tf(des, paper_plant(act, reading)), t)
        err = np.max(np.abs(q[:, leg] / step - yc))
        assert err < 0.01, (act, err)


def test_zoh_variant_is_stable_and_tracks():
    jc = JointControllers("corrected", method="zoh")
    _, q, _, _ = _simulate(jc, [1e-3] * 3, t_end=4.0)
    np.testing.assert_allclose(q[-1], 1e-3, rtol=5e-3)


def test_units_reading_scales_the_printed_gains():
    """Y in potentiometer volts (20 V/m): eq. (34)'s b = 245.94 V/s^3/V is 12.30 m/s^3/V
    and eq. (36)'s k_p = 265 V/V is 5300 V/m; the product k_p b stays 65 174."""
    assert paper_scale("volts") == 20.0 and paper_scale("metres") == 1.0
    p = paper_plant("actuator1", "volts")
    assert p.b == pytest.approx(12.297, abs=1e-3)
    assert paper_plant("actuator2", "volts").b == pytest.approx(100.415, abs=1e-3)
    d = printed_design("actuator1", "volts")
    assert d.kp == pytest.approx(5300.0)
    assert d.kp * p.b == pytest.approx(265.0 * 245.94)
    jc = JointControllers("printed", reading="volts")
    assert jc.designs[1].kp == pytest.approx(640.0)
    assert JointControllers("printed", reading="metres").designs[1].kp == pytest.approx(32.0)
    with pytest.raises(ValueError, match="volts"):
        JointControllers(reading="inches")


def test_corrected_design_on_another_plant_keeps_the_printed_loop():
    """On an identified plant the corrected controller rescales k_p so that k_p b, and so
    the reduced loop of eq. (29), stays the printed one: same closed-loop poles."""
    ident = Plant(b=34.4, a1=25.2, a0=211.0)
    d = corrected_design("actuator1", ident)
    assert d.kp * ident.b == pytest.approx(265.0 * 245.94)
    want = np.sort_complex(
        np.roots(reduced_polynomial(printed_design("actuator1"), PLANTS["actuator1"]))
    )
    got = np.sort_complex(np.roots(reduced_polynomial(d, ident)))
    np.testing.assert_allclose(got, want, rtol=1e-9)


def test_split_integrator_is_exact_partial_fraction():
    des = corrected_design("actuator1")
    r0, (kp, m1, m0) = split_integrator(des)
    s = np.array([0.3j, 2.0 + 1j, 17.0, 100j])
    c = np.polyval(des.num, s) / np.polyval(des.den, s)
    parts = r0 / s + np.polyval([kp, m1, m0], s) / np.polyval([1, des.c1, des.c0], s)
    np.testing.assert_allclose(parts, c, rtol=1e-10)
    assert r0 == pytest.approx(des.kp * des.ki * des.n0 / des.c0)


def test_offset_and_saturation():
    jc = JointControllers()
    v = jc.update(np.full(3, 0.25), np.full(3, 0.25))
    np.testing.assert_allclose(v, 5.0)
    v = jc.update(np.full(3, 0.45), np.full(3, 0.05))  # 0.4 m error: kp * 0.4 >> 5 V
    np.testing.assert_allclose(v, 10.0)
    v = jc.update(np.full(3, 0.05), np.full(3, 0.45))
    np.testing.assert_allclose(v, 0.0)


@pytest.mark.parametrize("aw", ["back_calculation", "conditional"])
def test_anti_windup_bounds_integrator(aw):
    """Blocked cylinder: constant error for 10 s with the valve saturated."""
    e = 0.05
    jc = JointControllers("corrected", anti_windup=aw)
    free = JointControllers("corrected", anti_windup="none")
    ref, meas = np.full(3, 0.3), np.full(3, 0.3 - e)
    for _ in range(10000):
        jc.update(ref, meas)
        free.update(ref, meas)
    r0 = np.array([split_integrator(d)[0] for d in jc.designs])
    # without anti-windup the integrator ramps: r0 * e * 10 s
    np.testing.assert_allclose(free.integrator, r0 * e * 10.0, rtol=1e-2)
    # with it: bounded by the back-calculation equilibrium u - u_sat = T_t r0 e plus C_r(0) e
    crest0 = np.array([split_integrator(d)[1][2] / d.c0 for d in jc.designs])
    bound = 5.0 + jc.tracking_time * r0 * e + np.abs(crest0) * e + 1e-6
    assert np.all(np.abs(jc.integrator) <= bound)
    before = jc.integrator
    jc.update(ref, meas)
    assert np.all(np.abs(jc.integrator - before) < 1e-6)  # settled, not ramping


def test_back_calculation_pulls_a_dithered_command_to_the_centre():
    """A held 10 mm error under a +-4 V, 40 ms square dither (the cabin's leg-1 loop).

    Back-calculation settles where the integrator's input ``r0 T e`` equals the mean
    excess ``(T / T_t) E[v - v_sat]``; a square of +-a around a mean m exceeds the
    upper rail by ``(m + a - 10) / 2`` on average, so ``m = 10 - a + 2 T_t r0 e`` and
    the applied mean is ``(10 + m - a) / 2 = 10 - a + T_t r0 e``: about 6.2 V, far
    from the open valve the error asks for. Conditional integration only stops
    while the command grows into a rail, so it climbs until both halves saturate:
    10 V.
    """
    from controllers.design import Plant

    plants = [Plant(4.899, 12.09, 50.21), Plant(21.41, 34.48, 218.7), Plant(21.41, 34.48, 218.7)]
    e, a, n_half = 0.010, 4.0, 20
    ref, meas = np.full(3, 0.3), np.full(3, 0.3 - e)
    means = {}
    for aw in ("back_calculation", "conditional"):
        jc = JointControllers("corrected", plants=plants, anti_windup=aw)
        v = np.zeros((12000, 3))  # the conditional integrator reaches its rail by 6 s
        for k in range(12000):
            v[k] = jc.update(ref, meas, np.full(3, a if (k // n_half) % 2 == 0 else -a))
        means[aw] = v[-4000:].mean(axis=0)  # whole dither periods
    r0 = np.array([split_integrator(d)[0] for d in jc.designs])
    expect = 10.0 - a + jc.tracking_time * r0 * e
    np.testing.assert_allclose(means["back_calculation"], expect, atol=0.05)
    assert np.all(expect < 6.5)
    np.testing.assert_allclose(means["conditional"], 10.0, atol=1e-9)


def test_rejects_bad_arguments():
    with pytest.raises(TypeError):
        JointControllers(bogus=1)
    with pytest.raises(ValueError):
        JointControllers("typo")
    with pytest.raises(ValueError):
        JointControllers(method="euler")
    with pytest.raises(ValueError):
        JointControllers(u_min=10, u_max=0)
    with pytest.raises(ValueError):
        JointControllers("corrected", spec={"zeta": 0.7})
    with pytest.raises(ValueError):
        JointControllers("redesigned", spec={"zta": 0.7})


def test_controllers_import_without_mujoco():
    code = (
        "import sys, controllers, controllers.joint, controllers.design, "
        "controllers.task_space, controllers.analysis\n"
        "bad = [m for m in ('mujoco', 'simpro_mj', 'matplotlib') if m in sys.modules]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize("variant", ["printed", "corrected", "redesigned"])
def test_the_closed_forms_equal_c2d(variant):
    """discretise (the closed forms the 1 ms controllers run on, kept by hand: see its notes)
    equals python-control's c2d on the joint controllers' realisation, Tustin and ZOH, to
    1e-12 of each matrix's largest entry (inv against solve: rounding only)."""
    des = design_for("actuator2", variant, plant=paper_plant("actuator2"))
    r0, (kp, m1, m0) = split_integrator(des)
    a = np.array([[0.0, 1.0], [-des.c0, -des.c1]])
    b = np.array([[0.0], [1.0]])
    c = np.array([[m0 - kp * des.c0, m1 - kp * des.c1]])
    d = np.array([[kp]])
    for method in ("tustin", "zoh"):
        ref = control.c2d(control.ss(a, b, c, d), 1e-3, method=method)
        got = discretise(a, b, c, d, 1e-3, method)
        for g, w in zip(got, (ref.A, ref.B, ref.C, ref.D), strict=True):
            np.testing.assert_allclose(g, w, rtol=0, atol=1e-12 * np.abs(w).max())
    with pytest.raises(ValueError, match="allowed"):
        discretise(a, b, c, d, 1e-3, "euler")


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_expm_equals_scipys_on_the_zoh_discretisations(dt):
    """expm (the ZOH's exponential, kept free of scipy's import) equals scipy.linalg.expm
    to 1e-15 of the largest entry on every actuator's ZOH matrix ``[[A, B], [0, 0]] T``
    (norms 0.3-14): float rounding only."""
    from scipy.linalg import expm as scipy_expm

    for actuator in ACTUATORS:
        plant = paper_plant(actuator)
        ap, bp, _, _ = companion(plant.num, plant.den)
        n = ap.shape[0]
        big = np.zeros((n + 1, n + 1))
        big[:n, :n], big[:n, n:] = ap, bp
        want = scipy_expm(big * dt)
        np.testing.assert_allclose(expm(big * dt), want, rtol=0, atol=1e-15 * np.abs(want).max())
    np.testing.assert_array_equal(expm(np.zeros((3, 3))), np.eye(3))
    assert expm([[1.0]])[0, 0] == pytest.approx(np.e, rel=1e-15)
