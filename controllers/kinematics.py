"""Inverse and forward kinematics of the SIMPRO platform (paper eqs. 3-14, 30-33).

The task-space pose is ``x = (roll theta, pitch phi, heave h)`` in rad, rad, m;
y and yaw are held at zero by the passive guide. Joint coordinates ``q`` are
the cylinder extensions from fully retracted (m). Every function is
vectorised over leading axes: a pose array of shape ``(..., 3)`` gives joint
arrays of shape ``(..., 3)``.

Vector-loop model (eqs. 3-13)
-----------------------------
Rotation (8), ZYX with zero yaw: ``R = Ry(phi) Rx(theta)``.
The U joint B1 lies on the guide circle (eq. 14, corrected):
``B1 = P + R PB1`` with ``(B1x - xc)^2 + (B1z - zc)^2 = r^2``, which fixes the
platform's x position ``Px`` (the curvilinear heave of Fig. 4). Then

* leg 1 (eq. 11): ``A1C1 = OP + R PB1 - OA1 + B1C2 + C2C1`` (bracket translates),
* legs 2, 3 (eqs. 12-13): ``AiBi = OP + R PBi - OAi``,

and ``q_i = |AiXi| - L0_i`` (eq. 15, lost in our copy).
"""

from __future__ import annotations

import numpy as np

from .errors import ConvergenceError, KinematicsError, WorkspaceError
from .geometry import PlatformGeometry, nominal_geometry

_NOMINAL = nominal_geometry()
AXIS_NAMES = ("roll", "pitch", "heave")


def _geom(geometry: PlatformGeometry | None) -> PlatformGeometry:
    return _NOMINAL if geometry is None else geometry


