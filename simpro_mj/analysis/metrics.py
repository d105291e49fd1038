"""Performance figures of a run: steady-state error, step response, IAE.

Definitions (also written into ``metrics.json`` under ``definitions``):

* **error** ``e = reference - true pose`` (the plant's pose, not the
  sensors'); SI: rad, rad, m.
* **final window**: the last ``min(3 s, 20 % of the run)`` of the log.
* **steady_state_error**: signed mean of ``e`` over the final window
  (``steady_state_error_measured``: the same with the sensors' pose; the
  task-space loop drives this one to zero, the true error keeps the sensors'
  offsets).
* **step**: the last step component of the axis in the scenario (steps at the
  same time add up); ``null`` figures if the axis has none.
* Step-response figures follow MATLAB's ``stepinfo``: relative to the
  output's own change ``Δy = y_final - y_0`` with ``y_0`` the output at the
  last sample before the step and ``y_final`` its mean over the final window.

  - **rise_time_s**: from 10 % to 90 % of ``Δy`` (first crossings, linear
    interpolation between samples);
  - **overshoot_pct**: ``100 max(0, max((y - y_0)/Δy) - 1)`` after the step;
  - **settling_time_s**: from the step until ``|y - y_final|`` stays within
    ``max(2 % |Δy|, floor)``, floor 0.02 deg (roll, pitch) or 0.2 mm (heave):
    the true pose jitters with the sensor noise the loops feed back, and a
    band below that would never be entered; ``null`` if the last sample is
    outside the band;
  - if the output moved by less than 10 % of the reference step (or the
    wrong way), these three are ``null`` and ``note`` says why.

* **iae**: ``∫ |e| dt`` over the whole run (trapezoidal), rad s or m s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass

import numpy as np

from simpro_mj.analysis.cue_metrics import cue_metrics  # vehicle vs simulator, perceived
from simpro_mj.config.entries import Step
from simpro_mj.config.models import Scenario, as_scenario

AXES = ("roll", "pitch", "heave")
UNITS = {"roll": "rad", "pitch": "rad", "heave": "m"}
_TRUE = {"roll": "roll_rad", "pitch": "pitch_rad", "heave": "heave_m"}
_REF = {"roll": "roll_ref_rad", "pitch": "pitch_ref_rad", "heave": "heave_ref_m"}
_MEAS = {"roll": "roll_meas_rad", "pitch": "pitch_meas_rad", "heave": "heave_meas_m"}

#: Final window: the last min(FINAL_WINDOW_S, FINAL_WINDOW_FRACTION * run) seconds.
FINAL_WINDOW_S = 3.0
FINAL_WINDOW_FRACTION = 0.2
#: Settling band: SETTLING_BAND * |Δy|, but not narrower than SETTLING_FLOOR (SI).
SETTLING_BAND = 0.02
SETTLING_FLOOR = {"roll": math.radians(0.02), "pitch": math.radians(0.02), "heave": 0.2e-3}
#: The output must move by at least this fraction of the reference step.
MIN_RESPONSE = 0.1

DEFINITIONS = {
    "error": "reference - true pose (SI: rad, rad, m)",
    "final_window": f"last min({FINAL_WINDOW_S} s, {FINAL_WINDOW_FRACTION:.0%} of the run)",
    "steady_state_error": "signed mean of the error over the final window",
    "step": "last step component of the axis in the scenario",
    "rise_time_s": "10 % -> 90 % of the output change y_final - y_0 (stepinfo convention)",
    "overshoot_pct": "peak beyond y_final after the step, % of the output change",
    "settling_time_s": (
        f"from the step until |y - y_final| stays within max({SETTLING_BAND:.0%} of the output "
        "change, floor); floor 0.02 deg (roll, pitch), 0.2 mm (heave)"
    ),
    "iae": "integral of |error| dt over the run (trapezoidal)",
}


def final_window(time_s: np.ndarray) -> tuple[float, float]:
    """(start, end) of the final window of a time column (s)."""
    t0, t1 = float(time_s[0]), float(time_s[-1])
    width = min(FINAL_WINDOW_S, FINAL_WINDOW_FRACTION * (t1 - t0))
    return t1 - width, t1


def _finite_prefix(columns: Mapping, names) -> int:
    """Number of leading rows where every named column is finite (a diverged run stops there)."""
    n = len(columns["time_s"])
    for name in names:
        bad = ~np.isfinite(np.asarray(columns[name], dtype=float)[:n])
        if bad.any():
            n = int(np.argmax(bad))
    return n


@dataclass
class StepFigures:
    """A step response's figures (:func:`step_info`); None where one does not apply."""

    output_change: float
    rise_time_s: float | None = None
    overshoot_pct: float | None = None
    settling_time_s: float | None = None
    settling_band: float | None = None
    #: None, or why figures are None
    note: str | None = None


