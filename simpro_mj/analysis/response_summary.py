"""A frequency response's prediction and summary: the scenario's linearised loop
(:func:`loop_model`, for :func:`controllers.frequency.predict`) and the measured
responses of :mod:`simpro_mj.analysis.response` tabulated beside it (:func:`summary`).

The linearised loop: the joint controllers as built, the plant the analysis
uses (the linear actuator's eq. 19 coefficients, or the identified plants
``controller.inner.identified`` for the nonlinear cylinders), the IK Jacobian
at home, the IMU filter, the outer law, gains and period.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from controllers.design import Plant
from controllers.frequency import (
    LoopModel,
    bandwidth_3db,
    equivalent_delay,
    phase_at,
    predict,
    unwrapped_phase_deg,
)
from controllers.kinematics import jacobian
from controllers.setpoint_filter import filter_state_space, leg_times
from controllers.task_space import outer_law
from controllers.velocity_feedforward import velocity_gains
from simpro_mj.analysis.response import _UNITS, AXES, ResponsePlan, failures
from simpro_mj.config.models import Scenario

__all__ = ["figures", "loop_model", "summary"]


def loop_model(scenario: Scenario | Mapping) -> LoopModel:
    """The scenario's linearised loop for :func:`controllers.frequency.predict`."""
    # the loop as built (MuJoCo): not loaded by the analyze command, which only
    # uses figures()
    from simpro_mj.sim.build import Build

    build = Build(scenario)
    cs = build.simulation()
    ctl = build.spec.controller
    identified = ctl.inner.identified.plants()
    if cs.actuators.kind == "linear":
        p = cs.actuators.params
        plants = [Plant(b=p.lin_b[i], a1=p.lin_a1[i], a0=p.lin_a0[i]) for i in range(3)]
    else:
        plants = identified
    o, ff, sf = ctl.outer, ctl.feedforward, ctl.setpoint_filter
    law, pi_zero = outer_law(o.type, o.integrator, o.pi_zero)
    mode = {"task_space": law, "feedforward": "feedforward"}.get(cs.mode, "joint_only")
    cfg = cs.sensor_cfg
    # Fig. 13's filter between q_d and the joint loops
    times = leg_times(np.asarray(sf.time_ms, float) * 1e-3)
    return LoopModel(
        plants=plants,
        designs=cs.joint.designs,
        jac=jacobian(cs.geometry.home),
        mode=mode,
        gains=np.asarray(ff.gains if cs.mode == "feedforward" else o.gains, float),
        period=cs.outer_every * cs.dt,
        dt=cs.dt,
        method=ctl.inner.discretisation,
        pi_zero=pi_zero,
        outer_law=law,
        imu_alpha=cfg.imu_alpha,
        imu_every=cfg.imu_every,
        model_tau=ff.model_tau_ms * 1e-3,
        setpoint_filter=[filter_state_space(sf.type, cs.dt, t) for t in times],
        lag=ff.lag,
        velocity_ff=velocity_gains(identified) if cs.u_ff is not None else np.zeros(3),
        average=ff.average,
    )


def _complex(pair) -> complex:
    return complex(pair[0], pair[1])


def _in_edge(axis_in: str, axis_out: str, h: complex) -> complex:
    """An SI ratio expressed in the edge units (deg/deg, mm/deg, deg/mm, mm/mm)."""
    return h * _UNITS[axis_in][1] / _UNITS[axis_out][1]