def rotation(roll, pitch) -> np.ndarray:
    """Rotation matrix of eq. (8): ``R = Ry(pitch) @ Rx(roll)``.

    Returns an array of shape ``(..., 3, 3)``.
    """
    roll = np.asarray(roll, dtype=float)
    pitch = np.asarray(pitch, dtype=float)
    ct, st = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    z = np.zeros_like(ct + cp)
    rows = [
        [cp + z, sp * st, sp * ct],
        [z, ct + z, -st + z],
        [-sp + z, cp * st, cp * ct],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def _rotation_derivatives(roll, pitch):
    """dR/droll and dR/dpitch of eq. (8)."""
    ct, st = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    z = np.zeros_like(ct + cp)
    d_roll = [[z, sp * ct, -sp * st], [z, -st + z, -ct + z], [z, cp * ct, -cp * st]]
    d_pitch = [[-sp + z, cp * st, cp * ct], [z, z, z], [-cp + z, -sp * st, -sp * ct]]
    return tuple(np.stack([np.stack(r, axis=-1) for r in m], axis=-2) for m in (d_roll, d_pitch))


def line_circle_intersection(m, b, xc, zc, r, side: int = -1):
    """x of the intersection of the line z = m x + b with a circle (eq. 14, corrected).

    Substituting the line into ``(x - xc)^2 + (z - zc)^2 = r^2`` gives
    ``(1 + m^2) x^2 + 2 [m (b - zc) - xc] x + k1 = 0`` with
    ``k1 = xc^2 + (b - zc)^2 - r^2``. The paper prints ``b(b + 2 zc)`` in k1,
    a sign typo (docs/paper-notes.md). ``side`` picks the root: -1 the
    smaller x, +1 the larger.

    Raises
    ------
    WorkspaceError
        If the line misses the circle (the guide cannot reach that height).
    """
    m = np.asarray(m, dtype=float)
    qa = 1.0 + m**2
    qb = 2.0 * (m * (b - zc) - xc)
    k1 = xc**2 + (b - zc) ** 2 - r**2
    disc = qb**2 - 4.0 * qa * k1
    if np.any(disc < 0):
        raise WorkspaceError(
            "pose unreachable: the guide arc (radius "
            f"{r:.4f} m about z = {zc:.4f} m) does not reach that height; "
            f"allowed heave keeps |z_B1 - z_c| <= r"
        )
    return (-qb + side * np.sqrt(disc)) / (2.0 * qa)


def platform_position(pose, geometry: PlatformGeometry | None = None):
    """Platform frame for a pose: position P (..., 3) and rotation R (..., 3, 3)."""
    g = _geom(geometry)
    pose = np.asarray(pose, dtype=float)
    roll, pitch, h = pose[..., 0], pose[..., 1], pose[..., 2]
    rot = rotation(roll, pitch)
    b1_off = rot @ g.platform_points[0]
    b1z = h + b1_off[..., 2]
    xc, zc = g.guide_centre
    # eq. (14) with the horizontal line z = b1z (m = 0): B1 on the guide circle.
    b1x = line_circle_intersection(0.0, b1z, xc, zc, g.guide_radius, g.guide_side)
    px = b1x - b1_off[..., 0]
    pos = np.stack([px, np.zeros_like(px), h], axis=-1)
    return pos, rot


def attachment_points(pose, geometry: PlatformGeometry | None = None) -> np.ndarray:
    """Moving attachment point of each leg, (..., 3 legs, 3): C1, B2, B3."""
    g = _geom(geometry)
    pos, rot = platform_position(pose, g)
    pb = np.einsum("...ij,kj->...ki", rot, g.platform_points) + pos[..., None, :]
    c1 = pb[..., 0, :] + g.bracket_c1  # eq. (11): bracket offsets not rotated
    return np.concatenate([c1[..., None, :], pb[..., 1:, :]], axis=-2)


def leg_lengths(pose, geometry: PlatformGeometry | None = None) -> np.ndarray:
    """Pin-to-pin leg lengths |A_i X_i| (..., 3), eqs. (11)-(13)."""
    g = _geom(geometry)
    return np.linalg.norm(attachment_points(pose, g) - g.base_points, axis=-1)


def check_reachable(pose, geometry: PlatformGeometry | None = None, margin: float = 0.0):
    """Raise :class:`WorkspaceError` naming the first limit a pose violates.

    ``margin`` (m) shrinks the stroke at both ends.
    """
    g = _geom(geometry)
    pose = np.asarray(pose, dtype=float)
    if not np.all(np.isfinite(pose)):
        raise WorkspaceError("pose unreachable: non-finite pose; allowed: finite roll, pitch, h")
    q = leg_lengths(pose, g) - g.retracted_length
    lo, hi = margin, g.stroke - margin
    for i in range(3):
        qi = q[..., i]
        if np.any(qi < lo - 1e-12) or np.any(qi > hi + 1e-12):
            bad = float(qi[qi < lo].min()) if np.any(qi < lo) else float(qi[qi > hi].max())
            raise WorkspaceError(
                f"pose unreachable: leg {i + 1} stroke q{i + 1} = {bad * 1e3:.1f} mm, "
                f"allowed {lo * 1e3:.1f}..{hi * 1e3:.1f} mm"
            )
    return q


def reachable(pose, geometry: PlatformGeometry | None = None, margin: float = 0.0) -> np.ndarray:
    """Boolean mask (...,) of poses inside the stroke limits and the guide arc."""
    g = _geom(geometry)
    pose = np.asarray(pose, dtype=float)
    roll, pitch, h = pose[..., 0], pose[..., 1], pose[..., 2]
    b1z = h + (rotation(roll, pitch) @ g.platform_points[0])[..., 2]
    ok = np.abs(b1z - g.guide_centre[1]) < g.guide_radius
    safe = np.where(ok[..., None], pose, g.home)
    q = leg_lengths(safe, g) - g.retracted_length
    ok &= np.all((q >= margin) & (q <= g.stroke - margin), axis=-1)
    return ok


def inverse_kinematics(
    pose, geometry: PlatformGeometry | None = None, check: bool = True
) -> np.ndarray:
    """Joint coordinates q (..., 3) for poses (..., 3) by the vector loops.

    Parameters
    ----------
    pose : array_like, (..., 3)
        (roll rad, pitch rad, heave m).
    geometry : PlatformGeometry, optional
        Defaults to :func:`nominal_geometry`.
    check : bool
        Raise :class:`WorkspaceError` when a leg leaves its stroke.
    """
    g = _geom(geometry)
    if check:
        return check_reachable(pose, g)
    return leg_lengths(pose, g) - g.retracted_length


def jacobian(pose, geometry: PlatformGeometry | None = None) -> np.ndarray:
    """IK Jacobian dq/dx (..., 3, 3), analytic; rows legs, columns (roll, pitch, h)."""
    g = _geom(geometry)
    pose = np.asarray(pose, dtype=float)
    roll, pitch, h = pose[..., 0], pose[..., 1], pose[..., 2]
    rot = rotation(roll, pitch)
    d_roll, d_pitch = _rotation_derivatives(roll, pitch)
    pb = g.platform_points
    b1_off = rot @ pb[0]
    d_b1_off = np.stack([d_roll @ pb[0], d_pitch @ pb[0], np.zeros_like(b1_off)], axis=-1)
    b1z = h + b1_off[..., 2]
    dz = b1z - g.guide_centre[1]
    s = np.sqrt(g.guide_radius**2 - dz**2)
    b1x = g.guide_centre[0] + g.guide_side * s
    d_b1z = d_b1_off[..., 2, :] + np.array([0.0, 0.0, 1.0])
    d_b1x = (g.guide_side * (-dz / s))[..., None] * d_b1z
    d_px = d_b1x - d_b1_off[..., 0, :]
    px = b1x - b1_off[..., 0]
    pos = np.stack([px, np.zeros_like(px), h], axis=-1)
    zeros = np.zeros_like(d_px)
    d_pos = np.stack([d_px, zeros, np.broadcast_to([0.0, 0.0, 1.0], d_px.shape)], axis=-2)
    jac = np.empty(pose.shape[:-1] + (3, 3))
    # leg 1: X1 = B1 + bracket offset (translation only)
    x1 = np.stack([b1x, np.zeros_like(b1x), b1z], axis=-1) + g.bracket_c1
    d_x1 = np.stack([d_b1x, zeros, d_b1z], axis=-2)
    u1 = (x1 - g.base_points[0]) / np.linalg.norm(x1 - g.base_points[0], axis=-1)[..., None]
    jac[..., 0, :] = np.einsum("...i,...ij->...j", u1, d_x1)
    for i in (1, 2):
        xi = pos + rot @ pb[i]
        d_xi = d_pos + np.stack([d_roll @ pb[i], d_pitch @ pb[i], np.zeros_like(xi)], axis=-1)
        ui = (xi - g.base_points[i]) / np.linalg.norm(xi - g.base_points[i], axis=-1)[..., None]
        jac[..., i, :] = np.einsum("...i,...ij->...j", ui, d_xi)
    return jac


def forward_kinematics(
    q,
    geometry: PlatformGeometry | None = None,
    initial_pose=None,
    tol: float = 1e-13,
    max_iter: int = 50,
) -> np.ndarray:
    """Pose (..., 3) for joint coordinates q (..., 3) by Newton iteration on the IK.

    Iterates ``x <- x - J(x)^-1 (IK(x) - q)`` from ``initial_pose`` (default:
    the home pose) until the joint residual is below ``tol`` (m).

    Raises
    ------
    WorkspaceError
        If q is outside the stroke.
    ConvergenceError
        If Newton does not converge in ``max_iter`` iterations (singular
        Jacobian or a pose outside the guide's reach).
    """
    g = _geom(geometry)
    q = np.asarray(q, dtype=float)
    if q.shape[-1] != 3:
        raise KinematicsError(f"q must have 3 components in its last axis, got shape {q.shape}")
    if np.any(q < -1e-12) or np.any(q > g.stroke + 1e-12):
        raise WorkspaceError(
            f"joint vector outside the stroke: q in [{q.min() * 1e3:.1f}, {q.max() * 1e3:.1f}] mm, "
            f"allowed 0..{g.stroke * 1e3:.1f} mm"
        )
    x = np.broadcast_to(g.home if initial_pose is None else initial_pose, q.shape).copy()
    res = np.inf
    for _ in range(max_iter):
        try:
            r = leg_lengths(x, g) - g.retracted_length - q
        except WorkspaceError as exc:
            raise ConvergenceError(f"forward kinematics left the guide's reach: {exc}") from exc
        res = np.max(np.abs(r)) if r.size else 0.0
        if res < tol:
            return x
        jac = jacobian(x, g)
        try:
            dx = np.linalg.solve(jac, r[..., None])[..., 0]
        except np.linalg.LinAlgError as exc:
            raise ConvergenceError("forward kinematics: singular IK Jacobian") from exc
        x = x - dx
    raise ConvergenceError(
        f"forward kinematics did not converge in {max_iter} iterations "
        f"(joint residual {res:.3e} m > tol {tol:.1e} m)"
    )


# --------------------------------------------------------------------------
# The paper's closed-form IK, eqs. (30)-(33), exactly as printed.
# --------------------------------------------------------------------------
def paper_leg_lengths(pose, h0: float = 1.265) -> np.ndarray:
    """Leg lengths (m) from eqs. (30)-(32) as printed.

    The printed h enters ``lambda_0 = sqrt(1672^2 - 1720 h - h^2)`` which is
    imaginary at h = 1265 mm, so the paper's h must be a heave measured from
    the initial elevation: we use ``h_paper = (h - h0)`` in mm. Angles in rad.
    Returns ``sqrt`` of the right-hand sides (the physical reading of L_i).
    """
    pose = np.asarray(pose, dtype=float)
    th, ph = pose[..., 0], pose[..., 1]
    h = (pose[..., 2] - h0) * 1e3
    arg = 1672.0**2 - 1720.0 * h - h**2
    if np.any(arg < 0):
        raise WorkspaceError("pose unreachable for eq. (30): 1672^2 - 1720 h - h^2 < 0")
    lam0 = np.sqrt(arg)
    lam1 = 500.0 * np.sin(th) * np.sin(ph)
    lam2 = 500.0 * np.cos(ph) - 500.0
    lam3 = 500.0 * np.sin(th) * np.cos(ph)
    lam4 = 720.0 * np.sin(ph) + 945.0 + h
    l1sq = (2076.0 - lam0 - 940.0 * np.cos(ph)) ** 2 + (740.0 + h + 940.0 * np.sin(ph)) ** 2
    l2sq = (1397.0 - lam0 + 720.0 * np.cos(ph) + lam1) ** 2 + lam2**2 + (lam3 - lam4) ** 2
    l3sq = (1397.0 - lam0 + 720.0 * np.cos(ph) - lam1) ** 2 + lam2**2 + (-lam3 - lam4) ** 2
    return np.sqrt(np.stack([l1sq, l2sq, l3sq], axis=-1)) * 1e-3


def paper_inverse_kinematics(pose, reading: str = "corrected", h0: float = 1.265):
    """Joint displacements from the paper's IK, eqs. (30)-(33).

    Parameters
    ----------
    pose : array_like (..., 3)
    reading : {"corrected", "printed"}
        ``"corrected"``: q_i = L_i - L0_i with L_i the leg length (sqrt of
        eqs. 30-32). ``"printed"``: eq. (33) verbatim, q_i = sqrt(L_i) - L0_i
        with L_i the leg length in mm, giving a displacement in sqrt(mm).
        In both, L0_i is the same formula's value at the home pose, so q is
        the displacement from the initial position (eq. 15 is lost).
    """
    if reading not in ("corrected", "printed"):
        raise KinematicsError(f"reading must be one of 'corrected', 'printed'; got {reading!r}")
    lengths = paper_leg_lengths(pose, h0)
    home = paper_leg_lengths(np.array([0.0, 0.0, h0]), h0)
    if reading == "corrected":
        return lengths - home
    # eq. (33) verbatim: sqrt of a length (mm) -> "sqrt(mm)", reported as such
    return np.sqrt(lengths * 1e3) - np.sqrt(home * 1e3)
