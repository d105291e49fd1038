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
from controllers.geometry import geometry_from_rig
from controllers.kinematics import check_reachable, reachable
from simpro_mj.config.cueing import cue_poses
from simpro_mj.config.rules import PHYSICS_DT_S, SETPOINT_AXES
from simpro_mj.core.errors import UserInputError

__all__ = ["SetpointError", "reference", "check_setpoints", "late_setpoints"]


class SetpointError(UserInputError, WorkspaceError):
    """A set-point outside the reachable workspace.

    Both a :class:`~simpro_mj.core.errors.UserInputError` (the user's scenario is
    wrong) and a :class:`~controllers.errors.WorkspaceError` (the message of
    :func:`controllers.kinematics.check_reachable` names the limit).
    """


def late_setpoints(s: Mapping) -> list[str]:
    """Set-point components that start after the run ends: they never act.

    Not an error (a short run of a shipped scenario cuts its steps off on
    purpose), but never silent: :func:`simpro_mj.analysis.preflight.preflight` turns
    each into a warning line, recorded in ``metrics.json``.
    """
    duration = s["duration_s"]
    out = []
    for axis in SETPOINT_AXES:  # not setpoint.cueing, which has no components
        for i, c in enumerate(s["setpoint"].get(axis) or ()):
            key = {"step": "time_s", "ramp": "start_s", "sine": "start_s"}.get(c["type"])
            if key is not None and c[key] > duration:
                out.append(
                    f"setpoint.{axis}[{i}].{key} = {c[key]:g} s is after the end of the run "
                    f"(duration_s = {duration:g} s): this {c['type']} never acts"
                )
    return out


# ------------------------------------------------------------------ set-points


def _component(c: Mapping, t: np.ndarray) -> np.ndarray:
    kind = c["type"]
    if kind == "step":
        return np.where(t >= c["time_s"], c["value"], 0.0)
    if kind == "ramp":
        frac = np.clip((t - c["start_s"]) / (c["end_s"] - c["start_s"]), 0.0, 1.0)
        return c["value"] * frac
    if kind == "sine":
        start = c.get("start_s", 0.0)
        end = math.inf if c.get("end_s") is None else c["end_s"]
        phase = math.radians(c.get("phase_deg", 0.0))
        wave = c["amplitude"] * np.sin(2.0 * np.pi * (t - start) / c["period_s"] + phase)
        return np.where((t >= start) & (t < end), wave, 0.0)
    if kind == "table":
        return np.interp(t, np.asarray(c["times_s"], float), np.asarray(c["values"], float))
    raise UserInputError(f"invalid value at setpoint: component type {kind!r}")  # pragma: no cover


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


def reference(scenario: Mapping, t, *, clamp: bool | None = None) -> np.ndarray:
    """The set-point pose at times ``t``, SI, vectorised.

    Parameters
    ----------
    scenario : mapping
        A resolved scenario (:func:`load_scenario`).
    t : array_like, (n,)
        Times (s).
    clamp : bool, optional
        Pull unreachable poses back to the workspace boundary along the segment
        from the home pose (40 bisection steps on the nominal geometry).
        Default: ``scenario["controller"]["clamp_setpoints"]``.

    Returns
    -------
    ndarray, (n, 3)
        (roll rad, pitch rad, heave m); heave absolute, home height + ``heave_mm``.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    geometry = geometry_from_rig(scenario["plant"].get("rig"))
    sp = scenario["setpoint"]
    if sp.get("cueing"):  # the washout's set-points, inside its workspace box
        return cue_poses(scenario, t)
    out = np.empty((t.size, 3))
    for j, (axis, scale) in enumerate(
        zip(SETPOINT_AXES, (math.pi / 180.0, math.pi / 180.0, 1e-3), strict=True)
    ):
        total = np.zeros(t.size)
        for c in sp.get(axis) or ():
            total += _component(c, t)
        out[:, j] = geometry.home[j] + scale * total
    if clamp is None:
        clamp = bool(scenario["controller"]["clamp_setpoints"])
    if clamp:
        out = _clamp(out, geometry)
    return out


#: Poses per block of :func:`check_setpoints` (memory bound, not a result).
_CHECK_BLOCK = 20_000


def check_setpoints(scenario: Mapping, t=None) -> None:
    """Raise :class:`SetpointError` if the set-point leaves the reachable workspace.

    Parameters
    ----------
    scenario : mapping
        A resolved scenario.
    t : array_like, optional
        Times to check; default the 1 ms physics grid over ``[0, duration_s]``
        (every sample the controllers can see).
    """
    if t is None:
        n = int(round(scenario["duration_s"] / PHYSICS_DT_S))
        t = np.arange(n + 1) * PHYSICS_DT_S
    t = np.atleast_1d(np.asarray(t, dtype=float))
    geometry = geometry_from_rig(scenario["plant"].get("rig"))
    # in blocks: the vectorised IK holds ~350 B of temporaries per pose, which
    # over a whole 600 s grid would be 200 MB for a check that keeps nothing
    for k0 in range(0, t.size, _CHECK_BLOCK):
        pose = reference(scenario, t[k0 : k0 + _CHECK_BLOCK], clamp=False)
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
