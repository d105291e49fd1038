"""Nominal geometry of the SIMPRO RPSU-2SPS platform (paper, section 5.2.1).

All values are SI (metres). The paper gives the points in millimetres at
the initial elevation h = 1265 mm, base frame z up, x pointing to the back
of the platform::

    A1 = [-180, 0, 0]     A2 = [180, -500, 0]   A3 = [180, 500, 0]
    B1 = [-840, 0, h]     B2 = [896, -500, h]   B3 = [896, 500, h]
    C1 = [-760, 0, h-210] C2 = [-840, 0, h-150]

Choices the paper leaves open (see docs/paper-notes.md):

* The platform reference point P (the task-space origin whose height is h)
  is at x = 0, y = 0 in the plane of the B_i points at the home pose, so
  PB_i = B_i - [0, 0, h].
* The C1-C2-B1 bracket translates without rotating (eq. 11 adds B1C2 and
  C2C1 without a rotation matrix). It is carried by the passive guide: a
  parallelogram of two links (the paper's "two additional rigid bodies",
  Fig. 4) pivoting on the base. Every bracket point therefore moves on a
  circle of the guide radius. The default radius and centre come from the
  lambda_0 term of eq. (30): sqrt(1672^2 - 1720 h - h^2) = sqrt(R^2 - (h+860)^2)
  with R = hypot(1672, 860) mm, i.e. B1 lies on a circle whose centre is
  860 mm below and 1672 mm behind B1 at the home pose.
* Leg i's slide coordinate q_i is the extension from fully retracted
  (0 <= q_i <= 0.5 m, the DNC-125-500 stroke); eq. (15) is lost, and we take
  the retracted pin-to-pin length L0_i so that the home pose is mid-stroke.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

#: The driver's head above the axes the cabin tilts about (m), the ``h`` of the
#: cueing laws' head model ``f = h a'' - g a`` (the jolt a tilt onset throws the head
#: with). Roll: the MJCF ``head`` site, 0.75 m above P (the least-squares fit of the
#: head's measured specific force on ``cue_lane_change`` gives 0.76 m). Pitch: 1.21 m,
#: measured: the RPSU moves the cabin along x as it pitches and heaves, and the fit
#: ``f_x + g sin(theta) = h theta'' + c z''`` on a ``cue_braking`` run gives h = 1.21 m,
#: c = -0.56 (residual 0.005 of 0.115 m/s^2 rms; docs/cueing.md). One source for the
#: classical washout and the MPC law.
HEAD_HEIGHT_ROLL = 0.75
HEAD_HEIGHT_PITCH = 1.21

#: Initial elevation of the platform (paper section 5.2.1), m.
H0 = 1265.0 * 1e-3

#: The paper's point list at h = H0, in millimetres, exactly as printed.
PAPER_POINTS_MM: dict[str, tuple[float, float, float]] = {
    "A1": (-180.0, 0.0, 0.0),
    "A2": (180.0, -500.0, 0.0),
    "A3": (180.0, 500.0, 0.0),
    "B1": (-840.0, 0.0, 1265.0),
    "B2": (896.0, -500.0, 1265.0),
    "B3": (896.0, 500.0, 1265.0),
    "C1": (-760.0, 0.0, 1265.0 - 210.0),
    "C2": (-840.0, 0.0, 1265.0 - 150.0),
}


#: The paper's rig as a rig record (millimetres, base frame, home pose): the keys of a
#: rig file (``simpro_mj.config.rig``), from which the MJCF (``simpro_mj.plant.model``)
#: and :func:`geometry_from_rig` both follow. ``guide_centre_from_b1_mm`` is (x, z) of
#: the guide arc's centre from B1: eq. (30)'s lambda_0 = sqrt(1672^2 - 1720 h - h^2)
#: = sqrt(R^2 - (h + 860)^2), a centre 1672 mm behind and 860 mm below B1.
PAPER_RIG_MM: dict = {
    "base_anchors_mm": {k: list(PAPER_POINTS_MM[k]) for k in ("A1", "A2", "A3")},
    "platform_anchors_mm": {k: list(PAPER_POINTS_MM[k]) for k in ("B1", "B2", "B3")},
    "bracket_mm": {k: list(PAPER_POINTS_MM[k]) for k in ("C1", "C2")},
    "guide_centre_from_b1_mm": [1672.0, -860.0],
    "stroke_mm": 500.0,
    "home_stroke_mm": 250.0,
}


def _m(points: dict, name: str) -> np.ndarray:
    return np.asarray(points[name], dtype=float) * 1e-3


@dataclass(frozen=True)
class PlatformGeometry:
    """Geometry of the platform as the kinematic model sees it (SI units).

    Attributes
    ----------
    base_points : (3, 3) array
        A_i, base attachment of leg i, in the base frame.
    platform_points : (3, 3) array
        PB_i, the B_i points in the platform frame (origin P).
    bracket_c1 : (3,) array
        B1C1, from the U-joint centre B1 to leg 1's attachment C1 (base-frame
        orientation: the bracket translates, eq. 11).
    bracket_c2 : (3,) array
        B1C2, from B1 to the lower guide link's joint C2.
    guide_centre : (2,) array
        (x_c, z_c) of the circle on which B1 moves (eq. 14).
    guide_radius : float
        r of that circle (upper guide link length).
    guide_side : int
        -1 if B1 lies at x < x_c (in front of the centre), +1 otherwise.
    retracted_length : (3,) array
        L0_i, pin-to-pin leg length at q_i = 0 (eq. 15).
    stroke : float
        Cylinder stroke, 0.5 m for the DNC-125-500.
    home : (3,) array
        Home pose (roll, pitch, heave) = (0, 0, H0).
    """

    base_points: np.ndarray
    platform_points: np.ndarray
    bracket_c1: np.ndarray
    bracket_c2: np.ndarray
    guide_centre: np.ndarray
    guide_radius: float
    guide_side: int = -1
    retracted_length: np.ndarray = field(default_factory=lambda: np.zeros(3))
    stroke: float = 0.5
    home: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, H0]))

    def replace(self, **changes) -> PlatformGeometry:
        """Return a copy with some fields changed (``dataclasses.replace``)."""
        return replace(self, **changes)


def nominal_geometry(home_stroke: float = 0.25) -> PlatformGeometry:
    """The nominal geometry of section 5.2.1 with our documented choices.

    Parameters
    ----------
    home_stroke : float
        Slide position q_i (m) of every leg at the home pose; sets L0_i.
        Default 0.25 m: mid-stroke, so the platform can move both ways.
    """
    return geometry_from_rig(PAPER_RIG_MM, home_stroke=home_stroke)


def geometry_from_rig(rig: dict | None, home_stroke: float | None = None) -> PlatformGeometry:
    """The geometry of a rig record (:data:`PAPER_RIG_MM`'s keys, millimetres).

    ``None`` is the paper's rig. The platform reference point P is at x = y = 0 at
    B1's height (h = B1_z); PB_i = B_i - P; the bracket offsets are C1 - B1 and
    C2 - B1; the guide's centre is B1 + ``guide_centre_from_b1_mm`` and its radius
    the distance from there to B1; L0_i = |A_i attach_i| - the home stroke (the
    attachment C1, B2, B3 at home). ``home_stroke`` (m) overrides the record's.
    """
    r = PAPER_RIG_MM if rig is None else rig
    base, plat, brk = r["base_anchors_mm"], r["platform_anchors_mm"], r["bracket_mm"]
    a = np.stack([_m(base, k) for k in ("A1", "A2", "A3")])
    b = np.stack([_m(plat, k) for k in ("B1", "B2", "B3")])
    h = b[0, 2]
    p_home = np.array([0.0, 0.0, h])  # P at x = 0 in B1's plane (our choice)
    c1, c2 = _m(brk, "C1"), _m(brk, "C2")
    dx, dz = (float(v) * 1e-3 for v in r["guide_centre_from_b1_mm"])
    centre = np.array([b[0, 0] + dx, b[0, 2] + dz])
    attach = np.stack([c1, b[1], b[2]])
    home_len = np.linalg.norm(attach - a, axis=1)
    q_home = float(r["home_stroke_mm"]) * 1e-3 if home_stroke is None else home_stroke
    return PlatformGeometry(
        base_points=a,
        platform_points=b - p_home,
        bracket_c1=c1 - b[0],
        bracket_c2=c2 - b[0],
        guide_centre=centre,
        guide_radius=float(np.hypot(dx, dz)),
        guide_side=-1 if b[0, 0] < centre[0] else 1,
        retracted_length=home_len - q_home,
        stroke=float(r["stroke_mm"]) * 1e-3,
        home=np.array([0.0, 0.0, h]),
    )
