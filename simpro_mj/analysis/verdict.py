"""A run's verdict: did the pose settle, or does it still oscillate or drift at the end?

A run that ran to its end is ``ok`` only if, over the metrics' final window
(the last ``min(3 s, 20 %)`` of the run, :func:`simpro_mj.analysis.metrics.final_window`),
the error ``reference - true pose`` of every task axis is quiet:

* the error is fitted, by least squares, with a constant, a straight line in
  time and, for every axis whose reference moves in the window, that
  reference and its first two derivatives (a linear loop's tracking error of
  a slow reference, ``e ≈ c0 r + c1 ṙ + c2 r̈``). The fit is the error the set
  point explains; what is left over (the *residual*) is the loop's own motion.
  The error is judged against the set-point, not the pose's motion: a cue
  or a sine that is still being followed at the end is not an oscillation.
* **limit_cycle**: the residual's amplitude (``√2 × rms``, a sine's amplitude)
  exceeds the axis' threshold and its spectrum peaks at a frequency with at
  least :data:`MIN_CYCLES` periods in the window (≥ 0.67 Hz in 3 s). The
  fastest cycle the task-space loop can hold is half its rate, ``1 / (2 T)``
  (8.3 Hz at T = 60 ms); a faster one comes from the joint loops (valve chatter).
* **not_settled**: the residual exceeds the threshold at a slower frequency
  (fewer than two periods in the window), or the straight line's change
  over the window (a drift, a slow convergence) exceeds the threshold.

The threshold of an axis is the settling band's floor
(:data:`simpro_mj.analysis.metrics.SETTLING_FLOOR`: 0.02 deg, 0.2 mm, the band a
settled step stays in), or :data:`FLOOR_FACTOR` times the sensors' resolution
floor (:meth:`simpro_mj.plant.sensors.SensorConfig.resolution_floor` without the
IMU's static bias: quantisation plus three standard deviations of the 1 s averaged
noise) if that is larger. A bias moves the pose the loop settles at, by a constant
the fit takes out; it does not oscillate, so it does not raise the threshold (a
0.5 deg bias would otherwise let a 2 deg peak-to-peak cycle read ``ok``). On the
shipped step scenarios the residual is 0.002-0.003 deg and 0.01-0.02 mm (the sensor
noise the loop feeds back), ten times below it; the outer gains [25, 25, 25] on
``step_pitch`` hold a roll cycle of about 4 deg at 2 Hz.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from simpro_mj.analysis.metrics import AXES, SETTLING_FLOOR, final_window

#: What a run that ran to its end can be.
VERDICTS = ("ok", "limit_cycle", "not_settled")
#: The statuses of a run that finished (judged, or stopped by a divergence).
FINISHED_STATUSES = (*VERDICTS, "diverged")
#: A limit cycle completes at least this many periods in the final window.
MIN_CYCLES = 2.0
#: The threshold is at least this many sensor resolution floors.
FLOOR_FACTOR = 3.0
#: Where a reference moves in the window: the threshold is at least this share
#: of its peak-to-peak excursion there.
TRACKING_FRACTION = 0.1

_TRUE = {"roll": "roll_rad", "pitch": "pitch_rad", "heave": "heave_m"}
_REF = {"roll": "roll_ref_rad", "pitch": "pitch_ref_rad", "heave": "heave_ref_m"}
#: SI to the unit shown in a reason, and that unit.
_SHOW = {"roll": (180.0 / math.pi, "deg"), "pitch": (180.0 / math.pi, "deg"), "heave": (1e3, "mm")}


def thresholds(sensor_floor: Mapping | None = None) -> dict:
    """Per-axis amplitude threshold (SI): max(settling floor, FLOOR_FACTOR x sensor floor)."""
    floor = sensor_floor or {}
    return {a: max(SETTLING_FLOOR[a], FLOOR_FACTOR * float(floor.get(a, 0.0))) for a in AXES}


def _moving(x: np.ndarray, scale: float) -> bool:
    return x.size > 2 and float(np.ptp(x)) > 1e-9 * max(scale, 1.0)


def verdict(columns: Mapping, sensor_floor: Mapping | None = None) -> dict:
    """The verdict of a run that ran to its end (criterion: module docstring).

    Parameters
    ----------
    columns : mapping of str to ndarray
        The logged time series: ``time_s`` and per axis the reference and
        the true pose (SI).
    sensor_floor : mapping, optional
        The sensors' resolution floor per axis (SI).

    Returns
    -------
    dict
        ``status`` (one of :data:`VERDICTS`), ``reason`` (None or one line),
        ``axis``, ``amplitude``, ``frequency_hz`` (the worst axis; SI), and
        ``window_s``, ``thresholds`` and per axis ``amplitude``,
        ``frequency_hz``, ``drift`` (the straight line's change over the
        window, SI).
    """
    t = np.asarray(columns["time_s"], dtype=float)
    out: dict = {
        "status": "ok",
        "reason": None,
        "axis": None,
        "amplitude": None,
        "frequency_hz": None,
        "window_s": None,
        "thresholds": thresholds(sensor_floor),
        "axes": {},
    }
    if t.size < 8:
        return out
    w0, w1 = final_window(t)
    sel = t >= w0
    ts = t[sel]
    if ts.size < 8 or not np.all(np.isfinite(ts)):
        return out
    width = float(ts[-1] - ts[0])
    out["window_s"] = [float(ts[0]), float(ts[-1])]
    x = (ts - ts[0]) / max(width, 1e-12)
    basis = [np.ones_like(ts)]
    excursion = {}
    for a in AXES:  # the references that move in the window, and their derivatives
        r = np.asarray(columns[_REF[a]], dtype=float)[sel]
        excursion[a] = float(np.ptp(r)) if np.all(np.isfinite(r)) else 0.0
        if np.all(np.isfinite(r)) and _moving(r, float(np.abs(r).max())):
            d1 = np.gradient(r, ts)
            basis += [r, d1, np.gradient(d1, ts)]
    A = np.column_stack(basis)
    A = A / np.maximum(np.abs(A).max(axis=0), 1e-300)
    line = np.column_stack([np.ones_like(x), x])
    dt = float(np.median(np.diff(ts)))
    f_min = MIN_CYCLES / width if width > 0 else math.inf
    worst = None
    for a in AXES:
        out["thresholds"][a] = max(out["thresholds"][a], TRACKING_FRACTION * excursion[a])
        e = (
            np.asarray(columns[_REF[a]], dtype=float)[sel]
            - np.asarray(columns[_TRUE[a]], dtype=float)[sel]
        )
        if not np.all(np.isfinite(e)):
            out.update(status="not_settled", reason=f"{a}: non-finite pose at the end", axis=a)
            return out
        # what the set-point explains, then the straight line of what is left
        rest = e - A @ np.linalg.lstsq(A, e, rcond=None)[0]
        c_line = np.linalg.lstsq(line, rest, rcond=None)[0]
        resid = rest - line @ c_line
        drift = float(c_line[1])
        amp = float(math.sqrt(2.0) * np.sqrt(np.mean(resid**2)))
        spec = np.abs(np.fft.rfft(resid * np.hanning(resid.size), n=8 * resid.size))
        freqs = np.fft.rfftfreq(8 * resid.size, dt)
        spec[0] = 0.0
        f = float(freqs[int(np.argmax(spec))])
        thr = out["thresholds"][a]
        out["axes"][a] = {"amplitude": amp, "frequency_hz": f, "drift": drift}
        if amp > thr:
            kind = "limit_cycle" if f >= f_min else "not_settled"
            score = amp / thr
        elif abs(drift) > thr:
            kind, score = "not_settled", abs(drift) / thr
        else:
            continue
        rank = (kind == "limit_cycle", score)
        if worst is None or rank > worst[0]:
            worst = (rank, kind, a, amp if kind == "limit_cycle" or amp > thr else drift, f)
    if worst is not None:
        _, kind, a, amp, f = worst
        scale, unit = _SHOW[a]
        thr = out["thresholds"][a] * scale
        if kind == "limit_cycle":
            reason = (
                f"limit cycle on {a}: amplitude {amp * scale:.3g} {unit} at {f:.3g} Hz over "
                f"the last {width:.3g} s (threshold {thr:.3g} {unit})"
            )
        else:
            what = "oscillates" if abs(amp) == out["axes"][a]["amplitude"] else "drifts"
            reason = (
                f"not settled on {a}: {what} by {abs(amp) * scale:.3g} {unit} over the last "
                f"{width:.3g} s (threshold {thr:.3g} {unit})"
            )
        out.update(
            status=kind,
            reason=reason,
            axis=a,
            amplitude=abs(amp),
            frequency_hz=f if kind == "limit_cycle" else None,
        )
    return out
