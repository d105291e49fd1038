"""Parameters of the plant model as plain data (no MuJoCo import).

:mod:`simpro_mj.config.scenario` validates a scenario's ``plant`` block against
:data:`DEFAULT_MODEL_PARAMS` without building a model, so loading (or
refusing) a scenario does not pay for importing MuJoCo;
:mod:`simpro_mj.plant.model` applies them to the MJCF.
"""

from __future__ import annotations

import math

import numpy as np

from simpro_mj.core.errors import UserInputError

#: Largest payload the MJCF builder accepts (kg): far above what the cylinders hold
#: (the preflight refuses a payload with its limit first), below what makes the
#: compiled masses meaningless.
MAX_MODEL_PAYLOAD_KG = 1e5

LEG_POINTS = ("C1", "B2", "B3")  # moving attachment of legs 1..3
BASE_POINTS = ("A1", "A2", "A3")

#: Parameters of the plant model, edge units in the key names.
DEFAULT_MODEL_PARAMS: dict = {
    # the platform's geometry as a rig record (millimetres; simpro_mj.config.rig reads
    # and checks a rig file): null, the MJCF as shipped (the paper's section 5.2.1);
    # given, the MJCF's points, guide, legs and stroke rebuilt from it
    "rig": None,
    "payload": {
        # cabin, seat, screens and driver (assumption: Table 1 is lost)
        "mass_kg": 250.0,
        # centre of mass in the platform frame (origin P), mm
        "com_mm": [0.0, 0.0, 400.0],
        # inertia about the centre of mass in the platform frame's axes, kg m^2:
        # [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (MuJoCo's fullinertia order). null: a
        # uniform 1.4 m x 0.9 m x 0.8 m box of the payload's mass (the MJCF's geom)
        "inertia_kg_m2": None,
        # the mass inertia_kg_m2 was given for, kg: set, the inertia scales with
        # mass_kg / inertia_mass_kg (the same body, lighter or heavier); null: as given
        "inertia_mass_kg": None,
    },
    "platform_mass_kg": 120.0,
    # as-built errors of the attachment points, mm, added to the nominal ones
    "anchor_offsets_mm": {k: [0.0, 0.0, 0.0] for k in BASE_POINTS + LEG_POINTS},
    "guide": {
        # error of the guide links' length (both links of the parallelogram), mm
        "radius_offset_mm": 0.0,
        # error of the pivots' position (x, z), mm
        "centre_offset_mm": [0.0, 0.0],
    },
    # loop-closure constraint time constant (MuJoCo solref[0]); >= 2 timesteps
    "loop_timeconst_s": 0.002,
}


def inertia_tensor(value) -> list[float]:
    """``payload.inertia_kg_m2`` checked: 6 finite numbers [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]
    (kg m^2) of a physical inertia tensor: positive definite, its principal moments
    obeying the triangle inequality. Raises ``UserInputError`` naming the key."""
    ok = isinstance(value, list | tuple) and len(value) == 6
    ok = ok and all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
    )
    if ok:
        ixx, iyy, izz, ixy, ixz, iyz = (float(v) for v in value)
        m = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        e = np.linalg.eigvalsh(m)
        ok = bool(e[0] > 0 and e[0] + e[1] >= e[2] * (1 - 1e-9))
    if not ok:
        raise UserInputError(
            f"invalid value at model.payload.inertia_kg_m2: {value!r}; allowed: null or "
            "[Ixx, Iyy, Izz, Ixy, Ixz, Iyz] kg m^2 about the centre of mass, positive "
            "definite, its principal moments obeying the triangle inequality"
        )
    return [float(v) for v in value]
