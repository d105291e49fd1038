"""Closed-loop frequency response of the platform in the co-simulation (stepped sines).

For each task axis (roll, pitch, heave) and each frequency, one run of the
scenario with its set-point replaced by a small sine on that axis alone
(the other axes held at home): ``settle_s`` to let the start transient die,
then ``periods`` whole periods over which the set-point, the true pose and
the measured pose are fitted by least squares
(:func:`controllers.frequency.fit_sine`: offset, trend, cosine, sine). The
ratio of the fitted complex amplitudes is the response: on the excited axis
the closed-loop response, on the others the cross-axis coupling (a pitch
command moves heave through the mechanism and the unequal legs).

Frequencies
-----------
By default the twelve OMCT frequencies (ICAO 9625: 0.1 to 15.85 rad/s,
five per decade), each moved to the nearest period on the 1 ms physics grid
(at most 0.4 % away; the table gives the frequency used), plus 0.5 Hz and
1 Hz, where the summary's phases are read. Frequencies given by the user
must have periods on the grid (whole milliseconds): the fit is over whole
periods of whole samples. Every run is independent: they run in parallel
with the batch executors (:func:`simpro_mj.sim.executors.run_tasks`).

Prediction
----------
:func:`loop_model` reads the scenario's linearised loop (the joint
controllers as built, the plant the analysis uses: the linear actuator's
eq. 19 coefficients, or the identified plants ``controller.inner.identified``
for the nonlinear cylinders; the IK Jacobian at home; the IMU filter; the
outer law, gains and period) for :func:`controllers.frequency.predict`.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from controllers.frequency import (
    OMCT_RAD_S,
    LoopModel,
    bandwidth_3db,
    equivalent_delay,
    fit_sine,
    phase_at,
    predict,
    unwrapped_phase_deg,
)
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.messages import one_line

__all__ = [
    "AXES",
    "DEFAULT_AMPLITUDES",
    "ResponsePlan",
    "default_periods_ms",
    "check_periods",
    "check_amplitudes",
    "check_settle_periods",
    "check_run_length",
    "failures",
    "plan_response",
    "point_scenario",
    "measure_point",
    "measure",
    "loop_model",
    "summary",
    "figures",
]

AXES = ("roll", "pitch", "heave")
_SETPOINT_KEYS = ("roll_deg", "pitch_deg", "heave_mm")
#: Edge units per axis and their scale to SI.
_UNITS = {
    "roll": ("deg", math.pi / 180.0),
    "pitch": ("deg", math.pi / 180.0),
    "heave": ("mm", 1e-3),
}
#: Small-signal amplitudes (edge units): well inside the valves' linear range.
DEFAULT_AMPLITUDES = {"roll": 0.5, "pitch": 0.5, "heave": 5.0}
#: Frequencies where the summary reads the phase (Hz); measured by default.
PHASE_POINTS_HZ = (0.5, 1.0)
MIN_PERIOD_MS = 20  # 50 Hz: above every loop of the platform
MAX_PERIOD_MS = 600_000
MAX_PERIODS = 100
MAX_SETTLE_S = 600.0


def default_periods_ms() -> list[int]:
    """OMCT frequencies on the 1 ms period grid, plus 0.5 and 1 Hz (longest period first)."""
    periods = {int(round(2000.0 * math.pi / w)) for w in OMCT_RAD_S}
    periods |= {int(round(1000.0 / f)) for f in PHASE_POINTS_HZ}
    return sorted(periods, reverse=True)


def check_periods(freq_hz: Sequence[float], where: str = "--freq-hz") -> list[int]:
    """Periods (ms) of user frequencies; one-line :class:`UserInputError` otherwise."""
    out = []
    for f in freq_hz:
        allowed = (
            f"allowed: frequencies from {1000.0 / MAX_PERIOD_MS:g} to {1000.0 / MIN_PERIOD_MS:g} "
            "Hz whose period is a whole number of milliseconds (the 1 ms physics grid)"
        )
        if not (isinstance(f, (int, float)) and math.isfinite(f) and f > 0):
            raise UserInputError(f"invalid value at {where}: {f!r}; {allowed}")
        period = 1000.0 / f
        k = round(period)
        if not MIN_PERIOD_MS <= period <= MAX_PERIOD_MS:
            raise UserInputError(f"invalid value at {where}: {f:g} Hz; {allowed}")
        if abs(period - k) > 1e-6 * period:
            raise UserInputError(
                f"invalid value at {where}: {f:g} Hz (period {period:.4f} ms is not on the 1 ms "
                f"grid); {allowed}, e.g. {1000.0 / k:.6g} Hz ({k} ms)"
            )
        out.append(int(k))
    if len(set(out)) != len(out):
        raise UserInputError(
            f"invalid value at {where}: a frequency given twice; allowed: distinct"
        )
    return sorted(out, reverse=True)


def _max_amplitude(axis: int, geometry) -> float:
    """Largest symmetric excursion (SI) from home on one axis inside the workspace."""
    from controllers.kinematics import reachable

    home = np.asarray(geometry.home, float)
    lo, hi = 0.0, 1.0 if axis < 2 else 0.5  # rad, m: beyond the platform's reach
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        poses = np.array([home, home])
        poses[0, axis] += mid
        poses[1, axis] -= mid
        if reachable(poses, geometry).all():
            lo = mid
        else:
            hi = mid
    return lo


def check_amplitudes(amplitudes: Mapping[str, float]) -> dict:
    """Amplitudes (edge units) -> SI per axis; beyond the workspace is a one-line error."""
    from controllers.geometry import nominal_geometry

    geometry = nominal_geometry()
    out = {}
    for j, axis in enumerate(AXES):
        unit, scale = _UNITS[axis]
        where = "--amplitude-mm" if axis == "heave" else "--amplitude-deg"
        a = amplitudes[axis]
        limit = _max_amplitude(j, geometry) / scale
        if not (isinstance(a, (int, float)) and math.isfinite(a) and 0 < a <= limit):
            raise UserInputError(
                f"invalid value at {where}: {a!r}; allowed: 0 < amplitude <= {limit:.3g} {unit} "
                f"on {axis} (a sine about home inside the workspace, see simpro-sim workspace)"
            )
        out[axis] = a * scale
    return out


def check_settle_periods(settle_s, periods) -> None:
    """``--settle-s`` (0..600 s on the 1 ms grid) and ``--periods`` (1..100), one-line errors."""
    ok = isinstance(settle_s, (int, float)) and not isinstance(settle_s, bool)
    if not (ok and math.isfinite(settle_s) and 0 <= settle_s <= MAX_SETTLE_S) or (
        abs(settle_s * 1e3 - round(settle_s * 1e3)) > 1e-6
    ):
        raise UserInputError(
            f"invalid value at --settle-s: {settle_s!r}; allowed: 0..{MAX_SETTLE_S:g} s on the "
            "1 ms grid"
        )
    if isinstance(periods, bool) or not isinstance(periods, int) or not 1 <= periods <= MAX_PERIODS:
        raise UserInputError(
            f"invalid value at --periods: {periods!r}; allowed: an integer 1..{MAX_PERIODS}"
        )


def check_run_length(settle_s: float, periods: int, periods_ms: Sequence[int]) -> None:
    """The longest run (settle plus whole periods) within a scenario's longest duration."""
    from simpro_mj.config.scenario import MAX_DURATION_S

    longest = settle_s + periods * max(periods_ms) / 1000.0
    if longest > MAX_DURATION_S:
        raise UserInputError(
            f"invalid value at --periods: {periods} periods of {max(periods_ms)} ms after "
            f"{settle_s:g} s is a {longest:g} s run; allowed: runs up to {MAX_DURATION_S:g} s"
        )


