"""A frequency response's prediction and summary: the scenario's linearised loop
(:func:`loop_model`, for :func:`controllers.frequency.predict`) and the measured
responses of :mod:`simpro_mj.analysis.response` tabulated beside it (:func:`summary`).

The linearised loop: the joint controllers as built, the plant the analysis
uses (the linear actuator's eq. 19 coefficients, or the identified plants
``controller.inner.identified`` for the nonlinear cylinders), the IK Jacobian
at home, the IMU filter, the outer law, gains and period.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field

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
from simpro_mj.analysis.response import (
    AXES,
    UNITS,
    Failed,
    SinePlan,
    db,
    dense_grid,
    failures,
    fits,
    in_edge,
)
from simpro_mj.config.models import Scenario


@dataclass
class CurveFigures:
    """Bandwidth, phases at 0.5 and 1 Hz and equivalent delay of one response curve
    (``None``: fewer than two measured frequencies, or not crossed)."""

    bandwidth_3db_hz: float | None = None
    #: with no bandwidth: the gain stays within 3 dB up to this frequency
    bandwidth_above_hz: float | None = None
    phase_deg_at_0_5_hz: float | None = None
    phase_deg_at_1_hz: float | None = None
    equivalent_delay_ms: float | None = None


@dataclass
class AxisFigures(CurveFigures):
    """An excited axis' figures from the true pose, with the measured pose's and the
    prediction's (``predicted`` only with a loop model)."""

    measured_pose: CurveFigures | None = None
    predicted: CurveFigures | None = None

    def to_json(self) -> dict:
        return {k: v for k, v in asdict(self).items() if k != "predicted" or v is not None}


@dataclass
class ResponseRow:
    """One measured ratio: an output axis' response to a sine on the input axis at one
    frequency (edge units: deg/deg, mm/deg, deg/mm, mm/mm), beside the prediction."""

    input_axis: str
    output_axis: str
    signal: str  # "true" or "measured" pose
    frequency_hz: float
    omega_rad_s: float
    period_ms: int
    amplitude: float
    gain: float
    gain_db: float
    phase_deg: float
    predicted_gain_db: float | None = None
    predicted_phase_deg: float | None = None
    diff_db: float | None = None
    diff_deg: float | None = None
    saturated_pct: float = 0.0


@dataclass
class Agreement:
    """Largest |measured - predicted| up to 1 Hz on the excited axis."""

    max_abs_diff_db: float | None
    max_abs_diff_deg: float | None


@dataclass
class Bode:
    """A predicted curve's gain (dB) and phase (deg) on its grid."""

    gain_db: list[float]
    phase_deg: list[float]

    @classmethod
    def of(cls, gain: np.ndarray, phase_deg: np.ndarray) -> Bode:
        """The curve of a gain (a ratio) and a phase (deg) on a grid."""
        return cls((20 * np.log10(np.maximum(gain, 1e-300))).tolist(), phase_deg.tolist())


@dataclass
class PredictedCurve:
    """The prediction of one excited axis on a dense grid between the measured
    frequencies, for the true and the measured pose."""

    frequency_hz: list[float]
    true: Bode
    measured: Bode


@dataclass
class PoseResponse:
    """The summary of a pose frequency response (:func:`summary`)."""

    rows: list[ResponseRow] = field(default_factory=list)
    #: per excited axis
    axes: dict[str, AxisFigures] = field(default_factory=dict)
    #: per excited axis and signal ("true", "measured"); empty without a prediction
    agreement: dict[str, dict[str, Agreement]] = field(default_factory=dict)
    #: the frequencies that did not run
    failed: list[Failed] = field(default_factory=list)
    predicted_curves: dict[str, PredictedCurve] = field(default_factory=dict)

    def to_json(self) -> dict:
        return {
            "rows": [asdict(r) for r in self.rows],
            "axes": {a: v.to_json() for a, v in self.axes.items()},
            "agreement": {
                a: {sig: asdict(x) for sig, x in v.items()} for a, v in self.agreement.items()
            },
            "failed": [f.as_json("axis") for f in self.failed],
            "predicted_curves": {a: asdict(c) for a, c in self.predicted_curves.items()},
        }


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