@dataclass
class AxisMetrics:
    """One task axis's figures in ``metrics.json`` (SI; :data:`DEFINITIONS`)."""

    steady_state_error: float | None = None
    steady_state_error_measured: float | None = None
    rise_time_s: float | None = None
    settling_time_s: float | None = None
    overshoot_pct: float | None = None
    iae: float | None = None
    rms_error: float | None = None
    max_abs_error: float | None = None
    #: the last step's time, reference and output changes and settling band
    step: dict | None = None
    note: str | None = None


def _crossing(t: np.ndarray, s: np.ndarray, level: float) -> float | None:
    """First time ``s`` reaches ``level`` (interpolated), or None."""
    idx = np.flatnonzero(s >= level)
    if idx.size == 0:
        return None
    k = int(idx[0])
    if k == 0:
        return float(t[0])
    s0, s1 = s[k - 1], s[k]
    return float(t[k - 1] + (level - s0) / (s1 - s0) * (t[k] - t[k - 1]))


def step_info(
    t: np.ndarray,
    y: np.ndarray,
    t_step: float,
    y_final: float,
    ref_change: float,
    floor: float = 0.0,
) -> StepFigures:
    """Rise time, overshoot and settling time of a step response.

    Not :func:`controllers.analysis.inner.step_metrics` (:func:`control.step_info`):
    that one reads the crossings on the sample grid and settles in a band
    proportional to the final value; a run's figures interpolate the 10 %,
    90 % and band crossings between logged rows and give the band a floor
    (the sensors' resolution, :data:`SETTLING_FLOOR`), and the reference
    metrics (``tests/test_reference_metrics.py``) hold these numbers.

    Parameters
    ----------
    t, y : ndarray
        Time (s) and output.
    t_step : float
        Time of the step (s).
    y_final : float
        Final value of the output (e.g. its mean over the final window).
    ref_change : float
        Size of the reference step (same unit as y); sets the direction and
        the "did it respond" check.
    floor : float
        Narrowest settling half-band (same unit as y).

    Returns
    -------
    StepFigures
        None where a figure does not apply, and the ``note`` says why.
    """
    before = np.flatnonzero(t < t_step)
    y0 = float(y[before[-1]]) if before.size else float(y[0])
    dy = float(y_final) - y0
    out = StepFigures(output_change=dy)
    if ref_change == 0 or dy / ref_change < MIN_RESPONSE:
        out.note = (
            f"the output moved by {dy:.4g} for a reference step of {ref_change:.4g} "
            f"(< {MIN_RESPONSE:.0%}): no step-response figures"
        )
        return out
    after = t >= t_step
    ta, ya = t[after], y[after]
    s = (ya - y0) / dy
    t10, t90 = _crossing(ta, s, 0.1), _crossing(ta, s, 0.9)
    if t10 is not None and t90 is not None:
        out.rise_time_s = t90 - t10
    out.overshoot_pct = 100.0 * max(0.0, float(s.max()) - 1.0)
    band = max(SETTLING_BAND * abs(dy), floor)
    out.settling_band = band
    dev = np.abs(ya - y_final)
    outside = np.flatnonzero(dev > band)
    if outside.size == 0:
        out.settling_time_s = 0.0
    elif outside[-1] == ya.size - 1:
        out.note = "not settled at the end of the run"
    else:
        k = int(outside[-1])
        d0, d1 = dev[k], dev[k + 1]
        tc = ta[k] + (d0 - band) / (d0 - d1) * (ta[k + 1] - ta[k])
        out.settling_time_s = float(tc - t_step)
    return out


def _last_step(components, scale: float, t_end: float) -> tuple[float, float] | None:
    """(time, size in SI) of the last step of an axis' set-point ``components`` (edge
    units, ``scale`` to SI) before ``t_end``, or None."""
    steps = [c for c in components if isinstance(c, Step) and 0.0 <= c.time_s < t_end]
    if not steps:
        return None
    t_last = max(c.time_s for c in steps)
    size = sum(c.value for c in steps if c.time_s == t_last) * scale
    return (t_last, size) if size != 0 else None


def _trapz(y: np.ndarray, t: np.ndarray) -> float:
    if y.size < 2:
        return 0.0
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