def failures(tasks: Sequence[Mapping], results: Sequence[Mapping], key: str) -> list:
    """The tasks that did not run ``ok``: ``key`` (axis or channel), period, status, reason."""
    return [
        {key: t[key], "period_ms": t["period_ms"], "status": r["status"], "reason": r["reason"]}
        for t, r in zip(tasks, results, strict=True)
        if r.get("status") != "ok"
    ]


@dataclass
class ResponsePlan:
    """What :func:`measure` runs: one task per (axis, period)."""

    scenario: dict
    axes: tuple
    periods_ms: list
    amplitudes: dict  # SI per axis
    settle_s: float
    periods: int
    tasks: list = field(default_factory=list)


def plan_response(
    scenario: Mapping,
    *,
    periods_ms: Sequence[int] | None = None,
    amplitudes: Mapping[str, float] | None = None,
    axes: Sequence[str] = AXES,
    settle_s: float = 4.0,
    periods: int = 2,
) -> ResponsePlan:
    """Check the test's parameters and build its tasks (plain data for the workers)."""
    amps = dict(DEFAULT_AMPLITUDES)
    amps.update(amplitudes or {})
    amp_si = check_amplitudes(amps)
    check_settle_periods(settle_s, periods)
    for a in axes:
        if a not in AXES:
            raise UserInputError(f"invalid value at --axes: {a!r}; allowed: {list(AXES)}")
    periods_ms = default_periods_ms() if periods_ms is None else list(periods_ms)
    check_run_length(settle_s, periods, periods_ms)
    plan = ResponsePlan(
        scenario=copy.deepcopy(dict(scenario)),
        axes=tuple(axes),
        periods_ms=periods_ms,
        amplitudes=amp_si,
        settle_s=float(settle_s),
        periods=int(periods),
    )
    for axis in plan.axes:
        for p in periods_ms:
            plan.tasks.append(
                {
                    "scenario": point_scenario(scenario, axis, p, amps[axis], settle_s, periods),
                    "axis": axis,
                    "period_ms": int(p),
                    "settle_s": float(settle_s),
                    "periods": int(periods),
                }
            )
    return plan


