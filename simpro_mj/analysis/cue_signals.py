"""Measures of one cueing channel: the vehicle's perceived signal against the head's.

Plain functions on two perceived signals ``pv`` (the vehicle's) and ``ps`` (the
simulator's head) sampled at ``dt``: their correlation and the lag that maximises it,
the onsets of a sensation and how the head follows each, the rotation felt beyond the
car's, how strong the head's sensation is, and a law's share of the bound's. The
``cueing`` block of ``metrics.json`` (:mod:`simpro_mj.analysis.cue_metrics`) is made of
them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

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


def false_rotation(pv: np.ndarray, ps: np.ndarray) -> np.ndarray:
    """The simulator's rotation sensation beyond the vehicle's, in its own direction:
    ``|ps| - max(0, sign(ps) pv)``. A weaker rotation of the right sense is not false
    (negative); one of the wrong sense, or one the vehicle does not make, is all false;
    one stronger than the vehicle's is false by the excess."""
    s = np.sign(ps)
    return np.abs(ps) - np.maximum(0.0, s * pv)


def onsets(pv: np.ndarray, thr: float) -> list[tuple[int, int]]:
    """The onsets of a sensation: ``(start, end)`` sample ranges, each from its
    magnitude crossing ``thr`` (from below, or a change of sign above it) to where it
    falls back below ``thr`` or changes sign."""
    sign = np.where(np.abs(pv) > thr, np.sign(pv), 0.0)
    out = []
    start = None
    for i in np.flatnonzero(np.diff(np.r_[0.0, sign, 0.0]) != 0):
        if start is not None:
            out.append((start, int(i)))
            start = None
        if i < sign.size and sign[i] != 0:
            start = int(i)
    return out


def onset_block(
    t: np.ndarray,
    pv: np.ndarray,
    ps: np.ndarray,
    veh_raw: np.ndarray,
    raw: np.ndarray,
    thr: float,
) -> dict:
    """Onset delay and wrong-sign figures of one channel (:func:`cue_metrics`).

    An onset counts where the vehicle's stimulus itself is past the threshold with
    the sensation's sign when the sensation crosses it (a stimulus, not the
    otoliths' after-effect once a sustained force ends)."""
    dt = float(t[1] - t[0])
    delays, raw_peaks, raw_wrong_s = [], [], 0.0
    missed = 0
    for a, b in onsets(pv, thr):
        s = np.sign(pv[a])
        if not np.any(s * veh_raw[a : min(b, a + int(round(0.2 / dt)) + 1)] > thr):
            continue
        # the head's sensation crossing the threshold with the vehicle's sign, from the
        # vehicle's crossing until its sensation ends (an onset missed when it never does)
        hit = np.flatnonzero(s * ps[a:b] > thr)
        if hit.size:
            delays.append(float(hit[0] * dt))
        else:
            missed += 1
        # the raw head signal against the vehicle's stimulus, from the vehicle's
        # crossing to its peak, where the stimulus is past the threshold
        peak = a + int(np.argmax(np.abs(pv[a:b])))
        stim = s * veh_raw[a : peak + 1] > thr
        wrong = np.where(stim, -s * raw[a : peak + 1], 0.0)
        raw_peaks.append(float(wrong.max()))
        raw_wrong_s += float((wrong > thr).sum() * dt)
    return {
        "onsets": len(delays) + missed,
        "onset_delay_s": max(delays) if delays else None,
        "onset_delays_s": delays,
        "onsets_missed": missed,
        "onset_raw_wrong_sign_peak": max(raw_peaks) if raw_peaks else None,
        "onset_raw_wrong_sign_s": raw_wrong_s,
        "onset_raw_right_sign": bool(raw_peaks) and max(raw_peaks) <= thr,
    }


def correlation(a: np.ndarray, b: np.ndarray) -> float | None:
    if a.size < 2 or a.std() == 0 or b.std() == 0:
        return None
    return float(np.corrcoef(a, b)[0, 1])


def strength(pv: np.ndarray, ps: np.ndarray, lag_s: float | None, dt: float) -> dict:
    """How strong the head's sensation ``ps`` is against the vehicle's ``pv``.

    ``gain``: the least-squares ``g`` minimising ``|ps(t + lag) - g pv(t)|`` over the
    overlap, at the mean lag (so that a late cue of the right size is not read as a
    weak one; the lag is reported beside); ``gain_rms``: ``rms(ps) / rms(pv)`` (no
    shape, no shift). A cue of the right shape at a tenth of the car's has correlation
    1 and gain 0.1. None where the vehicle's sensation is zero.
    """
    k = int(round((lag_s or 0.0) / dt))
    k = min(max(k, 0), pv.size - 2)
    a, b = pv[: pv.size - k], ps[k:]
    den = float(a @ a)
    rv = float(np.sqrt(np.mean(pv * pv)))
    return {
        "gain": float(a @ b) / den if den > 0 else None,
        "gain_rms": float(np.sqrt(np.mean(ps * ps))) / rv if rv > 0 else None,
    }


def bound_share(ch: Mapping, b: Mapping | None) -> dict:
    """The law's share of the bound on one channel: ``gain_share`` (its gain over the
    bound's) and ``error_share`` (how much of the error the bound removes, against a
    platform at rest whose head feels nothing, the law removes: ``(e_0 - e) / (e_0 -
    e_bound)`` with ``e_0`` the RMS of the vehicle's sensation). None where undefined
    (``error_share`` also where the bound removes less than a tenth of ``e_0``)."""
    if not b:
        return {"gain_share": None, "error_share": None}
    g, gb = ch.get("gain"), b.get("gain")
    e0 = ch.get("vehicle_rms")
    e, eb = ch.get("rms_error"), b.get("rms_error")
    # undefined where the bound removes less than a tenth of the error (a channel the
    # car hardly drives, such as the roll rate in a straight braking): no share to take
    share = None
    if e0 is not None and e is not None and eb is not None and e0 - eb > 0.1 * e0 > 0:
        share = (e0 - e) / (e0 - eb)
    return {
        "gain_share": g / gb if g is not None and gb and abs(gb) > 1e-9 else None,
        "error_share": share,
    }
