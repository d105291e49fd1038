"""What the driver perceives: vehicle against simulator, through one vestibular model.

The simulator side is measured at the driver's head by MuJoCo's ``head_accel`` and
``head_gyro`` (ISO axes, :mod:`controllers.frames`); the vehicle side is the cueing
scenario's input (:func:`simpro_mj.config.cueing.vehicle_input`). Both go through
the same :class:`~controllers.vestibular.VestibularModel` (issue 16). The result is
the ``cueing`` block of ``metrics.json`` and the cueing columns of a batch summary.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from controllers.vestibular import VestibularModel
from simpro_mj.config.cueing import CUE_COLUMNS, vehicle_input
from simpro_mj.config.telemetry import Telemetry

__all__ = [
    "CHANNELS",
    "SUMMARY_COLUMNS",
    "cue_metrics",
    "mean_lag",
    "perceived",
    "shift_correlations",
    "summary_columns",
    "telemetry_of",
]

#: Channels compared: (name, vehicle column, simulator column, kind, axis).
CHANNELS = (
    ("longitudinal_f", "veh_fx_mps2", "head_fx_mps2", "f", 0),
    ("lateral_f", "veh_fy_mps2", "head_fy_mps2", "f", 1),
    ("vertical_f", "veh_fz_mps2", "head_fz_mps2", "f", 2),
    ("roll_rate", "veh_wx_rad_s", "head_wx_rad_s", "w", 0),
    ("pitch_rate", "veh_wy_rad_s", "head_wy_rad_s", "w", 1),
)
#: The mean-lag search starts over shifts 0..LAG_WINDOW_S and doubles its window while
#: the best shift sits at the window's edge, up to half the record (the compared overlap
#: never shorter than half the run); a best shift still at that edge is a lower bound.
LAG_WINDOW_S = 2.0
#: Resolution of the mean-lag search (s).
LAG_STEP_S = 0.01


def shift_correlations(a: np.ndarray, b: np.ndarray, kmax: int) -> np.ndarray:
    """Pearson's r of ``a[:n-k]`` and ``b[k:]`` (their overlap) for every k = 0..kmax.

    One FFT cross-correlation for the sums of products and running sums for the
    overlaps' means and variances: O(n log n) for all shifts at once, where the
    sample-by-sample search was O(n) per shift. A shift whose overlap has no variance
    gets -inf.
    """
    a = np.asarray(a, float) - np.mean(a)  # centred: the running sums stay small
    b = np.asarray(b, float) - np.mean(b)
    n = a.size
    kmax = int(min(kmax, n - 2))
    size = 1 << int(2 * n - 1).bit_length()
    sxy = np.fft.irfft(np.conj(np.fft.rfft(a, size)) * np.fft.rfft(b, size), size)[: kmax + 1]
    k = np.arange(kmax + 1)
    m = (n - k).astype(float)
    ca, ca2 = np.cumsum(a), np.cumsum(a * a)
    cb, cb2 = np.cumsum(b), np.cumsum(b * b)
    sx, sxx = ca[n - 1 - k], ca2[n - 1 - k]
    before = np.r_[0.0, cb[:-1]][k], np.r_[0.0, cb2[:-1]][k]
    sy, syy = cb[-1] - before[0], cb2[-1] - before[1]
    cov = sxy - sx * sy / m
    var = (sxx - sx * sx / m) * (syy - sy * sy / m)
    tiny = 1e-12 * (float(np.dot(a, a)) * float(np.dot(b, b)) + 1e-300)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(var > tiny, cov / np.sqrt(np.maximum(var, tiny)), -np.inf)
    return r


def mean_lag(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[float | None, bool]:
    """Lag (s) of ``b`` behind ``a`` maximising their cross-correlation, and whether it
    is only a lower bound.

    The shift (0 up, :data:`LAG_STEP_S` resolution) maximising Pearson's r over the
    overlap, searched over 0..:data:`LAG_WINDOW_S` first; while the best shift is the
    window's last, the window doubles, up to half the record. ``(None, False)`` when
    either signal is constant.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    if a.size < 4 or a.std() == 0 or b.std() == 0:
        return None, False
    step = max(1, int(round(LAG_STEP_S / dt)))
    half = a.size // 2
    r = shift_correlations(a, b, half)[::step]  # r[j] is the shift j * step
    last = (r.size - 1) * step  # the largest shift searched, <= half
    window = int(round(LAG_WINDOW_S / dt))
    while True:
        w = min(window, last)
        j = int(np.argmax(r[: w // step + 1]))
        at_edge = j * step + step > w  # the window's last grid shift
        if not at_edge or w >= last:
            return round(j * step * dt, 9), bool(at_edge)
        window *= 2


def _corr(a: np.ndarray, b: np.ndarray) -> float | None:
    if a.size < 2 or a.std() == 0 or b.std() == 0:
        return None
    return float(np.corrcoef(a, b)[0, 1])


def cue_metrics(columns: Mapping, scenario: Mapping, model: VestibularModel | None = None, *,
                info: Mapping | None = None) -> dict:  # fmt: skip
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
    Then ``workspace`` (largest excursion per axis as a fraction of the cueing
    box, strokes used, end-stop margin) and ``valves`` (fraction of samples
    with a valve at 0 or 10 V).

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
    veh = model.perceive(
        np.stack([col[f"veh_f{a}_mps2"] for a in "xyz"], -1),
        np.stack([col[f"veh_w{a}_rad_s"] for a in "xyz"], -1),
        dt,
    )
    sim = model.perceive(
        np.stack([col[f"head_f{a}_mps2"] for a in "xyz"], -1),
        np.stack([col[f"head_w{a}_rad_s"] for a in "xyz"], -1),
        dt,
    )
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
        out["channels"][name] = {
            "unit": "m/s^2" if kind == "f" else "rad/s",
            "threshold": thr,
            "rms_error": float(np.sqrt(np.mean((pv - ps) ** 2))),
            "correlation": _corr(pv, ps),
            "raw_correlation": _corr(col[vc], col[sc]),
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
    out["workspace"] = {
        "box_fraction_max": usage,
        "box": box,
        "setpoint_softened_fraction": info["softened_fraction"],
        "tilt_rate_limited_fraction": info["rate_limited_fraction"],
    }
    strokes = [np.asarray(columns[f"q{i}_m"], float)[:n] for i in (1, 2, 3)]
    out["workspace"]["stroke_min_m"] = float(min(q.min() for q in strokes))
    out["workspace"]["stroke_max_m"] = float(max(q.max() for q in strokes))
    out["workspace"]["end_stop_margin_m"] = float(min(min(q.min(), 0.5 - q.max()) for q in strokes))
    u = np.stack([np.asarray(columns[f"u{i}_v"], float)[:n] for i in (1, 2, 3)], -1)
    sat = (u <= 1e-9) | (u >= 10.0 - 1e-9)
    out["valves"] = {
        "saturated_fraction": float(sat.any(axis=1).mean()),
        "saturated_fraction_per_valve": [float(v) for v in sat.mean(axis=0)],
    }
    out["source"] = info["source"]
    return out


def perceived(columns: Mapping, model: VestibularModel | None = None):
    """(t, vehicle Perception, simulator Perception) of a cueing run's columns (for plots)."""
    model = VestibularModel() if model is None else model
    t = np.asarray(columns["time_s"], float)
    dt = float(np.median(np.diff(t)))

    def side(prefix):
        f = np.stack([np.asarray(columns[f"{prefix}_f{a}_mps2"], float) for a in "xyz"], -1)
        w = np.stack([np.asarray(columns[f"{prefix}_w{a}_rad_s"], float) for a in "xyz"], -1)
        return model.perceive(f, w, dt)

    return t, side("veh"), side("head")


def telemetry_of(columns: Mapping) -> Telemetry:
    """The vehicle side of a cueing run as telemetry (for re-use)."""
    t = np.asarray(columns["time_s"], float)
    f = np.stack([np.asarray(columns[f"veh_f{a}_mps2"], float) for a in "xyz"], -1)
    w = np.stack([np.asarray(columns[f"veh_w{a}_rad_s"], float) for a in "xyz"], -1)
    return Telemetry(t=t, f=f, w=w)


#: Cueing columns of ``simpro-sim batch``'s summary.csv (perceived correlations,
#: false-cue times, workspace and valve usage).
SUMMARY_COLUMNS = (
    "cue_long_corr",
    "cue_lat_corr",
    "cue_long_false_s",
    "cue_lat_false_s",
    "cue_roll_rate_false_s",
    "cue_pitch_rate_false_s",
    "cue_roll_box_frac",
    "cue_pitch_box_frac",
    "cue_heave_box_frac",
    "cue_end_stop_margin_mm",
    "cue_valve_sat_frac",
)


def summary_columns(cue: Mapping) -> dict:
    """The :data:`SUMMARY_COLUMNS` of one run's ``metrics.json`` cueing block."""
    ch = cue.get("channels") or {}
    ws = cue.get("workspace") or {}
    box = ws.get("box_fraction_max") or {}

    def g(name, key):
        return (ch.get(name) or {}).get(key)

    margin = ws.get("end_stop_margin_m")
    return {
        "cue_long_corr": g("longitudinal_f", "correlation"),
        "cue_lat_corr": g("lateral_f", "correlation"),
        "cue_long_false_s": g("longitudinal_f", "false_cue_s"),
        "cue_lat_false_s": g("lateral_f", "false_cue_s"),
        "cue_roll_rate_false_s": g("roll_rate", "false_cue_s"),
        "cue_pitch_rate_false_s": g("pitch_rate", "false_cue_s"),
        "cue_roll_box_frac": box.get("roll"),
        "cue_pitch_box_frac": box.get("pitch"),
        "cue_heave_box_frac": box.get("heave"),
        "cue_end_stop_margin_mm": None if margin is None else margin * 1e3,
        "cue_valve_sat_frac": (cue.get("valves") or {}).get("saturated_fraction"),
    }