def point_scenario(
    scenario: Mapping, axis: str, period_ms: int, amplitude: float, settle_s: float, periods: int
) -> dict:
    """The scenario with a sine of ``amplitude`` (edge units) on ``axis`` alone, run for
    ``settle_s`` plus ``periods`` periods, logged every step, faults removed."""
    sc = copy.deepcopy(dict(scenario))
    sc["setpoint"] = {key: [] for key in _SETPOINT_KEYS}
    sc["setpoint"][_SETPOINT_KEYS[AXES.index(axis)]] = [
        {
            "type": "sine",
            "amplitude": float(amplitude),
            "period_s": period_ms / 1000.0,
            "phase_deg": 0.0,
            "start_s": 0.0,
            "end_s": None,
        }
    ]
    sc["duration_s"] = round(settle_s + periods * period_ms / 1000.0, 3)
    sc["faults"] = []
    sc["logging"] = dict(sc["logging"], decimation=1)
    return sc


def measure_point(task: Mapping) -> dict:
    """Run one stepped sine and fit it (worker side; top level, pickles by name).

    Returns ``status``, ``reason``, and when ``ok``: ``axis``, ``period_ms``,
    ``ref`` (the set-point's complex amplitude as ``[re, im]``, SI), ``true``
    and ``measured`` (3 outputs each, ``[re, im]`` SI), ``saturated_pct``
    (share of the fitted steps with a valve at a rail).
    """
    from simpro_mj.sim.loop import CoSimulation

    try:
        res = CoSimulation(task["scenario"]).run()
        if res.status != "ok":
            return {"status": res.status, "reason": res.reason}
        c = res.columns
        dt = res.sim["timestep_s"]
        period = task["period_ms"] / 1000.0
        k0 = int(round(task["settle_s"] / dt))
        k1 = k0 + int(round(task["periods"] * period / dt))
        t = c["time_s"][k0:k1]
        w = 2.0 * math.pi / period
        j = AXES.index(task["axis"])
        ref_col = ("roll_ref_rad", "pitch_ref_rad", "heave_ref_m")[j]
        true = np.column_stack([c[k][k0:k1] for k in ("roll_rad", "pitch_rad", "heave_m")])
        meas = np.column_stack(
            [c[k][k0:k1] for k in ("roll_meas_rad", "pitch_meas_rad", "heave_meas_m")]
        )
        r = fit_sine(t, c[ref_col][k0:k1], w)
        yt, ym = fit_sine(t, true, w), fit_sine(t, meas, w)
        u = np.column_stack([c[f"u{i}_v"][k0:k1] for i in (1, 2, 3)])
        sat = np.any((u <= 0.0) | (u >= 10.0), axis=1).mean() * 100.0
        return {
            "status": "ok",
            "reason": None,
            "axis": task["axis"],
            "period_ms": task["period_ms"],
            "ref": [r.real, r.imag],
            "true": [[v.real, v.imag] for v in yt],
            "measured": [[v.real, v.imag] for v in ym],
            "saturated_pct": float(sat),
        }
    except UserInputError as exc:
        return {"status": "invalid", "reason": one_line(exc)}
    except Exception as exc:  # noqa: BLE001 - a failure is this frequency's, not the test's
        return {"status": "failed", "reason": f"{type(exc).__name__}: {' '.join(str(exc).split())}"}


