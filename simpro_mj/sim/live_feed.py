"""A game's feed as it arrives: jitter, loss, duplicates, reordering, pauses and a bias.

``simpro-sim send`` paces a telemetry file exactly; a game on a busy machine and a
network do not. :func:`impair` turns the exact schedule of (times, datagrams) into the
one a rig sees, reproducibly from a seed, so that ``simpro-sim live`` can be judged on
it (docs/live.md): each datagram's send time moved uniformly within ``+-jitter_s``
(the sends kept in their new time order), a share ``loss`` dropped, a share
``duplicate`` sent twice, a share ``reorder`` swapped with the next one, and nothing
sent within each pause ``(at_s, length_s)`` while the game's clock runs on (the first
datagram after it carries the later time). A bias of the vertical specific force (a
real accelerometer's, 9.6 instead of 9.81 m/s^2) is the telemetry's own
(:func:`biased`), packed into every datagram.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from simpro_mj.config.telemetry import Telemetry
from simpro_mj.core.errors import UserInputError


@dataclass(frozen=True)
class FeedImpairment:
    """What happens to a feed on its way (:func:`impair`); the defaults change nothing.

    Attributes
    ----------
    jitter_s : float
        Each send time moved uniformly within ``+-jitter_s`` (s), 0..0.1.
    loss, duplicate, reorder : float
        Shares of the datagrams dropped, sent twice, swapped with the next, 0..0.5 each.
    pauses : tuple of (at_s, length_s)
        Spans of the game's time in which nothing is sent.
    seed : int
        The draws' seed: the same seed, the same feed.
    """

    jitter_s: float = 0.0
    loss: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0
    pauses: tuple[tuple[float, float], ...] = ()
    seed: int = 1

    def __post_init__(self):
        checks = {
            "--jitter-ms": (self.jitter_s * 1e3, 0.0, 100.0),
            "--loss": (self.loss, 0.0, 0.5),
            "--duplicate": (self.duplicate, 0.0, 0.5),
            "--reorder": (self.reorder, 0.0, 0.5),
        }
        for key, (v, lo, hi) in checks.items():
            if not (math.isfinite(v) and lo <= v <= hi):
                raise UserInputError(f"invalid value at {key}: {v:g}; allowed: {lo:g}..{hi:g}")
        for at, length in self.pauses:
            if not (math.isfinite(at) and math.isfinite(length) and at >= 0 and length > 0):
                raise UserInputError(
                    f"invalid value at --pause: {at:g}:{length:g}; allowed: AT_S:LENGTH_S, "
                    "AT_S >= 0 and LENGTH_S > 0"
                )


def impair(times, grams: list, imp: FeedImpairment) -> tuple[np.ndarray, list, dict]:
    """(times, datagrams, counts) of the feed ``times``, ``grams`` after ``imp``.

    The order of the draws is fixed (pauses, loss, reordering, duplicates, jitter), so
    one seed gives one feed. ``counts``: ``paused``, ``lost``, ``reordered`` (pairs
    swapped), ``duplicated``.
    """
    rng = np.random.default_rng(imp.seed)
    t = np.asarray(times, float)
    keep = np.ones(t.size, bool)
    for at, length in imp.pauses:
        keep &= ~((t >= at) & (t < at + length))
    paused = int((~keep).sum())
    lost = keep & (rng.random(t.size) < imp.loss)
    keep &= ~lost
    idx = np.flatnonzero(keep)
    out = [grams[i] for i in idx]
    tt = t[idx].copy()
    swaps = 0
    k = 0
    draws = rng.random(len(out))
    while k < len(out) - 1:
        if draws[k] < imp.reorder:  # this one and the next leave in each other's place
            out[k], out[k + 1] = out[k + 1], out[k]
            swaps += 1
            k += 2
        else:
            k += 1
    dup = rng.random(len(out)) < imp.duplicate
    times_out, grams_out = [], []
    for ti, g, d in zip(tt.tolist(), out, dup.tolist(), strict=True):
        times_out += [ti, ti] if d else [ti]
        grams_out += [g, g] if d else [g]
    ts = np.asarray(times_out, float)
    if imp.jitter_s > 0 and ts.size:
        ts = ts + rng.uniform(-imp.jitter_s, imp.jitter_s, ts.size)
        ts -= min(0.0, float(ts.min()))  # none before the start
        order = np.argsort(ts, kind="stable")
        ts = ts[order]
        grams_out = [grams_out[i] for i in order]
    counts = {"paused": paused, "lost": int(lost.sum()), "reordered": swaps,
              "duplicated": int(dup.sum())}  # fmt: skip
    return ts, grams_out, counts


def biased(tel: Telemetry, fz_mps2: float) -> Telemetry:
    """``tel`` with ``fz_mps2`` added to its vertical specific force (a bias)."""
    if not math.isfinite(fz_mps2) or abs(fz_mps2) > 5.0:
        raise UserInputError(f"invalid value at --bias-fz-mps2: {fz_mps2:g}; allowed: -5..5")
    f = np.array(tel.f, float)
    f[:, 2] += fz_mps2
    return Telemetry(t=tel.t, f=f, w=tel.w, source=tel.source)
