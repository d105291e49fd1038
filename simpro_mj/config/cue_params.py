"""The motion-cueing laws' parameters as a scenario writes them.

``setpoint.cueing.parameters`` holds the washout's (:class:`controllers.washout.WashoutParams`)
or the MPC's (:class:`controllers.cue_mpc_params.MpcParams`) parameters in YAML units:
:data:`PARAMETER_KEYS` and :data:`MPC_PARAMETER_KEYS` map each key to the law's field
and the factor to SI, :func:`washout_params` builds the law's parameters from a block.
The synthetic inputs' channels (:data:`SINE_CHANNELS`) and the generated manoeuvres'
spec (:func:`manoeuvre_spec`) are here too: what the block's models
(:mod:`simpro_mj.config.cue_models`) check and the cueing chain
(:mod:`simpro_mj.config.cueing`) runs.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from controllers.cue_mpc_params import MpcParams
from controllers.washout import WashoutParams

if TYPE_CHECKING:
    from simpro_mj.config.cue_models import Cueing, CueManoeuvre

__all__ = [
    "ALGORITHMS",
    "INTEGERS",
    "MPC_PARAMETER_KEYS",
    "PARAMETER_KEYS",
    "SINE_CHANNELS",
    "default_parameters",
    "manoeuvre_spec",
    "parameter_keys",
    "washout_params",
]

#: The motion-cueing laws (``setpoint.cueing.algorithm``).
ALGORITHMS = ("classical_washout", "mpc")
#: Channels a ``sine`` vehicle input may drive (telemetry column names, SI) and their
#: largest amplitude: 1 g of specific force, 90 deg/s.
SINE_CHANNELS = {
    "fx_mps2": 9.80665,
    "fy_mps2": 9.80665,
    "fz_mps2": 9.80665,
    "wx_rad_s": math.pi / 2,
    "wy_rad_s": math.pi / 2,
}

#: YAML key -> (WashoutParams field, factor from the YAML unit to SI).
PARAMETER_KEYS = {
    "period_ms": ("period", 1e-3),
    "gain_x": ("gain_x", 1.0),
    "gain_y": ("gain_y", 1.0),
    "gain_z": ("gain_z", 1.0),
    "gain_rot": ("gain_rot", 1.0),
    "tilt_omega_rad_s": ("tilt_omega", 1.0),
    "tilt_zeta": ("tilt_zeta", 1.0),
    "tilt_rate_limit_deg_s": ("tilt_rate_limit", math.pi / 180.0),
    "tilt_limit_deg": ("tilt_limit", math.pi / 180.0),
    "tilt_accel_limit_deg_s2": ("tilt_accel_limit", math.pi / 180.0),
    "head_height_m": ("head_height", 1.0),
    "head_height_pitch_m": ("head_height_pitch", 1.0),
    "jolt_limit_mps2": ("jolt_limit", 1.0),
    "heave_omega_rad_s": ("heave_omega", 1.0),
    "heave_zeta": ("heave_zeta", 1.0),
    "heave_omega_b_rad_s": ("heave_omega_b", 1.0),
    "rot_order": ("rot_order", 1.0),
    "rot_omega_rad_s": ("rot_omega", 1.0),
    "rot_zeta": ("rot_zeta", 1.0),
    "heave_fraction": ("heave_fraction", 1.0),
    "stroke_margin_mm": ("stroke_margin", 1e-3),
    "knee": ("knee", 1.0),
}


#: YAML key -> (MpcParams field, factor from the YAML unit to SI), ``algorithm: mpc``.
MPC_PARAMETER_KEYS = {
    "period_ms": ("period", 1e-3),
    "horizon": ("horizon", 1.0),
    "gain_x": ("gain_x", 1.0),
    "gain_y": ("gain_y", 1.0),
    "gain_z": ("gain_z", 1.0),
    "gain_rot": ("gain_rot", 1.0),
    "weight_f": ("weight_f", 1.0),
    "weight_raw": ("weight_raw", 1.0),
    "weight_w": ("weight_w", 1.0),
    "weight_tilt": ("weight_tilt", 1.0),
    "weight_jerk": ("weight_jerk", 1.0),
    "tilt_rate_max_deg_s": ("tilt_rate_max", math.pi / 180.0),
    "tilt_accel_max_deg_s2": ("tilt_accel_max", math.pi / 180.0),
    "heave_rate_max_mm_s": ("heave_rate_max", 1e-3),
    "heave_accel_max_mps2": ("heave_accel_max", 1.0),
    "head_height_m": ("head_height", 1.0),
    "head_height_pitch_m": ("head_height_pitch", 1.0),
    "preview_s": ("preview", 1.0),
    "heave_fraction": ("heave_fraction", 1.0),
    "stroke_margin_mm": ("stroke_margin", 1e-3),
    "box_fraction": ("box_fraction", 1.0),
    "rotation_limit": ("rotation_limit", 1.0),
    "rotation_limit_pitch": ("rotation_limit_pitch", 1.0),
    "lead_s": ("lead", 1.0),
    "lead_x_s": ("lead_x", 1.0),
    "loop_omega_rad_s": ("loop_omega", 1.0),
    "loop_zeta": ("loop_zeta", 1.0),
    "loop_zero_s": ("loop_zero", 1.0),
    "loop_delay_s": ("loop_delay", 1.0),
    "loop_filter_s": ("loop_filter", 1.0),
    "knee_mps2": ("knee", 1.0),
    "jolt_limit_mps2": ("jolt_limit", 1.0),
    "heave_washout_rad_s": ("heave_washout", 1.0),
    "weight_heave": ("weight_heave", 1.0),
    "weight_heave_rate": ("weight_heave_rate", 1.0),
    "gain_y_sustained": ("gain_y_sustained", 1.0),
    "sustained_tau_s": ("sustained_tau", 1.0),
}
#: Whole-number parameters (an int in the resolved scenario).
INTEGERS = ("rot_order", "horizon")


def parameter_keys(algorithm: str = "classical_washout") -> dict:
    """The YAML key -> (field, factor) table of ``algorithm``."""
    return MPC_PARAMETER_KEYS if algorithm == "mpc" else PARAMETER_KEYS


def default_parameters(algorithm: str = "classical_washout") -> dict:
    """The law's defaults (:class:`WashoutParams`, :class:`MpcParams`) as ``parameters``
    (YAML units).

    ``rot_order`` and ``horizon`` ints, the others floats rounded to 12 digits (so
    that a default reads as ``3.0`` deg/s, not ``3.0000000000000004``).
    """
    p = MpcParams() if algorithm == "mpc" else WashoutParams()
    out = {}
    for key, (name, factor) in parameter_keys(algorithm).items():
        v = getattr(p, name) / factor
        out[key] = int(round(v)) if name in INTEGERS else float(round(v, 12))
    return out


def washout_params(cue: Cueing | Mapping) -> WashoutParams | MpcParams:
    """:class:`WashoutParams` (or :class:`MpcParams` for ``algorithm: mpc``) from a
    resolved block's ``parameters`` (YAML units), typed or its dict."""
    if isinstance(cue, Mapping):
        algorithm, given = cue.get("algorithm", "classical_washout"), cue["parameters"]
    else:
        algorithm, given = cue.algorithm, cue.parameters.model_dump()
    keys = parameter_keys(algorithm)
    kw: dict[str, Any] = {}
    for key, v in given.items():
        name, factor = keys[key]
        if name in INTEGERS:  # a whole number as int; 1.5 stays 1.5 and is refused
            kw[name] = int(v) if float(v).is_integer() else float(v)
        else:
            kw[name] = float(v) * factor
    return MpcParams(**kw) if algorithm == "mpc" else WashoutParams(**kw)


def manoeuvre_spec(man: CueManoeuvre):
    """The :class:`~simpro_mj.config.manoeuvres.ManoeuvreSpec` of a ``manoeuvre`` block."""
    # imported on use: manoeuvres loads scipy.signal and scipy.integrate (about 1.5 s),
    # which only a scenario with a manoeuvre needs
    from simpro_mj.config.manoeuvres import ManoeuvreSpec

    assert man.type is not None  # required (CueManoeuvre)
    # the block's keys are the spec's fields, ``type`` its ``manoeuvre``
    # (its values as given: a refused one is checked by the spec, never serialised)
    return ManoeuvreSpec(manoeuvre=man.type, **{k: v for k, v in man if k != "type"})
