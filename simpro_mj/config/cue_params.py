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

#: A YAML key's unit (its suffix) -> the factor from that unit to SI; a key without
#: one of these suffixes is the field's name, unitless.
UNITS = {
    "_ms": 1e-3,
    "_deg_s2": math.pi / 180.0,
    "_deg_s": math.pi / 180.0,
    "_deg": math.pi / 180.0,
    "_mm_s": 1e-3,
    "_mm": 1e-3,
    "_rad_s": 1.0,
    "_mps2": 1.0,
    "_m": 1.0,
    "_s": 1.0,
}


def _fields(keys: str) -> dict[str, tuple[str, float]]:
    """YAML key -> (field, factor from the YAML unit to SI): the field's name is the
    key less its unit (:data:`UNITS`)."""
    out = {}
    for key in keys.split():
        unit = next((u for u in UNITS if key.endswith(u)), "")
        out[key] = (key[: len(key) - len(unit)], UNITS.get(unit, 1.0))
    return out


#: YAML key -> (WashoutParams field, factor from the YAML unit to SI).
PARAMETER_KEYS = _fields(
    "period_ms gain_x gain_y gain_z gain_rot tilt_omega_rad_s tilt_zeta tilt_rate_limit_deg_s "
    "tilt_limit_deg tilt_accel_limit_deg_s2 head_height_m head_height_pitch_m jolt_limit_mps2 "
    "heave_omega_rad_s heave_zeta heave_omega_b_rad_s rot_order rot_omega_rad_s rot_zeta "
    "heave_fraction stroke_margin_mm knee"
)
#: YAML key -> (MpcParams field, factor from the YAML unit to SI), ``algorithm: mpc``.
MPC_PARAMETER_KEYS = _fields(
    "period_ms horizon gain_x gain_y gain_z gain_rot weight_f weight_raw weight_w weight_tilt "
    "weight_jerk tilt_rate_max_deg_s tilt_accel_max_deg_s2 heave_rate_max_mm_s "
    "heave_accel_max_mps2 head_height_m head_height_pitch_m preview_s heave_fraction "
    "stroke_margin_mm box_fraction rotation_limit rotation_limit_pitch lead_s lead_x_s "
    "loop_omega_rad_s loop_zeta loop_zero_s loop_delay_s loop_filter_s knee_mps2 "
    "jolt_limit_mps2 heave_washout_rad_s weight_heave weight_heave_rate gain_y_sustained "
    "sustained_tau_s"
)
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
