"""Frames of the motion-cueing chain, stated once.

Vehicle frame V (ISO 8855)
    x forward, y left, z up; origin at the driver's head. Vehicle telemetry,
    the cueing algorithm's input and every perceived quantity are in V.
    Specific force ``f = a - g`` (m/s^2): at rest ``f = (0, 0, +9.81)``.
    Braking gives ``f_x < 0``: the belt pushes the driver backwards, the
    driver feels pressed forwards into it. A left turn gives ``f_y > 0``: the
    seat pushes the driver to the left, the driver feels pressed to the right.
    ISO angles: roll about +x (positive: right side down), pitch about +y
    (positive: nose down).

Base frame B (paper section 2.1, :mod:`controllers.geometry`)
    x pointing to the **back** of the platform, z up, hence y to the
    driver's **right** (right-handed). The MJCF world frame is B. The
    platform pose is ``(roll, pitch, h)`` with ``R = Ry(pitch) Rx(roll)``
    (eq. 8, :func:`controllers.kinematics.rotation`): positive pitch lowers
    the rear (the paper's own rotation), i.e. lifts the nose.

Cabin/head frame H
    Fixed to the platform at the driver's head, axes those of V when the
    platform is at home: H is the platform frame turned by 180 deg about z.

Going between V and B is the rotation by pi about z, ``T = diag(-1, -1, 1)``
(its own inverse). Conjugating eq. (8) with it flips both angles:
``T Ry(p) Rx(r) T = Ry(-p) Rx(-r)``, so ``roll_iso = -roll_base`` and
``pitch_iso = -pitch_base``; heave is the same in both.
"""

from __future__ import annotations

import numpy as np

from .geometry import H0

#: Standard gravity (m/s^2), ISO 80000-3; the cueing's tilt coordination divides by it.
GRAVITY = 9.80665

#: Vector in B -> vector in V (and back): rotation by pi about z.
T_VB = np.diag([-1.0, -1.0, 1.0])


def base_to_vehicle(v) -> np.ndarray:
    """A vector (..., 3) given in base (or platform) axes, in vehicle (ISO 8855) axes."""
    v = np.asarray(v, dtype=float)
    return v * np.array([-1.0, -1.0, 1.0])


def pose_iso_to_base(roll_iso, pitch_iso, heave, h0: float = H0) -> np.ndarray:
    """Cabin attitude in ISO angles and heave from home -> platform pose (roll, pitch, h) in B.

    ``heave`` (m) is the displacement from the home height ``h0``; the result
    is ``(-roll_iso, -pitch_iso, h0 + heave)`` with a trailing axis of 3.
    """
    roll_iso, pitch_iso, heave = np.broadcast_arrays(
        np.asarray(roll_iso, float), np.asarray(pitch_iso, float), np.asarray(heave, float)
    )
    return np.stack([-roll_iso, -pitch_iso, h0 + heave], axis=-1)


def pose_base_to_iso(pose, h0: float = H0) -> np.ndarray:
    """Inverse of :func:`pose_iso_to_base`: (..., 3) -> (roll_iso, pitch_iso, heave from home)."""
    pose = np.asarray(pose, dtype=float)
    return np.stack([-pose[..., 0], -pose[..., 1], pose[..., 2] - h0], axis=-1)


def static_specific_force(roll_base, pitch_base, g: float = GRAVITY) -> np.ndarray:
    """Specific force at rest on a platform held at (roll, pitch), in head axes H (ISO).

    ``f_H = T R^T (0, 0, g)`` with ``R`` of eq. (8): what tilt coordination
    shows the otoliths in the steady state.
    """
    from .kinematics import rotation  # local: kinematics is heavier than this module

    rot = rotation(roll_base, pitch_base)
    f_platform = np.einsum("...ji,j->...i", rot, np.array([0.0, 0.0, g]))
    return base_to_vehicle(f_platform)
