"""Reachable workspace of the platform from the stroke limits and the guide arc.

The platform reaches a pose when every leg's q_i lies in [0, stroke] and the
U joint B1 can sit on the guide circle. Ranges are found by bisection on the
boundary of :func:`controllers.kinematics.reachable` along one axis at a time,
the others fixed.
"""

from __future__ import annotations

import numpy as np

from .geometry import PlatformGeometry, nominal_geometry
from .kinematics import AXIS_NAMES, reachable

__all__ = ["axis_range", "workspace_ranges", "combined_ranges"]


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
