"""What the driver perceives: vehicle against simulator, through one vestibular model.

The simulator side is measured at the driver's head by MuJoCo's ``head_accel`` and
``head_gyro`` (ISO axes, :mod:`controllers.frames`); the vehicle side is the cueing
scenario's input (:func:`simpro_mj.config.cueing.vehicle_input`). Both go through
the same :class:`~controllers.vestibular.VestibularModel`. The result is
the ``cueing`` block of ``metrics.json`` and the cueing columns of a batch summary.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

from controllers.vestibular import VestibularModel
from simpro_mj.analysis.cue_signals import (
    bound_share,
    correlation,
    false_rotation,
    mean_lag,
    onset_block,
    strength,
)
from simpro_mj.config.cueing import CUE_COLUMNS, vehicle_input
from simpro_mj.config.models import Scenario

#: Channels compared: (name, vehicle column, simulator column, kind, axis).
CHANNELS = (
    ("longitudinal_f", "veh_fx_mps2", "head_fx_mps2", "f", 0),
    ("lateral_f", "veh_fy_mps2", "head_fy_mps2", "f", 1),
    ("vertical_f", "veh_fz_mps2", "head_fz_mps2", "f", 2),
    ("roll_rate", "veh_wx_rad_s", "head_wx_rad_s", "w", 0),
    ("pitch_rate", "veh_wy_rad_s", "head_wy_rad_s", "w", 1),
)


def _forces(columns: Mapping, side: str) -> tuple[np.ndarray, np.ndarray]:
    """The specific force and angular velocity (n, 3) of ``side`` (``veh``, ``head``)."""
    f = np.stack([np.asarray(columns[f"{side}_f{a}_mps2"], float) for a in "xyz"], -1)
    w = np.stack([np.asarray(columns[f"{side}_w{a}_rad_s"], float) for a in "xyz"], -1)
    return f, w


def cue_metrics(columns: Mapping, scenario: Scenario | Mapping,
                model: VestibularModel | None = None, *, info: Mapping | None = None,
                bound: bool = True) -> dict:  # fmt: skip
    """The ``cueing`` block of ``metrics.json``: per channel, vehicle vs simulator, perceived.

    Per channel (:data:`CHANNELS`), of the perceived signals: ``rms_error``,
    ``correlation`` (and ``raw_correlation`` of the stimuli); ``peak_lag_s``
    (between the perceived peaks of largest magnitude) and ``mean_lag_s`` (the
    shift maximising the cross-correlation over the overlap, :func:`mean_lag`: searched
    over 0..2 s, widened while the best is at the edge, up to half the run;
    ``mean_lag_lower_bound`` true when it is still at that edge);
    ``false_cue_s`` (the simulator's sensation above threshold with the
    opposite sign to the vehicle's, or where the vehicle's is zero);
    ``simulator_above_threshold_s``, ``vehicle_above_threshold_s``,
    ``missed_cue_s`` (the vehicle's above threshold, the simulator's not);
    ``onset_s`` (the vehicle's sensation from crossing its threshold to its
    peak), ``onset_false_cue_s`` and ``onset_right_sign`` (no false cue in it).
    Every onset (:func:`onsets`: the vehicle's sensation crossing its threshold):
    ``onset_delay_s`` (the worst, and ``onset_delays_s`` each: the head's sensation
    crossing the threshold with the vehicle's sign, after the vehicle's; an onset
    where it never does is counted in ``onsets_missed``);
    ``onset_raw_wrong_sign_peak`` and ``onset_raw_wrong_sign_s``, the raw head
    signal (not perceived: the otoliths smooth a jolt away) against the vehicle's
    sign, from the crossing to the onset's peak, and ``onset_raw_right_sign`` (that
    peak at most the threshold). Rotation channels: ``false_rotation_s`` and
    ``false_rotation_peak`` (rad/s), where the head's sensation is above the canal
    threshold and exceeds the vehicle's in its direction by more than it
    (:func:`false_rotation`): a rotation felt that the car does not make.
    Then ``workspace`` (largest excursion per axis as a fraction of the cueing
    box, strokes used, end-stop margin) and ``valves`` (fraction of samples
    with a valve at 0 or 10 V).

    Strength beside shape (:func:`strength`): ``gain`` (least squares of the head's
    perceived signal on the vehicle's, at the mean lag), ``gain_rms`` (ratio of their
    RMS), ``rms_error`` (SI; rotation channels also ``rms_error_deg_s``). With
    ``bound`` (default): ``bound`` (:func:`bound_block`: the same figures for the best
    platform motion with the whole drive known, :mod:`controllers.cue_bound`) and per
    channel ``gain_share`` and ``error_share`` (:func:`bound_share`).

    ``info``: the washout's ``box``, ``softened_fraction``,
    ``rate_limited_fraction`` and ``source`` when the vehicle input did not
    come from the scenario (a live session); by default they are those of
    :func:`~simpro_mj.config.cueing.vehicle_input`.
    """
    model = VestibularModel() if model is None else model
    t = np.asarray(columns["time_s"], dtype=float)
    ok = np.isfinite(t)
    for c in CUE_COLUMNS:
        ok &= np.isfinite(np.asarray(columns[c], float))
    n = int(np.argmin(ok)) if not ok.all() else t.size
    if n < 10:
        return {"note": "fewer than 10 finite samples"}
    t = t[:n]
    dt = float(np.median(np.diff(t)))
    col = {c: np.asarray(columns[c], float)[:n] for c in CUE_COLUMNS}
    veh, sim = (model.perceive(*_forces(col, side), dt) for side in ("veh", "head"))
    out: dict = {"channels": {}, "sample_s": dt}
    for name, vc, sc, kind, ax in CHANNELS:
        pv = (veh.f if kind == "f" else veh.w)[:, ax]
        ps = (sim.f if kind == "f" else sim.w)[:, ax]
        thr = float((veh.f_threshold if kind == "f" else veh.w_threshold)[ax])
        iv, is_ = int(np.argmax(np.abs(pv))), int(np.argmax(np.abs(ps)))
        above = np.abs(ps) > thr
        false = above & (np.sign(ps) != np.sign(pv))  # opposite, or where the vehicle gives none
        missed = (np.abs(pv) > thr) & (np.abs(ps) <= thr)
        # the onset: from the vehicle's sensation first crossing its threshold to its peak
        felt = np.flatnonzero(np.abs(pv) > thr)
        onset = slice(int(felt[0]), iv + 1) if felt.size and felt[0] <= iv else slice(0, 0)
        lag, lag_bound = mean_lag(pv, ps, dt)
        g0 = 9.80665 if name == "vertical_f" else 0.0
        raw, veh_raw = col[sc] - g0, col[vc] - g0
        ch: dict[str, Any]
        out["channels"][name] = ch = {
            "unit": "m/s^2" if kind == "f" else "rad/s",
            "threshold": thr,
            "rms_error": float(np.sqrt(np.mean((pv - ps) ** 2))),
            "vehicle_rms": float(np.sqrt(np.mean(pv * pv))),
            "correlation": correlation(pv, ps),
            "raw_correlation": correlation(col[vc], col[sc]),
            "vehicle_peak": float(pv[iv]),
            "simulator_peak": float(ps[is_]),
            "peak_lag_s": float(t[is_] - t[iv]),
            "mean_lag_s": lag,
            "mean_lag_lower_bound": lag_bound,
            "false_cue_s": float(false.sum() * dt),
            "simulator_above_threshold_s": float(above.sum() * dt),
            "vehicle_above_threshold_s": float((np.abs(pv) > thr).sum() * dt),
            "missed_cue_s": float(missed.sum() * dt),
            "onset_s": [float(t[onset.start]), float(t[onset.stop - 1])] if felt.size else None,
            "onset_false_cue_s": float(false[onset].sum() * dt),
            "onset_right_sign": bool(felt.size) and not bool(false[onset].any()),
        }
        ch.update(onset_block(t, pv, ps, veh_raw, raw, thr))
        ch.update(strength(pv, ps, lag, dt))
        if kind == "w":
            excess = false_rotation(pv, ps)
            wrong = above & (excess > thr)
            ch.update(
                rms_error_deg_s=float(np.degrees(ch["rms_error"])),
                false_rotation_s=float(wrong.sum() * dt),
                false_rotation_peak=float(excess[wrong].max()) if wrong.any() else 0.0,
            )
    if bound:
        out["bound"] = best = bound_block(col, dt, scenario, veh, model)
        for name, ch in out["channels"].items():
            ch.update(bound_share(ch, best["channels"].get(name)))
    if info is None:
        _, _, _, _, info = vehicle_input(scenario)
    box = info["box"]
    usage = {}
    for k, (axis, unit) in enumerate((("roll", "rad"), ("pitch", "rad"), ("heave", "m"))):
        y = np.asarray(columns[f"{axis}_{unit}"], float)[:n]
        home = (0.0, 0.0, 1.265)[k]
        lo, hi = box[axis]
        frac = np.where(y >= home, (y - home) / (hi - home), (home - y) / (home - lo))
        usage[axis] = float(frac.max())
    q = np.stack([np.asarray(columns[f"q{i}_m"], float)[:n] for i in (1, 2, 3)])
    u = np.stack([np.asarray(columns[f"u{i}_v"], float)[:n] for i in (1, 2, 3)], -1)
    sat = (u <= 1e-9) | (u >= 10.0 - 1e-9)
    out.update(
        workspace={
            "box_fraction_max": usage,
            "box": box,
            "setpoint_softened_fraction": info["softened_fraction"],
            "tilt_rate_limited_fraction": info["rate_limited_fraction"],
            "stroke_min_m": float(q.min()),
            "stroke_max_m": float(q.max()),
            "end_stop_margin_m": float(min(q.min(), 0.5 - q.max())),
        },
        valves={
            "saturated_fraction": float(sat.any(axis=1).mean()),
            "saturated_fraction_per_valve": [float(v) for v in sat.mean(axis=0)],
        },
        source=info["source"],
        algorithm=info.get("algorithm", "classical_washout"),
    )
    if info.get("solve_time"):
        out["solve_time"] = info["solve_time"]
    return out


#: The bound is computed for drives up to this long (s): its QP grows with the drive
#: (about 1 s of solve for a 12 s drive on this machine).
BOUND_MAX_S = 120.0


def bound_block(col: Mapping, dt: float, scenario: Scenario | Mapping, veh,
                model: VestibularModel) -> dict:  # fmt: skip
    """The ``bound`` block: the best platform motion for this drive
    (:func:`controllers.cue_bound.cue_bound`, with the scenario's MPC parameters, or the
    MPC's defaults with the washout's box for a washout run), perceived through
    ``model``: per channel ``gain``, ``gain_rms``, ``correlation``, ``rms_error``
    against the vehicle's perceived ``veh``; ``status`` per axis, ``solve_s``."""
    from controllers.cue_bound import cue_bound
    from controllers.cue_mpc_params import MpcParams
    from simpro_mj.config.cue_params import washout_params

    n = col["time_s"].size if "time_s" in col else len(next(iter(col.values())))
    if n * dt > BOUND_MAX_S:
        return {"note": f"not computed: the drive is longer than {BOUND_MAX_S:g} s", "channels": {}}
    if isinstance(scenario, Scenario):  # a typed cueing block always names its algorithm
        cue = scenario.setpoint.cueing
        params = washout_params(cue) if cue is not None else None
    else:  # a resolved dict, or a bare law block (the OMCT's and the recordings' chain)
        block = (scenario.get("setpoint") or {}).get("cueing") or {}
        params = washout_params(block) if block.get("algorithm") else None
    if not isinstance(params, MpcParams):
        box: dict[str, Any] = {} if params is None else {
            "heave_fraction": params.heave_fraction, "stroke_margin": params.stroke_margin
        }  # fmt: skip
        params = MpcParams(**box)
    b = cue_bound(*_forces(col, "veh"), dt, params)
    sim = model.perceive(b.f, b.w, dt)
    chans = {}
    for name, _, _, kind, ax in CHANNELS:
        pv = (veh.f if kind == "f" else veh.w)[:, ax]
        ps = (sim.f if kind == "f" else sim.w)[:, ax]
        lag, _ = mean_lag(pv, ps, dt)
        chans[name] = {
            "correlation": correlation(pv, ps),
            "mean_lag_s": lag,
            "rms_error": float(np.sqrt(np.mean((pv - ps) ** 2))),
            **strength(pv, ps, lag, dt),
        }
    return {
        "channels": chans,
        "status": b.status,
        "solve_s": b.solve_s,
        "box_fraction_max": {
            k: float(np.abs(b.pose_iso[:, i]).max() / b.limits[i])
            for i, k in enumerate(("roll", "pitch", "heave"))
        },
    }


