"""Set-points of a scenario: the reference pose over time, its reachability.

The set-point profile of a resolved scenario (:func:`simpro_mj.config.scenario.load_scenario`):
per axis the sum of its components (:mod:`simpro_mj.config.entries`; what each
one is: :mod:`simpro_mj.config.scenario`) on top of the home pose, or the
washout's poses (``setpoint.cueing``, :mod:`simpro_mj.config.cueing`); SI out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from controllers.errors import WorkspaceError
from controllers.kinematics import check_reachable, reachable
from simpro_mj.config.cueing import cue_poses
from simpro_mj.config.models import Scenario, as_scenario
from simpro_mj.config.rules import PHYSICS_DT_S, SETPOINT_AXES
from simpro_mj.core.errors import UserInputError


class SetpointError(UserInputError, WorkspaceError):
    """A set-point outside the reachable workspace.

    Both a :class:`~simpro_mj.core.errors.UserInputError` (the user's scenario is
    wrong) and a :class:`~controllers.errors.WorkspaceError` (the message of
    :func:`controllers.kinematics.check_reachable` names the limit).
    """


def late_setpoints(scenario: Scenario | Mapping) -> list[str]:
    """Set-point components that start after the run ends: they never act.

    Not an error (a short run of a shipped scenario cuts its steps off on
    purpose), but never silent: :func:`simpro_mj.analysis.preflight.preflight` turns
    each into a warning line, recorded in ``metrics.json``.
    """
    sc = as_scenario(scenario)
    duration = sc.duration_s
    out = []
    for axis in SETPOINT_AXES:  # not setpoint.cueing, which has no components
        for i, c in enumerate(getattr(sc.setpoint, axis)):
            key = {"step": "time_s", "ramp": "start_s", "sine": "start_s"}.get(c.type)
            if key is not None and getattr(c, key) > duration:
                out.append(
                    f"setpoint.{axis}[{i}].{key} = {getattr(c, key):g} s is after the end of the "
                    f"run (duration_s = {duration:g} s): this {c.type} never acts"
                )
    return out


# ------------------------------------------------------------------ set-points


def _clamp(pose: np.ndarray, geometry, iterations: int = 40) -> np.ndarray:
    """Pull unreachable poses back along the segment from home (bisection, vectorised)."""
    ok = reachable(pose, geometry)
    if ok.all():
        return pose
    home = np.asarray(geometry.home, dtype=float)
    bad = pose[~ok]
    d = bad - home
    lo = np.zeros(len(bad))
    hi = np.ones(len(bad))
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        inside = reachable(home + mid[:, None] * d, geometry)
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    out = pose.copy()
    out[~ok] = home + lo[:, None] * d
    return out


def reference(scenario: Scenario | Mapping, t, *, clamp: bool | None = None) -> np.ndarray:
    """The set-point pose at times ``t``, SI, vectorised.

    Parameters
    ----------
    scenario : Scenario or mapping
        A resolved scenario (:func:`load_scenario`).
    t : array_like, (n,)
        Times (s).
    clamp : bool, optional
        Pull unreachable poses back to the workspace boundary along the segment
        from the home pose (40 bisection steps on the nominal geometry).
        Default: the scenario's ``controller.clamp_setpoints``.

    Returns
    -------
    ndarray, (n, 3)
        (roll rad, pitch rad, heave m); heave absolute, home height + ``heave_mm``.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    sc = as_scenario(scenario)
    geometry = sc.plant.geometry()
    if sc.setpoint.cueing is not None:  # the washout's set-points, inside its workspace box
        return cue_poses(sc, t)
    out = np.empty((t.size, 3))
    for j, (axis, scale) in enumerate(
        zip(SETPOINT_AXES, (math.pi / 180.0, math.pi / 180.0, 1e-3), strict=True)
    ):
        total = np.zeros(t.size)
        for c in getattr(sc.setpoint, axis):
            total += c.at(t)
        out[:, j] = geometry.home[j] + scale * total
    if clamp is None:
        clamp = sc.controller.clamp_setpoints
    if clamp:
        out = _clamp(out, geometry)
    return out


#: Poses per block of :func:`check_setpoints` (memory bound, not a result).
_CHECK_BLOCK = 20_000


def check_setpoints(scenario: Scenario | Mapping) -> None:
    """Raise :class:`SetpointError` if the set-point leaves the reachable workspace at
    any time of the 1 ms physics grid over ``[0, duration_s]`` (every sample the
    controllers can see).

    Parameters
    ----------
    scenario : mapping
        A resolved scenario.
    """
    sc = as_scenario(scenario)
    t = np.arange(int(round(sc.duration_s / PHYSICS_DT_S)) + 1) * PHYSICS_DT_S
    geometry = sc.plant.geometry()
    # in blocks: the vectorised IK holds ~350 B of temporaries per pose, which
    # over a whole 600 s grid would be 200 MB for a check that keeps nothing
    for k0 in range(0, t.size, _CHECK_BLOCK):
        pose = reference(sc, t[k0 : k0 + _CHECK_BLOCK], clamp=False)
        # a held pose is checked once, where it starts (a step's 40 000 samples are 2)
        moves = np.flatnonzero(np.r_[True, np.any(pose[1:] != pose[:-1], axis=1)])
        ok = reachable(pose[moves], geometry)
        if not ok.all():
            break
    else:
        return
    k = int(moves[np.argmin(ok)])
    t = t[k0:]
    try:
        check_reachable(pose[k], geometry)
        why = "outside the guide arc or stroke limits"
    except WorkspaceError as exc:
        why = str(exc)
    roll, pitch, heave = pose[k]
    raise SetpointError(
        f"unreachable set-point at setpoint (t = {t[k]:.3f} s: roll {math.degrees(roll):.2f} deg, "
        f"pitch {math.degrees(pitch):.2f} deg, heave {(heave - geometry.home[2]) * 1e3:+.1f} mm "
        f"from home): {why} (see simpro-sim workspace); or set "
        "controller.clamp_setpoints=true to clamp"
    )
