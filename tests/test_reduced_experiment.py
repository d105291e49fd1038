"""The Fig. 12 experiment on the reduced chain (simpro_mj.identification.reduced_experiment)."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from simpro_mj.config.scenario import load_scenario
from simpro_mj.identification import reduced_experiment as rx
from simpro_mj.identification.auto import plant_tree
from simpro_mj.identification.identify import run_experiment


def _tree(sets: list, seconds: float) -> dict:
    """``step_pitch``'s own plant's experiment with a ``seconds`` record."""
    tree = copy.deepcopy(plant_tree(load_scenario("step_pitch", sets)))
    tree["identify"]["duration_s"] = seconds
    return tree


def _rest(v) -> float:
    return float(np.mean(np.abs(v) < 1e-4))


def test_the_friction_rows_are_mujocos_soft_constraint_at_zero_violation():
    """The seals' rows take MuJoCo's numbers (solref 2 ms = 2 steps, solimp 0.9999 on the
    heavy cabin): b = 2 / (d tau) = 1000.1 1/s, so a sticking slide's speed goes to
    (1 - h b) v = -1e-4 v in one step, and R = (1 - d)/d of the slide's invweight0;
    the breakaway force is the frictionloss (250 N). A slide held at the breakaway force
    creeps at h R F_S per step of the softness: below 1e-5 m/s, a tenth of what the
    records call rest (0.1 mm/s)."""
    rm = rx.reduced_model(_tree(["plant.preset=heavy_cabin"], 0.5))
    assert rm.integrator == "implicitfast"
    np.testing.assert_allclose(rm.b_ref, 2.0 / (0.9999 * 0.002))
    assert np.all(np.abs(1.0 - rm.em.dt * rm.b_ref) < 2e-4)
    np.testing.assert_allclose(rm.dry, [250.0, 250.0, 250.0])
    assert np.all(rm.em.dt * rm.r_reg * rm.dry < 1e-5)


def test_on_the_paper_plant_the_record_is_mujocos():
    """Where the seals barely matter (`paper`: 1.7 N against about 100 N of swing) the
    reduced chain's leg-1 speed follows MuJoCo's experiment sample by sample: the
    difference's RMS within 3 % of the speed's over a 2 s record, the voltage's within
    3 % of its swing (what is left: the chain's configuration dependence over a 2 mm
    swing, the closures' softness)."""
    tree = _tree([], 2.0)
    rec = rx.run_reduced(rx.reduced_model(tree), (1,))
    ref = run_experiment(tree, 1)
    v, vr = rec.qdot[:, 0], ref.qdot
    assert v.shape == vr.shape
    assert np.sqrt(np.mean((v - vr) ** 2)) < 0.03 * np.sqrt(np.mean(vr**2))
    u, ur = rec.u[:, 0], ref.u
    assert np.sqrt(np.mean((u - ur) ** 2)) < 0.03 * np.std(ur)


def test_on_the_heavy_cabin_the_stick_slip_is_mujocos():
    """Where the seals dominate (`heavy_cabin`, 150/250 N, the joint loops' 2 V dither)
    the experiment is a stick-slip: no sample-by-sample agreement, but the statistics
    the fit sees. Over a 6 s record of leg 1 MuJoCo's leg is at rest 75-90 % of the
    time (81 %; 63 % over 20 s); the reduced chain's share of rest lies within 0.05 of
    it (82 %) and its RMS speed within 25 % (1.81 against 1.70 mm/s). A Gaussian
    describing function of the same seals rests 3.5 % of the time
    (docs/paper-notes.md)."""
    tree = _tree(["plant.preset=heavy_cabin"], 6.0)
    rec = rx.run_reduced(rx.reduced_model(tree), (1,))
    ref = run_experiment(tree, 1)
    assert 0.75 < _rest(ref.qdot) < 0.9
    assert abs(_rest(rec.qdot[:, 0]) - _rest(ref.qdot)) < 0.05
    rms, rms_ref = np.sqrt(np.mean(rec.qdot[:, 0] ** 2)), np.sqrt(np.mean(ref.qdot**2))
    assert rms == pytest.approx(rms_ref, rel=0.25)


def test_compiled_and_interpreted_are_one_source(monkeypatch):
    """The stepper compiled (the step's own compiled functions bound in) and the plain
    function interpreted give the same record within 1e-9 relative (floating-point
    contraction aside) over 0.5 s of the heavy cabin's stick-slip."""
    tree = _tree(["plant.preset=heavy_cabin"], 0.5)
    rm = rx.reduced_model(tree)
    fast = rx.run_reduced(rm, (1,))
    monkeypatch.setenv("SIMPRO_KERNEL", "python")
    slow = rx.run_reduced(rm, (1,))
    scale = np.abs(slow.qdot).max()
    assert scale > 1e-3
    np.testing.assert_allclose(fast.qdot, slow.qdot, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(fast.u, slow.u, rtol=0, atol=1e-9 * 10.0)


@pytest.mark.slow
def test_the_fit_is_the_experiments_fit_on_the_record():
    """identify_reduced fits each leg by the experiment's own fit: on the paper plant
    of step_pitch (20 s records, seed 1) within 0.5 % of the MuJoCo experiment's fit on
    every parameter of every leg (measured: 0.03-0.12 %; the experiment's seeds 1-3
    spread by 0.01-0.3 %), at the experiment's holding point."""
    from simpro_mj.identification.identify import identify

    tree = copy.deepcopy(plant_tree(load_scenario("step_pitch", [])))
    got = rx.identify_reduced(tree)
    ref = identify(tree)
    for a, fit in got.items():
        for k in ("b", "a1", "a0"):
            assert getattr(fit, k) == pytest.approx(getattr(ref[a], k), rel=0.005), (a, k)
        assert fit.holding_voltage_v == pytest.approx(ref[a].holding_voltage_v, abs=1e-9)
        assert fit.holding_force_n == pytest.approx(ref[a].holding_force_n, rel=1e-9)


def test_the_friction_solves_numbers_do_not_move_the_result():
    """The friction solve's tolerance a tenth and ten times its default (1e-9 of the
    breakaway force), and half its sweeps, leave the heavy cabin's stick-slip record
    (leg 1, 3 s) the same within 1e-9 m/s and its fit within 1e-6 relative: the
    three-variable box QP converges to round-off in a few sweeps. Over 20 s the fits
    agree to five digits (docs/paper-notes.md)."""
    from simpro_mj.identification.sensitivity_fit import fit_sensitivity

    rm = rx.reduced_model(_tree(["plant.preset=heavy_cabin"], 3.0))
    base = rx.run_reduced(rm, (1,))
    fit = fit_sensitivity(base.u[:, 0], base.qdot[:, 0], base.dt, skip=200)
    for sweeps, tol in ((rx.PGS_SWEEPS, rx.PGS_TOL / 10), (rx.PGS_SWEEPS, rx.PGS_TOL * 10),
                        (rx.PGS_SWEEPS // 2, rx.PGS_TOL)):  # fmt: skip
        other = rx.run_reduced(rm, (1,), sweeps, tol)
        np.testing.assert_allclose(other.qdot, base.qdot, rtol=0, atol=1e-9)
        again = fit_sensitivity(other.u[:, 0], other.qdot[:, 0], other.dt, skip=200)
        for k in ("b", "a1", "a0"):
            assert getattr(again, k) == pytest.approx(getattr(fit, k), rel=1e-6)