def perceived_columns(columns: Mapping, model: VestibularModel | None = None) -> dict:
    """The perceived signals of a cueing run, vehicle and head, as columns
    (``perceived.csv``): ``time_s``, ``veh_`` and ``head_`` ``fx_hat_mps2`` ...
    ``wz_hat_rad_s`` (z: the change from 1 g)."""
    t, veh, sim = perceived(columns, model)
    out = {"time_s": t}
    for prefix, side in (("veh", veh), ("head", sim)):
        for k, a in enumerate("xyz"):
            out[f"{prefix}_f{a}_hat_mps2"] = side.f[:, k]
        for k, a in enumerate("xyz"):
            out[f"{prefix}_w{a}_hat_rad_s"] = side.w[:, k]
    return out


def perceived(columns: Mapping, model: VestibularModel | None = None):
    """(t, vehicle Perception, simulator Perception) of a cueing run's columns (for plots)."""
    model = VestibularModel() if model is None else model
    t = np.asarray(columns["time_s"], float)
    dt = float(np.median(np.diff(t)))
    return t, *(model.perceive(*_forces(columns, side), dt) for side in ("veh", "head"))


@dataclass(frozen=True)
class Floors:
    """The acceptance floors (see :data:`FLOORS`)."""

    correlation: Mapping[str, float]
    mean_lag_s: float = 0.5
    onset_delay_s: float = 0.3
    onset_raw_wrong_sign_peak: float = 0.17
    false_rotation_s: float = 0.5
    box_fraction: float = 1.0
    valve_saturated_fraction: float = 0.05
    gain_share: float = 0.8


