"""Every rate an integer multiple of the physics timestep: the one check.

The co-simulation steps MuJoCo at :data:`PHYSICS_DT_S` (the ``timestep`` of
``models/simpro_platform.xml``; ``tests/test_model.py`` checks they
agree). Sensors, the outer loop, the washout and the set-point filter run every
k-th step, so each of their periods must be a whole number of steps: a
period of 2.5 ms would be silently rounded to 2 or 3 steps and change the
loop the analysis describes. The scenario (:mod:`simpro_mj.config.rules`), the
sensors (:mod:`simpro_mj.plant.sensors`), the loop (:mod:`simpro_mj.sim.loop`)
and the washout (:mod:`simpro_mj.config.cueing`) all ask :func:`whole_steps`.
"""

from __future__ import annotations

import math

from simpro_mj.core.errors import UserInputError

#: The physics timestep (s, and ms), that of the shipped MJCF.
PHYSICS_DT_S = 0.001
PHYSICS_DT_MS = 1

#: Relative tolerance of "a whole number of steps" (periods are typed in ms).
_TOL = 1e-9


def whole_steps(period_s: float, dt: float = PHYSICS_DT_S) -> int | None:
    """The number of steps ``k >= 1`` with ``k dt = period_s``, or None if there is none.

    ``period_s / dt`` must be within ``1e-9`` (relative, at least absolute) of
    a positive integer; non-finite and non-positive periods have none.
    """
    try:
        n = float(period_s) / dt
    except (TypeError, ValueError):
        return None
    if not math.isfinite(n):
        return None
    k = round(n)
    if k < 1 or abs(n - k) > _TOL * max(1.0, n):
        return None
    return int(k)


def steps_per_period(period_ms: float, dt: float, path: str) -> int:
    """:func:`whole_steps` of a period given in ms, or a one-line error naming ``path``.

    Raises
    ------
    UserInputError
        ``invalid value at PATH: 2.5; allowed: a positive integer multiple of
        the 1 ms physics step``.
    """
    k = whole_steps(period_ms * 1e-3, dt)
    if k is None:
        raise UserInputError(
            f"invalid value at {path}: {period_ms:g}; allowed: a positive integer multiple "
            f"of the {dt * 1e3:g} ms physics step"
        )
    return k
