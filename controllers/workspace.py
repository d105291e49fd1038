"""Reachable workspace of the platform from the stroke limits and the guide arc.

The platform reaches a pose when every leg's q_i lies in [0, stroke] and the
U joint B1 can sit on the guide circle. Ranges are found by bisection on the
boundary of :func:`controllers.kinematics.reachable` along one axis at a time,
the others fixed.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .geometry import PlatformGeometry, nominal_geometry
from .kinematics import AXIS_NAMES, reachable


def axis_range(
    axis: int,
    geometry: PlatformGeometry | None = None,
    at=None,
    margin: float = 0.0,
    span: float = 1.0,
    tol: float = 1e-9,
) -> tuple[float, float]:
    """(min, max) of one pose axis (0 roll, 1 pitch, 2 heave) with the others at ``at``.

    ``at`` defaults to the home pose and must be reachable. ``span`` bounds the
    search (rad or m) on each side.
    """
    g = nominal_geometry() if geometry is None else geometry
    x0 = np.array(g.home if at is None else at, dtype=float)
    if not reachable(x0, g, margin):
        raise ValueError(f"axis_range: the pose {x0} is not reachable")
    out = []
    for sign in (-1.0, 1.0):
        lo, hi = 0.0, span  # reachable at lo, search for the first unreachable
        probe = x0.copy()
        probe[axis] = x0[axis] + sign * hi
        if reachable(probe, g, margin):
            out.append(x0[axis] + sign * hi)
            continue
        # coarse scan first, so a disconnected far region is not mistaken
        steps = np.linspace(0.0, span, 201)
        probes = np.repeat(x0[None], steps.size, axis=0)
        probes[:, axis] = x0[axis] + sign * steps
        ok = reachable(probes, g, margin)
        first_bad = int(np.argmin(ok))
        lo, hi = steps[first_bad - 1], steps[first_bad]
        while hi - lo > tol:
            mid = 0.5 * (lo + hi)
            probe[axis] = x0[axis] + sign * mid
            if reachable(probe, g, margin):
                lo = mid
            else:
                hi = mid
        out.append(x0[axis] + sign * lo)
    return out[0], out[1]


def workspace_ranges(geometry: PlatformGeometry | None = None, margin: float = 0.0) -> dict:
    """Single-axis ranges about home: ``{"roll": (lo, hi), "pitch": ..., "heave": ...}`` (SI)."""
    return {name: axis_range(k, geometry, margin=margin) for k, name in enumerate(AXIS_NAMES)}


def combined_ranges(
    geometry: PlatformGeometry | None = None, n: int = 5, margin: float = 0.0
) -> list[dict]:
    """Roll and pitch ranges at ``n`` heights across the heave range.

    Shows how the angular workspace shrinks away from mid-heave.
    """
    g = nominal_geometry() if geometry is None else geometry
    hlo, hhi = axis_range(2, g, margin=margin)
    rows = []
    for h in np.linspace(hlo, hhi, n + 2)[1:-1]:
        at = np.array([0.0, 0.0, h])
        rows.append(
            {
                "heave": float(h),
                "roll": axis_range(0, g, at=at, margin=margin),
                "pitch": axis_range(1, g, at=at, margin=margin),
            }
        )
    return rows


# ---------------------------------------------------------------- motion cueing


def inscribed_box(
    geometry: PlatformGeometry | None = None,
    heave_fraction: float = 0.5,
    margin: float = 0.01,
    n: int = 5,
) -> dict:
    """A box about home, in (roll, pitch, heave), whose every point is reachable.

    The single-axis ranges overstate what can be combined: at the ends of the
    heave range the angular ranges shrink to half (:func:`combined_ranges`).
    The heave half-ranges are ``heave_fraction`` of the single-axis ones; the
    roll and pitch half-ranges are the single-axis ones scaled by the largest
    ``s`` (bisection, 30 steps) for which an ``n x n x n`` grid over the box
    is reachable with the stroke ``margin`` (m). The reachable set is not
    convex in general, so the grid is the test; :func:`soft_limit` keeps
    cueing set-points inside the box.

    Returns
    -------
    dict
        ``{"roll": (lo, hi), "pitch": (lo, hi), "heave": (lo, hi), "scale": s}``
        (rad, rad, m absolute heights).
    """
    g = nominal_geometry() if geometry is None else geometry
    if not (0.0 < heave_fraction <= 1.0):
        raise ValueError(f"heave_fraction must be in (0, 1], got {heave_fraction!r}")
    home = np.asarray(g.home, dtype=float)
    single = [axis_range(k, g, margin=margin) for k in range(3)]
    hlo = home[2] + heave_fraction * (single[2][0] - home[2])
    hhi = home[2] + heave_fraction * (single[2][1] - home[2])
    u = np.linspace(0.0, 1.0, n)

    def grid(s: float) -> np.ndarray:
        axes = [
            home[k] + s * (single[k][0] - home[k]) + u * s * (single[k][1] - single[k][0])
            for k in range(2)
        ]
        axes.append(hlo + u * (hhi - hlo))
        mesh = np.meshgrid(*axes, indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=-1)

    lo, hi = 0.0, 1.0
    if not reachable(grid(lo), g, margin).all():
        raise ValueError("inscribed_box: the heave range alone is not reachable; lower it")
    if reachable(grid(hi), g, margin).all():
        lo = hi
    for _ in range(30):
        if hi - lo < 1e-6:
            break
        mid = 0.5 * (lo + hi)
        if reachable(grid(mid), g, margin).all():
            lo = mid
        else:
            hi = mid
    s = lo
    out: dict[str, Any] = {
        name: (home[k] + s * (single[k][0] - home[k]), home[k] + s * (single[k][1] - home[k]))
        for k, name in enumerate(AXIS_NAMES[:2])
    }
    out["heave"] = (float(hlo), float(hhi))
    out["scale"] = float(s)
    return out


def soft_limit(x, centre, lo, hi, knee: float = 0.8):
    """Smooth saturation of ``x`` into the open interval (lo, hi) about ``centre``.

    With ``d = x - centre`` and ``L`` the distance from the centre to the limit
    on d's side: ``d`` unchanged for ``|d| <= knee L``; beyond,
    ``knee L + (1 - knee) L tanh((|d| - knee L) / ((1 - knee) L))``. Value and
    slope are continuous at the knee (tanh'(0) = 1), the output is monotonic
    and approaches the limit asymptotically (reaching it only where tanh rounds
    to 1, far past it), so a set-point near the workspace
    boundary slows down instead of hitting it (a clip would step the rate).
    ``knee = 1`` is a hard clip. ``x`` a float or an array; ``lo < centre < hi``
    is required.
    """
    if not (0.0 <= knee <= 1.0):
        raise ValueError(f"knee must be in [0, 1], got {knee!r}")
    if np.ndim(x):  # an array: the same arithmetic on each element
        return np.vectorize(soft_limit, otypes=[float])(x, centre, lo, hi, knee)
    d = float(x) - centre
    span = hi - centre if d >= 0.0 else centre - lo
    if span <= 0:
        raise ValueError(f"soft_limit needs lo < centre < hi, got {lo!r}, {centre!r}, {hi!r}")
    a, k = abs(d), knee * span
    if knee >= 1.0:
        mag = min(a, span)
    else:
        rest = (1.0 - knee) * span
        mag = a if a <= k else k + rest * math.tanh((a - k) / rest)
    return centre + math.copysign(mag, d)