#: What a driver would accept (docs/cueing.md), on every channel the vehicle drives (surge
#: and sway whose perceived vehicle peak passes the otoliths' threshold; the larger of the
#: two if neither does): perceived correlation (0.8 on surge, 0.85 on sway), mean lag (s),
#: worst onset delay (s) with no onset missed, the raw head signal's wrong-sign peak at the
#: onsets (m/s^2, the otoliths' threshold); felt false roll and pitch (s); the cueing box
#: and the end stops; valve saturation; the perceived gain at least ``gain_share`` of the
#: bound's (:func:`bound_share`: a cue right in shape but weaker than the platform can
#: give misses it), where the bound was computed.
FLOORS = Floors(correlation=MappingProxyType({"longitudinal_f": 0.8, "lateral_f": 0.85}))


@dataclass
class FloorVerdict:
    """One run's cueing block against :data:`FLOORS` (:func:`cue_floors`)."""

    channel: str  #: the main one: the larger perceived vehicle peak
    channels: list[str]  #: those judged
    missed: list[str]  #: one short phrase per floor missed, with its value

    @property
    def met(self) -> bool:
        """Every floor met."""
        return not self.missed


def cue_floors(cue: Mapping) -> FloorVerdict:
    """The :data:`FLOORS` on one run's ``cueing`` block: the main channel (the larger
    perceived vehicle peak), those judged (every surge or sway channel the vehicle drives
    past the otoliths' threshold, else the main one) and the floors missed."""
    ch = cue.get("channels") or {}
    peak = {c: abs((ch.get(c) or {}).get("vehicle_peak") or 0.0) for c in FLOORS.correlation}
    main = max(peak, key=lambda c: peak[c])
    thr = FLOORS.onset_raw_wrong_sign_peak
    judged = [
        c for c in FLOORS.correlation if peak[c] > ((ch.get(c) or {}).get("threshold") or thr)
    ]
    judged = judged or [main]
    missed = []

    def above(name, value, limit, unit=""):
        if value is None or value > limit:
            shown = "none" if value is None else f"{value:.2f}{unit}"
            missed.append(f"{name} {shown} > {limit:g}{unit}")

    for name in judged:
        m = ch.get(name) or {}
        corr = m.get("correlation")
        if corr is None or corr < FLOORS.correlation[name]:
            shown = "none" if corr is None else f"{corr:.2f}"
            missed.append(f"{name} correlation {shown} < {FLOORS.correlation[name]:g}")
        above(f"{name} mean lag", m.get("mean_lag_s"), FLOORS.mean_lag_s, " s")
        if m.get("onsets"):
            above(f"{name} onset delay", m.get("onset_delay_s"), FLOORS.onset_delay_s, " s")
            if m.get("onsets_missed"):
                missed.append(f"{name} onsets missed {m['onsets_missed']}")
            above(
                f"{name} raw wrong-sign peak",
                m.get("onset_raw_wrong_sign_peak"),
                FLOORS.onset_raw_wrong_sign_peak,
                " m/s^2",
            )
        share = m.get("gain_share")
        if share is not None and share < FLOORS.gain_share:
            missed.append(
                f"{name} gain {m.get('gain'):.2f} is {share:.2f} of the bound's "
                f"< {FLOORS.gain_share:g}"
            )
    for rot in ("roll_rate", "pitch_rate"):
        v = (ch.get(rot) or {}).get("false_rotation_s")
        if v is not None:
            above(f"felt false {rot.split('_')[0]}", v, FLOORS.false_rotation_s, " s")
    ws = cue.get("workspace") or {}
    for axis, v in (ws.get("box_fraction_max") or {}).items():
        above(f"{axis} box", v, FLOORS.box_fraction)
    margin = ws.get("end_stop_margin_m")
    if margin is not None and margin <= 0:
        missed.append(f"end stops reached ({margin * 1e3:.0f} mm)")
    sat = (cue.get("valves") or {}).get("saturated_fraction")
    if sat is not None:
        above("valve saturation", sat, FLOORS.valve_saturated_fraction)
    return FloorVerdict(main, judged, missed)