def compute_metrics(columns: Mapping[str, np.ndarray], scenario: Scenario | Mapping) -> dict:
    """Figures of merit of a run, per task axis (and per leg).

    Parameters
    ----------
    columns : mapping of str to ndarray
        The logged time series (SI, one row per sample): at least ``time_s``
        and, per axis, ``<axis>_ref_*`` and the true pose ``roll_rad``,
        ``pitch_rad``, ``heave_m``; optional ``*_meas_*``, ``q<i>_ref_m``,
        ``q<i>_m``.
    scenario : Scenario or mapping
        The resolved scenario, typed or its dict (for the step times).

    Returns
    -------
    dict
        ``axes.<roll|pitch|heave>`` with ``steady_state_error`` (SI),
        ``steady_state_error_measured``, ``rise_time_s``, ``settling_time_s``,
        ``overshoot_pct``, ``iae``, ``rms_error``, ``max_abs_error``, ``step``
        and ``note``; ``joints.q<i>`` with ``steady_state_error_m`` and
        ``iae``; ``final_window_s``, ``n_samples``, ``units``, ``definitions``.
        Figures that do not apply are ``None``. If some columns turn
        non-finite (a diverged run), only the rows before are used.
    """
    needed = ["time_s"] + [c for a in AXES for c in (_TRUE[a], _REF[a])]
    missing = [c for c in needed if c not in columns]
    if missing:
        raise KeyError(f"compute_metrics: missing columns {missing}")
    n = _finite_prefix(columns, needed)
    sp = as_scenario(scenario).setpoint
    deg = math.pi / 180.0  # the set-points' edge units
    set_points = {"roll": (sp.roll_deg, deg), "pitch": (sp.pitch_deg, deg),
                  "heave": (sp.heave_mm, 1e-3)}  # fmt: skip
    t = np.asarray(columns["time_s"], dtype=float)[:n]
    axes: dict[str, dict] = {}
    joints: dict[str, dict] = {}
    result: dict = {
        "n_samples": n,
        "final_window_s": None,
        "units": dict(UNITS),
        "definitions": dict(DEFINITIONS),
        "axes": axes,
        "joints": joints,
    }
    if n < 2:
        for axis in AXES:
            axes[axis] = asdict(AxisMetrics(note="fewer than 2 finite samples"))
        return result
    w0, w1 = final_window(t)
    result.update(final_window_s=[w0, w1])
    in_window = t >= w0
    for axis in AXES:
        ref = np.asarray(columns[_REF[axis]], dtype=float)[:n]
        y = np.asarray(columns[_TRUE[axis]], dtype=float)[:n]
        e = ref - y
        m = AxisMetrics(
            steady_state_error=float(e[in_window].mean()),
            iae=_trapz(np.abs(e), t),
            rms_error=float(np.sqrt(np.mean(e**2))),
            max_abs_error=float(np.abs(e).max()),
        )
        if _MEAS[axis] in columns:
            ym = np.asarray(columns[_MEAS[axis]], dtype=float)[:n]
            em = (ref - ym)[in_window]
            if np.all(np.isfinite(em)):
                m.steady_state_error_measured = float(em.mean())
        step = _last_step(*set_points[axis], float(t[-1]))
        if step is not None:
            t_step, _ = step
            after = np.flatnonzero(t >= t_step)
            before = np.flatnonzero(t < t_step)
            ref_change = float(ref[after[0]] - (ref[before[-1]] if before.size else ref[0]))
            if not before.size:  # a step at t = 0: from the home pose
                ref_change = step[1]
            y_final = float(y[in_window].mean()) if w0 > t_step else float(y[-1])
            info = step_info(t, y, t_step, y_final, ref_change, SETTLING_FLOOR[axis])
            m.step = {
                "time_s": t_step,
                "reference_change": ref_change,
                "output_change": info.output_change,
                "settling_band": info.settling_band,
            }
            m.rise_time_s, m.settling_time_s = info.rise_time_s, info.settling_time_s
            m.overshoot_pct, m.note = info.overshoot_pct, info.note
        axes[axis] = asdict(m)
    if sp.cueing is not None and "head_fx_mps2" in columns:
        result.update(cueing=cue_metrics(columns, scenario))
    for i in (1, 2, 3):
        qr, qm = f"q{i}_ref_m", f"q{i}_m"
        if qr in columns and qm in columns:
            eq = np.asarray(columns[qr], dtype=float)[:n] - np.asarray(columns[qm], dtype=float)[:n]
            if np.all(np.isfinite(eq)):
                joints[f"q{i}"] = {
                    "steady_state_error_m": float(eq[in_window].mean()),
                    "iae": _trapz(np.abs(eq), t),
                }
    return result
