"""The linear model of the Fig. 12 experiment (simpro_mj.identification.linear_experiment)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simpro_mj.config.scenario import load_scenario
from simpro_mj.identification import linear_experiment as le
from simpro_mj.identification.linear_pneumatics import equivalent_viscous
from simpro_mj.identification.settings import default_tree


@pytest.fixture(scope="module")
def paper():
    """The paper preset's experiment, its linear model and leg 1's closed loop."""
    tree = default_tree("paper")
    em = le.build(tree)
    details: dict = {}
    fits = le.identify_linear(tree, details=details, experiment=em)
    return tree, em, fits, details


def test_the_coulomb_describing_function_is_booton_s_closed_form():
    """A Gaussian speed of RMS s through a Coulomb force F_C (MuJoCo's dry friction, no
    Stribeck peak, no viscous part) acts as F_C sqrt(2/pi) / s; the Stribeck peak
    F_S - F_C adds its share v_S^2 / (v_S^2 + 2 s^2); the regularised curve (tanh)
    tends to the same with a small smoothing speed."""
    s = 0.004
    coulomb = (150.0, (150.0, 150.0, 0.01, 0.0, 0.0))
    assert equivalent_viscous(coulomb, s) == pytest.approx(150.0 * math.sqrt(2 / math.pi) / s)
    stick = (250.0, (250.0, 150.0, 0.01, 300.0, 0.0))
    k = math.sqrt(2 / math.pi) / s
    want = 150.0 * k + 100.0 * k * 0.01**2 / (0.01**2 + 2 * s**2)
    assert equivalent_viscous(stick, s) == pytest.approx(want)
    regularised = (0.0, (250.0, 150.0, 0.01, 300.0, 1e-6))  # quadrature of seal_friction
    assert equivalent_viscous(regularised, s) == pytest.approx(want, rel=2e-3)


def test_the_modal_simulation_is_the_step_by_step_one(paper):
    """The closed loop stepped mode by mode (lfilter per eigenvalue) gives the states
    the plain recursion x+ = Phi x + Gamma e gives: the excited leg's slide, speed and
    spool to 1e-8 of their range; the held legs' (locked: 1e-8 m) to 1e-12 m."""
    _, em, _, details = paper
    res = details["actuator1"]
    phi, gam, *_ = le.closed_loop(em, 1, le._matrices(em, res.sigma_s), res.c_eq)
    rng = np.random.default_rng(1)
    inputs = np.column_stack([np.zeros(3000), np.repeat(rng.choice([-0.3, 0.3], 150), 20)])
    modal = le.simulate(phi, gam, inputs)
    x = np.zeros(phi.shape[0])
    loop = np.empty_like(modal)
    for k in range(inputs.shape[0]):
        loop[k] = x
        x = phi @ x + gam @ inputs[k]
    err = np.abs(modal - loop).max(axis=0)
    own = [0, 3, 6 + em.n_leg - 1]  # leg 1's slide, speed, spool
    assert np.all(err[own] < 1e-8 * np.abs(loop[:, own]).max(axis=0))
    assert np.all(err[[1, 2, 4, 5]] < 1e-12)


def test_the_stationary_statistics_are_the_records(paper):
    """The fixed point's speed RMS (a Lyapunov equation over the bits) is the RMS of the
    simulated 20 s record within 3 % (the sequence's finite length and start)."""
    _, em, _, details = paper
    res = details["actuator1"]
    record = np.sqrt(np.mean(res.qdot**2))
    assert res.sigma_v[0] == pytest.approx(record, rel=0.03)
    assert res.iterations < le.MAX_ITER


def test_the_experiments_linear_model_fits_the_presets_identified_models(paper):
    """On the paper preset the fit of the experiment's linear model lands within 3 % of
    the preset's identified models (the experiment's fit) on every parameter of every
    leg: 0.6 / 1.1 / -0.4 % on leg 1, -2.2 / -0.6 / -0.3 % on legs 2 and 3. The leg's
    own linearisation (the others held rigidly, no seal friction) missed legs 2 and 3's
    a1 by 69 % (docs/paper-notes.md)."""
    _, _, fits, _ = paper
    given = load_scenario("step_pitch", []).controller.inner.identified
    for a in ("actuator1", "actuator2", "actuator3"):
        want = getattr(given, a)
        for k in ("b", "a1", "a0"):
            assert getattr(fits[a], k) == pytest.approx(getattr(want, k), rel=0.03), (a, k)


def test_the_held_legs_seals_lock_and_the_excited_leg_moves(paper):
    """While leg 1 is excited, the P loops hold legs 2 and 3 against seals of 1.7 N: the
    describing function locks them (speed RMS below 10 um/s) and leg 1 moves at
    millimetres per second."""
    _, _, _, details = paper
    res = details["actuator1"]
    assert 1e-3 < res.sigma_v[0] < 2e-2
    assert np.all(res.sigma_v[1:] < le.SIGMA_V_LOCKED)


@pytest.mark.slow
def test_the_linear_model_and_the_experiment_agree_on_the_paper_preset(paper):
    """The same experiment run in MuJoCo and fitted: the linear model's b, a1, a0 within
    3 % of it on every leg (the largest, legs 2 and 3's b, about -1.9 %)."""
    from simpro_mj.identification.identify import identify

    tree, _, fits, _ = paper
    got = identify(tree)
    for a in got:
        for k in ("b", "a1", "a0"):
            assert getattr(fits[a], k) == pytest.approx(getattr(got[a], k), rel=0.03), (a, k)