def summary(plan: ResponsePlan, results: list, model: LoopModel | None) -> dict:
    """Tables and per-axis figures from the measurements and the prediction.

    Returns a JSON-ready dict: ``rows`` (one per input axis, output axis,
    signal and frequency), ``axes`` (per excited axis, from the true pose:
    ``bandwidth_3db_hz``, ``phase_deg_at_0_5_hz``, ``phase_deg_at_1_hz``,
    ``equivalent_delay_ms``, and the same under ``predicted`` and
    ``measured_pose``), ``agreement`` (largest |measured - predicted| up to
    1 Hz on the excited axis), ``failed`` (frequencies that did not run),
    ``predicted_curves`` (per excited axis, its prediction on a dense grid
    between the lowest and highest measured frequency: ``frequency_hz`` and,
    for ``true`` and ``measured``, ``gain_db`` and ``phase_deg``; empty
    without a prediction).
    """
    periods = sorted(plan.periods_ms, reverse=True)
    freq = np.array([1000.0 / p for p in periods])
    omega = 2 * np.pi * freq
    pred = None
    if model is not None:
        # on a dense grid from well below the lowest frequency, so that the
        # predicted phase unwraps from ~0 deg whatever frequencies were asked for
        dense = np.unique(np.r_[np.geomspace(omega.min() / 20, omega.max(), 400), omega])
        full = predict(model, dense)
        at = np.searchsorted(dense, omega)
        pred = {sig: full[sig][at] for sig in ("true", "measured")}
        pred_phase = {
            sig: np.degrees(np.unwrap(np.angle(full[sig]), axis=0))[at]
            for sig in ("true", "measured")
        }
    by_key = {(r.get("axis"), r.get("period_ms")): r for r in results if r.get("status") == "ok"}
    failed = failures(plan.tasks, results, "axis")
    rows, axes, agreement = [], {}, {}
    for axis_in in plan.axes:
        j = AXES.index(axis_in)
        ok = [i for i, p in enumerate(periods) if (axis_in, p) in by_key]
        f_ok = freq[ok]
        curves = {}
        for sig in ("true", "measured"):
            h = np.full((len(periods), 3), np.nan + 0j)
            for i in ok:
                r = by_key[(axis_in, periods[i])]
                ref = _complex(r["ref"])
                h[i] = [_complex(v) / ref for v in r[sig]]
            curves[sig] = h
        diag_phase = {}
        for sig in ("true", "measured"):
            for o, axis_out in enumerate(AXES):
                hm = curves[sig][ok, o]
                hp = pred[sig][:, o, j] if pred is not None else None
                ph_p = pred_phase[sig][:, o, j] if pred is not None else None
                if not len(ok):
                    ph_m = np.array([])
                elif ph_p is not None:  # the branch nearest the prediction's
                    raw = np.degrees(np.angle(hm))
                    ph_m = raw + 360.0 * np.round((ph_p[ok] - raw) / 360.0)
                else:
                    ph_m = unwrapped_phase_deg(hm)
                if o == j:
                    diag_phase[sig] = ph_m
                for n, i in enumerate(ok):
                    r = by_key[(axis_in, periods[i])]
                    g = abs(_in_edge(axis_in, axis_out, hm[n]))
                    row = {
                        "input_axis": axis_in,
                        "output_axis": axis_out,
                        "signal": sig,
                        "frequency_hz": freq[i],
                        "omega_rad_s": omega[i],
                        "period_ms": periods[i],
                        "amplitude": plan.amplitudes[axis_in] / _UNITS[axis_in][1],
                        "gain": g,
                        "gain_db": 20 * math.log10(max(g, 1e-300)),
                        "phase_deg": float(ph_m[n]),
                        "predicted_gain_db": None,
                        "predicted_phase_deg": None,
                        "diff_db": None,
                        "diff_deg": None,
                        "saturated_pct": r["saturated_pct"],
                    }
                    if hp is not None and ph_p is not None:
                        gp = abs(_in_edge(axis_in, axis_out, hp[i]))
                        row["predicted_gain_db"] = 20 * math.log10(max(gp, 1e-300))
                        row["predicted_phase_deg"] = float(ph_p[i])
                        row["diff_db"] = row["gain_db"] - row["predicted_gain_db"]
                        d = float(np.degrees(np.angle(hm[n] / hp[i])))
                        row["diff_deg"] = d
                    rows.append(row)
        h_true = curves["true"][ok, j]
        enough = len(ok) >= 2
        axes[axis_in] = figures(f_ok, h_true, diag_phase["true"]) if enough else figures()
        axes[axis_in]["measured_pose"] = (
            figures(f_ok, curves["measured"][ok, j], diag_phase["measured"]) if enough else None
        )
        if pred is not None:
            axes[axis_in]["predicted"] = figures(
                freq, pred["true"][:, j, j], pred_phase["true"][:, j, j]
            )
            near = [
                r
                for r in rows
                if r["input_axis"] == axis_in
                and r["output_axis"] == axis_in
                and r["frequency_hz"] <= 1.0 + 1e-9
            ]
            agreement[axis_in] = {
                sig: {
                    "max_abs_diff_db": max(
                        (abs(r["diff_db"]) for r in near if r["signal"] == sig), default=None
                    ),
                    "max_abs_diff_deg": max(
                        (abs(r["diff_deg"]) for r in near if r["signal"] == sig), default=None
                    ),
                }
                for sig in ("true", "measured")
            }
    predicted: dict[str, dict] = {}
    if pred is not None:  # the prediction between the measured frequencies, to draw as curves
        span = (dense >= omega.min() * (1 - 1e-9)) & (dense <= omega.max() * (1 + 1e-9))
        for axis_in in plan.axes:
            j = AXES.index(axis_in)
            predicted[axis_in] = {"frequency_hz": (dense[span] / (2 * np.pi)).tolist()}
            for sig in ("true", "measured"):
                h = full[sig][span, j, j]
                phase = np.degrees(np.unwrap(np.angle(full[sig][:, j, j])))[span]
                predicted[axis_in][sig] = {
                    "gain_db": (20 * np.log10(np.maximum(np.abs(h), 1e-300))).tolist(),
                    "phase_deg": phase.tolist(),
                }
    return {
        "rows": rows,
        "axes": axes,
        "agreement": agreement,
        "failed": failed,
        "predicted_curves": predicted,
    }


def figures(freq=(), h=(), phase_deg=()) -> dict:
    """Bandwidth, phases at 0.5 and 1 Hz and equivalent delay of one response curve."""
    if len(freq) < 2:
        return {
            "bandwidth_3db_hz": None,
            "bandwidth_above_hz": None,
            "phase_deg_at_0_5_hz": None,
            "phase_deg_at_1_hz": None,
            "equivalent_delay_ms": None,
        }
    f = np.asarray(freq, float)
    h = np.asarray(h)
    order = np.argsort(f)
    f, h, ph = f[order], h[order], np.asarray(phase_deg, float)[order]
    bw = bandwidth_3db(f, h)
    tau = equivalent_delay(f, h, phase_deg=ph)
    return {
        "bandwidth_3db_hz": bw,
        # None bandwidth: the gain stays within 3 dB up to this frequency
        "bandwidth_above_hz": float(f[-1]) if bw is None else None,
        "phase_deg_at_0_5_hz": phase_at(f, h, 0.5, ph),
        "phase_deg_at_1_hz": phase_at(f, h, 1.0, ph),
        "equivalent_delay_ms": None if tau is None else tau * 1e3,
    }