def measure(
    plan,
    *,
    jobs: int = 1,
    scheduler=None,
    progress: bool = False,
    fn=None,
    desc: str = "response",
) -> list:
    """Run every task of ``plan``; results in task order (``fn``, default :func:`measure_point`;
    a top-level function, it pickles by name)."""
    from simpro_mj.sim.executors import Progress, run_tasks

    fn = measure_point if fn is None else fn
    results: list = [None] * len(plan.tasks)
    bar = Progress(len(plan.tasks), progress, desc=desc)

    def done(key: int, result: dict) -> None:
        results[key] = result
        bar.update(result.get("status", "failed"))

    try:
        run_tasks(list(enumerate(plan.tasks)), done, jobs=jobs, scheduler=scheduler, fn=fn)
    finally:
        bar.close()
    return [r if r is not None else {"status": "cancelled", "reason": "not run"} for r in results]


def loop_model(scenario: Mapping) -> LoopModel:
    """The scenario's linearised loop for :func:`controllers.frequency.predict`."""
    from controllers.design import Plant
    from controllers.kinematics import jacobian
    from controllers.task_space import outer_law
    from controllers.velocity_feedforward import velocity_gains
    from simpro_mj.sim.loop import CoSimulation

    cs = CoSimulation(dict(scenario))
    ctl = scenario["controller"]
    if cs.actuators.kind == "linear":
        p = cs.actuators.params
        plants = [Plant(b=p.lin_b[i], a1=p.lin_a1[i], a0=p.lin_a0[i]) for i in range(3)]
    else:
        ident = ctl["inner"]["identified"]
        plants = [Plant(**ident[a]) for a in ("actuator1", "actuator2", "actuator3")]
    o = ctl["outer"]
    law, pi_zero = outer_law(o["type"], o["integrator"], o["pi_zero"])
    mode = {"task_space": law, "feedforward": "feedforward"}.get(cs.mode, "joint_only")
    cfg = cs.sensor_cfg
    filt = None
    sf = ctl.get("setpoint_filter")
    if sf:  # Fig. 13's filter between q_d and the joint loops (issue 18)
        from controllers.setpoint_filter import filter_state_space, leg_times

        times = leg_times(np.asarray(sf["time_ms"], float) * 1e-3)
        filt = [filter_state_space(sf["type"], cs.dt, t) for t in times]
    return LoopModel(
        plants=plants,
        designs=cs.joint.designs,
        jac=jacobian(cs.geometry.home),
        mode=mode,
        gains=np.asarray(
            ctl["feedforward"]["gains"] if cs.mode == "feedforward" else ctl["outer"]["gains"],
            float,
        ),
        period=cs.outer_every * cs.dt,
        dt=cs.dt,
        method=ctl["inner"]["discretisation"],
        pi_zero=pi_zero,
        outer_law=law,
        imu_alpha=cfg.imu_alpha,
        imu_every=cfg.imu_every,
        model_tau=ctl["feedforward"]["model_tau_ms"] * 1e-3,
        setpoint_filter=filt,
        lag=ctl["feedforward"]["lag"],
        velocity_ff=(
            velocity_gains(
                [
                    Plant(**ctl["inner"]["identified"][a])
                    for a in ("actuator1", "actuator2", "actuator3")
                ]
            )
            if cs.u_ff is not None
            else np.zeros(3)
        ),
        average=bool(ctl["feedforward"]["average"]),
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
    1 Hz on the excited axis), ``failed`` (frequencies that did not run).
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
                    if hp is not None:
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
    return {"rows": rows, "axes": axes, "agreement": agreement, "failed": failed}


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
