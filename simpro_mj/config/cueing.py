"""Motion cueing in a scenario: vehicle input -> washout -> set-points; cue metrics (issue 16).

A scenario's ``setpoint`` may hold a ``cueing`` block instead of pose
components::

    setpoint:
      cueing:
        telemetry: braking_100kmh.csv   # a telemetry CSV (simpro_mj/config/telemetry.py), or
        manoeuvre: null                 # {type: braking|lane_change|slalom|bump, speed_kmh, ...}
        sine: null                      # or {channel: fx_mps2, amplitude: 0.3, period_s: 4.0}
        algorithm: classical_washout
        parameters: {}                  # PARAMETER_KEYS, YAML units in the names

``sine`` is a synthetic vehicle input: the vehicle at rest (``f = (0, 0, g)``,
``w = 0``) plus ``amplitude * sin(2 pi t / period_s)`` on one ``channel``
(:data:`SINE_CHANNELS`, telemetry column names, SI); it is what
``simpro-sim response --chain`` runs, one channel and frequency at a time.

A relative ``telemetry`` path is found beside the scenario file, then among
the shipped files (``simpro_mj/scenarios/telemetry/``). The resolved scenario
spells out every parameter. The vehicle input is resampled to the 1 ms
physics grid (linear), the washout runs at its own period on every
``period``-th sample and its set-point is held in between (what the rig's
computer would do); the chain is computed once per scenario and cached.

The simulator side is measured at the driver's head by MuJoCo's
``head_accel`` and ``head_gyro`` (ISO axes, :mod:`controllers.frames`); both
sides go through the same :class:`~controllers.vestibular.VestibularModel`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path

import numpy as np

from controllers.vestibular import VestibularModel
from controllers.washout import ClassicalWashout, WashoutParamError, WashoutParams
from simpro_mj.config.telemetry import Telemetry, read_telemetry, resample
from simpro_mj.core.errors import UserInputError

__all__ = [
    "PARAMETER_KEYS",
    "ALGORITHMS",
    "TELEMETRY_DIR",
    "check_cueing",
    "resolve_paths",
    "washout_params",
    "vehicle_input",
    "cue_poses",
    "CUE_COLUMNS",
    "cue_metrics",
]

ALGORITHMS = ("classical_washout",)
#: Channels a ``sine`` vehicle input may drive (telemetry column names, SI) and their
#: largest amplitude: 1 g of specific force, 90 deg/s.
SINE_CHANNELS = {
    "fx_mps2": 9.80665,
    "fy_mps2": 9.80665,
    "fz_mps2": 9.80665,
    "wx_rad_s": math.pi / 2,
    "wy_rad_s": math.pi / 2,
}
TELEMETRY_DIR = Path(__file__).resolve().parents[1] / "scenarios" / "telemetry"
PHYSICS_DT_S = 0.001

#: YAML key -> (WashoutParams field, factor from the YAML unit to SI).
PARAMETER_KEYS = {
    "period_ms": ("period", 1e-3),
    "gain_x": ("gain_x", 1.0),
    "gain_y": ("gain_y", 1.0),
    "gain_z": ("gain_z", 1.0),
    "gain_rot": ("gain_rot", 1.0),
    "tilt_omega_rad_s": ("tilt_omega", 1.0),
    "tilt_zeta": ("tilt_zeta", 1.0),
    "tilt_rate_limit_deg_s": ("tilt_rate_limit", math.pi / 180.0),
    "tilt_limit_deg": ("tilt_limit", math.pi / 180.0),
    "heave_omega_rad_s": ("heave_omega", 1.0),
    "heave_zeta": ("heave_zeta", 1.0),
    "heave_omega_b_rad_s": ("heave_omega_b", 1.0),
    "rot_order": ("rot_order", 1.0),
    "rot_omega_rad_s": ("rot_omega", 1.0),
    "rot_zeta": ("rot_zeta", 1.0),
    "heave_fraction": ("heave_fraction", 1.0),
    "stroke_margin_mm": ("stroke_margin", 1e-3),
    "knee": ("knee", 1.0),
}
_MANOEUVRE_KEYS = {
    "type": None,
    "speed_kmh": None,
    "vehicle": "bmw_320i",
    "deceleration_mps2": 5.0,
    "bump_height_m": 0.06,
    "bump_length_m": 0.5,
    "lead_s": 1.0,
}


def _defaults_yaml() -> dict:
    p = WashoutParams()
    out = {}
    for key, (name, factor) in PARAMETER_KEYS.items():
        v = getattr(p, name) / factor
        out[key] = int(round(v)) if name == "rot_order" else float(round(v, 12))
    return out


def check_cueing(value, path: str = "setpoint.cueing") -> dict:
    """Validate a ``cueing`` block; return it with every key spelled out.

    Raises :class:`UserInputError` (one line: the dotted key and what is allowed).
    """
    if not isinstance(value, Mapping):
        raise UserInputError(
            f"invalid value at {path}: expected a mapping with telemetry or manoeuvre"
        )
    allowed = ("telemetry", "manoeuvre", "sine", "algorithm", "parameters")
    for key in value:
        if key not in allowed:
            raise UserInputError(f"unknown key at {path}.{key}: allowed keys are {list(allowed)}")
    tel, man, sine = value.get("telemetry"), value.get("manoeuvre"), value.get("sine")
    if sum(v is not None for v in (tel, man, sine)) != 1:
        raise UserInputError(
            f"invalid value at {path}: give exactly one of telemetry (a CSV file), manoeuvre "
            "or sine"
        )
    if tel is not None and (not isinstance(tel, str) or not tel.strip()):
        raise UserInputError(f"invalid value at {path}.telemetry: {tel!r}; allowed: a file name")
    algo = value.get("algorithm", "classical_washout")
    if algo not in ALGORITHMS:
        raise UserInputError(
            f"invalid value at {path}.algorithm: {algo!r}; allowed: {list(ALGORITHMS)}"
        )
    params = value.get("parameters") or {}
    if not isinstance(params, Mapping):
        raise UserInputError(f"invalid value at {path}.parameters: expected a mapping")
    full = _defaults_yaml()
    for key, v in params.items():
        if key not in PARAMETER_KEYS:
            raise UserInputError(
                f"unknown key at {path}.parameters.{key}: allowed keys are {sorted(PARAMETER_KEYS)}"
            )
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise UserInputError(
                f"invalid value at {path}.parameters.{key}: {v!r}; allowed: a finite number"
            )
        full[key] = int(v) if key == "rot_order" and v == int(v) else float(v)
    try:
        washout_params({"parameters": full})
    except WashoutParamError as exc:
        raise UserInputError(f"invalid value at {path}.parameters: {exc}") from None
    out = {"telemetry": tel, "manoeuvre": None, "algorithm": algo, "parameters": full}
    if man is not None:
        out["manoeuvre"] = _check_manoeuvre(man, f"{path}.manoeuvre")
    if sine is not None:
        out["sine"] = check_sine(sine, f"{path}.sine")
    return out


def check_sine(sine, path: str = "setpoint.cueing.sine") -> dict:
    """A ``sine`` vehicle input: ``channel`` (:data:`SINE_CHANNELS`), ``amplitude`` (SI,
    > 0 up to the channel's limit) and ``period_s`` (0.02..600 s, on the 1 ms grid)."""
    keys = ("channel", "amplitude", "period_s")
    if not isinstance(sine, Mapping):
        raise UserInputError(f"invalid value at {path}: expected a mapping with keys {list(keys)}")
    for key in sine:
        if key not in keys:
            raise UserInputError(f"unknown key at {path}.{key}: allowed keys are {list(keys)}")
    ch = sine.get("channel")
    if ch not in SINE_CHANNELS:
        raise UserInputError(
            f"invalid value at {path}.channel: {ch!r}; allowed: {list(SINE_CHANNELS)}"
        )
    a, period = sine.get("amplitude"), sine.get("period_s")
    top = SINE_CHANNELS[ch]
    if isinstance(a, bool) or not isinstance(a, (int, float)) or not 0 < a <= top:
        raise UserInputError(
            f"invalid value at {path}.amplitude: {a!r}; allowed: 0 < amplitude <= {top:.4g} "
            f"({ch.split('_', 1)[1].replace('mps2', 'm/s^2').replace('rad_s', 'rad/s')})"
        )
    ok = isinstance(period, (int, float)) and not isinstance(period, bool)
    if not (ok and math.isfinite(period) and 0.02 <= period <= 600.0) or (
        abs(period * 1e3 - round(period * 1e3)) > 1e-6
    ):
        raise UserInputError(
            f"invalid value at {path}.period_s: {period!r}; allowed: 0.02..600 s on the 1 ms grid"
        )
    return {"channel": ch, "amplitude": float(a), "period_s": float(period)}


def sine_input(sine: Mapping, t) -> tuple[np.ndarray, np.ndarray]:
    """``f``, ``w`` (len(t), 3) of a ``sine`` vehicle input at times ``t`` (V frame, SI)."""
    from controllers.frames import GRAVITY

    t = np.asarray(t, dtype=float)
    f = np.zeros((t.size, 3))
    w = np.zeros((t.size, 3))
    f[:, 2] = GRAVITY
    ch = sine["channel"]
    k = "xyz".index(ch[1])
    (f if ch[0] == "f" else w)[:, k] += sine["amplitude"] * np.sin(
        2.0 * math.pi * t / sine["period_s"]
    )
    return f, w


def _check_manoeuvre(man, path: str) -> dict:
    from simpro_mj.config.manoeuvres import MANOEUVRES, ManoeuvreError

    if not isinstance(man, Mapping):
        raise UserInputError(f"invalid value at {path}: expected a mapping with type and speed_kmh")
    for key in man:
        if key not in _MANOEUVRE_KEYS:
            raise UserInputError(
                f"unknown key at {path}.{key}: allowed keys are {sorted(_MANOEUVRE_KEYS)}"
            )
    full = dict(_MANOEUVRE_KEYS)
    full.update(man)
    if full["type"] not in MANOEUVRES:
        raise UserInputError(
            f"invalid value at {path}.type: {full['type']!r}; allowed: {list(MANOEUVRES)}"
        )
    if full["speed_kmh"] is None:
        raise UserInputError(f"invalid value at {path}.speed_kmh: missing; allowed: 10..180")
    try:
        _spec(full).check()
    except ManoeuvreError as exc:
        raise UserInputError(
            str(exc).replace("invalid value at ", f"invalid value at {path}.")
        ) from None
    return full


def _spec(man: Mapping):
    from simpro_mj.config.manoeuvres import ManoeuvreSpec

    return ManoeuvreSpec(
        manoeuvre=man["type"],
        speed_kmh=man["speed_kmh"],
        vehicle=man["vehicle"],
        deceleration_mps2=man["deceleration_mps2"],
        bump_height_m=man["bump_height_m"],
        bump_length_m=man["bump_length_m"],
        lead_s=man["lead_s"],
    )


def sweep_defaults() -> dict:
    """The sweepable tree under ``setpoint.cueing`` (its parameters, YAML units)."""
    return {"parameters": _defaults_yaml()}


def resolve_paths(scenario: dict, base: Path | None) -> None:
    """Make ``setpoint.cueing.telemetry`` an absolute path (beside the scenario, then shipped).

    Raises :class:`UserInputError` naming the key if the file is in neither place.
    """
    cue = (scenario.get("setpoint") or {}).get("cueing")
    if not cue or not cue.get("telemetry"):
        return
    name = Path(cue["telemetry"]).expanduser()
    tries = [name] if name.is_absolute() else []
    if not name.is_absolute():
        if base is not None:
            tries.append(Path(base) / name)
        tries += [Path.cwd() / name, TELEMETRY_DIR / name]
    for p in tries:
        if p.is_file():
            cue["telemetry"] = str(p.resolve())
            return
    shipped = sorted(q.name for q in TELEMETRY_DIR.glob("*.csv"))
    raise UserInputError(
        f"invalid value at setpoint.cueing.telemetry: {str(name)!r} not found beside the "
        f"scenario or among the shipped files; allowed: a CSV path or one of {shipped}"
    )


def washout_params(cue: Mapping) -> WashoutParams:
    """:class:`WashoutParams` from a resolved block's ``parameters`` (YAML units)."""
    kw = {}
    for key, v in cue["parameters"].items():
        name, factor = PARAMETER_KEYS[key]
        kw[name] = int(v) if name == "rot_order" else float(v) * factor
    return WashoutParams(**kw)


def _key(cue: Mapping, duration: float) -> str:
    return json.dumps({"cue": cue, "duration": duration}, sort_keys=True, default=str)


@lru_cache(maxsize=8)
def _chain(key: str):
    d = json.loads(key)
    cue, duration = d["cue"], d["duration"]
    n = int(round(duration / PHYSICS_DT_S))
    t = np.arange(n + 1) * PHYSICS_DT_S
    if cue.get("sine"):
        f, w = sine_input(cue["sine"], t)
        s = cue["sine"]
        source = f"sine {s['channel']} {s['amplitude']:g} x {s['period_s']:g} s"
    else:
        if cue.get("telemetry"):
            tel = read_telemetry(cue["telemetry"], label=Path(cue["telemetry"]).name)
        else:
            from simpro_mj.config.manoeuvres import generate

            tel = generate(_spec(cue["manoeuvre"]))
        if tel.t[-1] < t[-1] - 1e-9:
            raise UserInputError(
                f"invalid value at duration_s: {duration:g} s is longer than the vehicle input "
                f"({tel.t[-1]:g} s, {tel.source}); allowed: <= {tel.t[-1]:g}"
            )
        f, w = resample(tel, t)
        source = tel.source
    params = washout_params(cue)
    every = int(round(params.period / PHYSICS_DT_S))
    if abs(every * PHYSICS_DT_S - params.period) > 1e-9:
        raise UserInputError(
            f"invalid value at setpoint.cueing.parameters.period_ms: {params.period * 1e3:g}; "
            "allowed: a positive integer multiple of the 1 ms physics timestep"
        )
    wash = ClassicalWashout(params)
    res = wash.run(f[::every], w[::every])
    pose = np.repeat(res.pose, every, axis=0)[: t.size]  # zero-order hold
    for arr in (f, w, pose):
        arr.setflags(write=False)
    info = {
        "source": source,
        "rate_limited": res.rate_limited,
        "softened": res.softened,
        "every": every,
        "rate_limited_fraction": float(res.rate_limited.mean()),
        "softened_fraction": float(res.softened.mean()),
        "box": {k: list(map(float, v)) if k != "scale" else v for k, v in wash.box.items()},
    }
    return t, f, w, pose, info


def vehicle_input(scenario: Mapping):
    """(t, f, w, pose, info) of a cueing scenario on the 1 ms grid (cached, read-only arrays)."""
    cue = scenario["setpoint"]["cueing"]
    return _chain(_key(cue, float(scenario["duration_s"])))


def cue_poses(scenario: Mapping, t) -> np.ndarray:
    """The washout's set-points (n, 3) at times ``t`` (held between cueing periods)."""
    tg, _, _, pose, _ = vehicle_input(scenario)
    t = np.atleast_1d(np.asarray(t, dtype=float))
    k = np.clip(np.rint(t / PHYSICS_DT_S).astype(int), 0, tg.size - 1)
    return pose[k]


#: Extra logged columns of a cueing run (V frame, SI).
CUE_COLUMNS = (
    [f"veh_f{a}_mps2" for a in "xyz"]
    + [f"veh_w{a}_rad_s" for a in "xyz"]
    + [f"head_f{a}_mps2" for a in "xyz"]
    + [f"head_w{a}_rad_s" for a in "xyz"]
)


# ------------------------------------------------------------------ metrics

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


def cue_metrics(columns: Mapping, scenario: Mapping, model: VestibularModel | None = None) -> dict:
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
