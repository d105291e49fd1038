"""Parameters of the plant model as plain data (no MuJoCo import).

:mod:`simpro_mj.config.scenario` validates a scenario's ``plant`` block against
:data:`DEFAULT_MODEL_PARAMS` without building a model, so loading (or
refusing) a scenario does not pay for importing MuJoCo;
:mod:`simpro_mj.plant.model` applies them to the MJCF.
"""

from __future__ import annotations

__all__ = ["LEG_POINTS", "BASE_POINTS", "DEFAULT_MODEL_PARAMS", "MAX_MODEL_PAYLOAD_KG"]

#: Largest payload the MJCF builder accepts (kg): far above what the cylinders hold
#: (the preflight refuses a payload with its limit first), below what makes the
#: compiled masses meaningless.
MAX_MODEL_PAYLOAD_KG = 1e5

LEG_POINTS = ("C1", "B2", "B3")  # moving attachment of legs 1..3
BASE_POINTS = ("A1", "A2", "A3")

#: Parameters of the plant model, edge units in the key names.
DEFAULT_MODEL_PARAMS: dict = {
    "payload": {
        # cabin, seat, screens and driver (assumption: Table 1 is lost)
        "mass_kg": 250.0,
        # centre of mass in the platform frame (origin P), mm
        "com_mm": [0.0, 0.0, 400.0],
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