_LONG, _LAT, _ROLL, _PITCH = "longitudinal_f", "lateral_f", "roll_rate", "pitch_rate"
#: Each column and where it comes from: a channel's key of the cueing block, or (None)
#: the run's workspace, valves, law, main channel, solve times, floors and bound.
_COLUMNS = (
    ("cue_long_corr", _LONG, "correlation"),
    ("cue_lat_corr", _LAT, "correlation"),
    ("cue_long_false_s", _LONG, "false_cue_s"),
    ("cue_lat_false_s", _LAT, "false_cue_s"),
    ("cue_roll_rate_false_s", _ROLL, "false_cue_s"),
    ("cue_pitch_rate_false_s", _PITCH, "false_cue_s"),
    ("cue_roll_box_frac", None, None),
    ("cue_pitch_box_frac", None, None),
    ("cue_heave_box_frac", None, None),
    ("cue_end_stop_margin_mm", None, None),
    ("cue_valve_sat_frac", None, None),
    ("cue_algorithm", None, None),
    ("cue_main_channel", None, None),
    ("cue_long_lag_s", _LONG, "mean_lag_s"),
    ("cue_lat_lag_s", _LAT, "mean_lag_s"),
    ("cue_long_onset_s", _LONG, "onset_delay_s"),
    ("cue_lat_onset_s", _LAT, "onset_delay_s"),
    ("cue_long_raw_wrong_mps2", _LONG, "onset_raw_wrong_sign_peak"),
    ("cue_lat_raw_wrong_mps2", _LAT, "onset_raw_wrong_sign_peak"),
    ("cue_roll_false_rot_s", _ROLL, "false_rotation_s"),
    ("cue_pitch_false_rot_s", _PITCH, "false_rotation_s"),
    ("cue_solve_p99_ms", None, None),
    ("cue_floors_met", None, None),
    ("cue_floors_missed", None, None),
    ("cue_long_gain", _LONG, "gain"),
    ("cue_lat_gain", _LAT, "gain"),
    ("cue_long_gain_rms", _LONG, "gain_rms"),
    ("cue_lat_gain_rms", _LAT, "gain_rms"),
    ("cue_long_rms_err_mps2", _LONG, "rms_error"),
    ("cue_lat_rms_err_mps2", _LAT, "rms_error"),
    ("cue_roll_rms_err_deg_s", _ROLL, "rms_error_deg_s"),
    ("cue_pitch_rms_err_deg_s", _PITCH, "rms_error_deg_s"),
    ("cue_long_bound_gain", None, None),
    ("cue_lat_bound_gain", None, None),
    ("cue_long_gain_share", _LONG, "gain_share"),
    ("cue_lat_gain_share", _LAT, "gain_share"),
    ("cue_long_error_share", _LONG, "error_share"),
    ("cue_lat_error_share", _LAT, "error_share"),
)
#: Cueing columns of ``simpro-sim batch``'s summary.csv (perceived correlations,
#: false-cue times, workspace and valve usage; lags, onset delays, the raw wrong-sign
#: peak at the onsets, felt false rotation, the MPC's p99 solve time; the perceived
#: gain, its RMS ratio, the RMS perceived error, the bound's gain and the law's shares).
SUMMARY_COLUMNS = tuple(name for name, _, _ in _COLUMNS)