def summary(plan: SinePlan, results: list, model: LoopModel | None) -> PoseResponse:
    """Tables and per-axis figures from the measurements and the prediction.

    Returns the :class:`PoseResponse`: ``rows`` (one per input axis, output axis,
    signal and frequency), ``axes`` (per excited axis, from the true pose, and the
    same for the measured pose and the prediction), ``agreement`` (largest
    |measured - predicted| up to 1 Hz on the excited axis), ``failed`` (frequencies
    that did not run), ``predicted_curves`` (per excited axis, its prediction on a
    dense grid between the lowest and highest measured frequency; empty without a
    prediction).
    """
    periods = sorted(plan.periods_ms, reverse=True)
    freq = np.array([1000.0 / p for p in periods])
    omega = 2 * np.pi * freq
    pred = None
    dense, at, span = dense_grid(omega, 400)
    if model is not None:
        full = predict(model, dense)
        pred = {sig: full[sig][at] for sig in ("true", "measured")}
        pred_phase = {
            sig: np.degrees(np.unwrap(np.angle(full[sig]), axis=0))[at]
            for sig in ("true", "measured")
        }
    by_key = fits(plan.tasks, results)
    out = PoseResponse(failed=failures(plan.tasks, results))
    rows, axes = out.rows, out.axes
    for axis_in in plan.inputs:
        j = AXES.index(axis_in)
        ok = [i for i, p in enumerate(periods) if (axis_in, p) in by_key]
        f_ok = freq[ok]
        curves = {}
        for sig in ("true", "measured"):
            h = np.full((len(periods), 3), np.nan + 0j)
            for i in ok:
                r = by_key[(axis_in, periods[i])]
                ref = complex(*r.ref)
                h[i] = [complex(*v) / ref for v in (r.true if sig == "true" else r.measured)]
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
                    g = abs(in_edge(axis_in, axis_out, hm[n]))
                    row = ResponseRow(
                        input_axis=axis_in,
                        output_axis=axis_out,
                        signal=sig,
                        frequency_hz=freq[i],
                        omega_rad_s=omega[i],
                        period_ms=periods[i],
                        amplitude=plan.amplitudes[axis_in] / UNITS[axis_in][1],
                        gain=g,
                        gain_db=db(g),
                        phase_deg=float(ph_m[n]),
                        saturated_pct=r.saturated_pct,
                    )
                    if hp is not None and ph_p is not None:
                        row.predicted_gain_db = db(abs(in_edge(axis_in, axis_out, hp[i])))
                        row.predicted_phase_deg = float(ph_p[i])
                        row.diff_db = row.gain_db - row.predicted_gain_db
                        row.diff_deg = float(np.degrees(np.angle(hm[n] / hp[i])))
                    rows.append(row)
        h_true = curves["true"][ok, j]
        enough = len(ok) >= 2
        true = figures(f_ok, h_true, diag_phase["true"]) if enough else CurveFigures()
        axes[axis_in] = AxisFigures(
            **asdict(true),
            measured_pose=(
                figures(f_ok, curves["measured"][ok, j], diag_phase["measured"]) if enough else None
            ),
        )
        if pred is not None:
            axes[axis_in].predicted = figures(
                freq, pred["true"][:, j, j], pred_phase["true"][:, j, j]
            )
            near = [
                r
                for r in rows
                if r.input_axis == r.output_axis == axis_in and r.frequency_hz <= 1.0 + 1e-9
            ]
            out.agreement[axis_in] = {
                sig: Agreement(
                    max((abs(r.diff_db or 0.0) for r in near if r.signal == sig), default=None),
                    max((abs(r.diff_deg or 0.0) for r in near if r.signal == sig), default=None),
                )
                for sig in ("true", "measured")
            }
    if pred is not None:  # the prediction between the measured frequencies, to draw as curves
        for axis_in in plan.inputs:
            j = AXES.index(axis_in)
            bode = {
                sig: Bode.of(
                    np.abs(full[sig][span, j, j]),
                    np.degrees(np.unwrap(np.angle(full[sig][:, j, j])))[span],
                )
                for sig in ("true", "measured")
            }
            out.predicted_curves[axis_in] = PredictedCurve(
                (dense[span] / (2 * np.pi)).tolist(), bode["true"], bode["measured"]
            )
    return out


def figures(freq=(), h=(), phase_deg=()) -> CurveFigures:
    """Bandwidth, phases at 0.5 and 1 Hz and equivalent delay of one response curve."""
    if len(freq) < 2:
        return CurveFigures()
    f = np.asarray(freq, float)
    h = np.asarray(h)
    order = np.argsort(f)
    f, h, ph = f[order], h[order], np.asarray(phase_deg, float)[order]
    bw = bandwidth_3db(f, h)
    tau = equivalent_delay(f, h, phase_deg=ph)
    return CurveFigures(
        bandwidth_3db_hz=bw,
        bandwidth_above_hz=float(f[-1]) if bw is None else None,
        phase_deg_at_0_5_hz=phase_at(f, h, 0.5, ph),
        phase_deg_at_1_hz=phase_at(f, h, 1.0, ph),
        equivalent_delay_ms=None if tau is None else tau * 1e3,
    )