def summary_columns(cue: Mapping) -> dict:
    """The :data:`SUMMARY_COLUMNS` of one run's ``metrics.json`` cueing block."""
    ch = cue.get("channels") or {}
    ws = cue.get("workspace") or {}
    box = ws.get("box_fraction_max") or {}
    margin = ws.get("end_stop_margin_m")
    bound = (cue.get("bound") or {}).get("channels") or {}
    floors = cue_floors(cue)
    lat = abs((ch.get(_LAT) or {}).get("vehicle_peak") or 0.0)
    long = abs((ch.get(_LONG) or {}).get("vehicle_peak") or 0.0)
    run = {
        "cue_roll_box_frac": box.get("roll"),
        "cue_pitch_box_frac": box.get("pitch"),
        "cue_heave_box_frac": box.get("heave"),
        "cue_end_stop_margin_mm": None if margin is None else margin * 1e3,
        "cue_valve_sat_frac": (cue.get("valves") or {}).get("saturated_fraction"),
        "cue_algorithm": cue.get("algorithm"),
        # the channel the vehicle drives: the larger perceived vehicle peak
        "cue_main_channel": "lat" if lat > long else "long",
        "cue_solve_p99_ms": (cue.get("solve_time") or {}).get("p99_ms"),
        "cue_floors_met": floors.met,
        "cue_floors_missed": "; ".join(floors.missed),
        "cue_long_bound_gain": bound.get(_LONG, {}).get("gain"),
        "cue_lat_bound_gain": bound.get(_LAT, {}).get("gain"),
    }
    return {
        name: run[name] if channel is None else (ch.get(channel) or {}).get(key)
        for name, channel, key in _COLUMNS
    }
