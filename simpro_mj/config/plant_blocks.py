"""The plant's blocks of the typed scenario: the actuators, the as-built plant, the sensors.

Each physical part owns its parameter record and its defaults
(:mod:`simpro_mj.plant.model_params`, :mod:`simpro_mj.plant.pneumatics.params`,
:mod:`simpro_mj.plant.sensors`); these blocks take them as their defaults and add
the as-built errors a scenario starts from, the ranges and the one-line
messages (:mod:`simpro_mj.config.rules`). :class:`simpro_mj.config.models.Scenario`
holds them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any

from pydantic import AfterValidator, BeforeValidator, Field

from simpro_mj.config.presets import DEFAULT_PRESET
from simpro_mj.config.rules import Block, Problem, below, number, one_of, rule
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import check_keys, value_text
from simpro_mj.plant.model_params import DEFAULT_MODEL_PARAMS, inertia_tensor
from simpro_mj.plant.pneumatics.params import ACTUATOR_KINDS as ACTUATOR_MODELS
from simpro_mj.plant.pneumatics.params import DEFAULT_PNEUMATIC_PARAMS, PneumaticParams
from simpro_mj.plant.sensors import DEFAULT_SENSORS, POT_BITS, POT_BITS_TEXT

__all__ = ["ACTUATOR_MODELS", "Actuator", "PlantBlock", "SensorsBlock", "check_pneumatics"]


def check_pneumatics(value: Any, path: str = "actuator.pneumatics") -> dict:
    """``actuator.pneumatics``: keys against the plant's tree, leaf types, then the
    plant's own range checks (run here so that a bad value is a load-time error)."""
    if not isinstance(value, Mapping):
        raise UserInputError(
            f"wrong type at {path}: got {type(value).__name__} {value_text(value)}; "
            "allowed: a mapping"
        )
    check_keys(value, DEFAULT_PNEUMATIC_PARAMS, path)
    try:
        out = _pneumatic_leaves(value, DEFAULT_PNEUMATIC_PARAMS)
    except Problem as p:
        raise UserInputError(f"{p.head} at {path}{p.suffix}{p.rest}") from None
    try:
        PneumaticParams.from_tree(out)
    except UserInputError as exc:
        # the plant names its own tree "pneumatics"; here it hangs under "actuator"
        raise UserInputError(str(exc).replace(" at pneumatics.", f" at {path}.")) from exc
    except (ValueError, TypeError, ArithmeticError) as exc:
        raise UserInputError(
            f"invalid value at {path}: {exc}; allowed: see simpro_mj.plant.pneumatics"
        ) from exc
    return out


def _pneumatic_leaves(value: Mapping, ref: Mapping) -> dict:
    """Leaf types of a pneumatics subtree; per-leg keys take a number or 3 numbers."""
    out: dict = {}
    for key, sub in value.items():
        default, here = ref[key], f".{key}"
        if isinstance(default, Mapping):
            out[key] = below(lambda v, d=default: _pneumatic_leaves(v, d), sub, here)
        elif isinstance(default, bool):
            if not isinstance(sub, bool):
                raise Problem.wrong_type(sub, "true or false", here)
            out[key] = sub
        elif isinstance(default, str):  # a choice: PneumaticParams checks the value
            if not isinstance(sub, str):
                raise Problem.wrong_type(sub, "a name", here)
            out[key] = sub
        elif (default is None or isinstance(default, list)) and isinstance(sub, (list, tuple)):
            if len(sub) != 3:
                raise Problem.wrong_type(sub, "a number or a list of 3 numbers (one per leg)", here)
            out[key] = [below(number, v, f"{here}[{i}]") for i, v in enumerate(sub)]
        elif default is None and sub is None:
            out[key] = None
        else:
            out[key] = below(number, sub, here)
    return out


class Actuator(Block):
    _path = "actuator"
    _own = frozenset({"pneumatics"})
    # nonlinear (Richer & Hurmuzlu) | linear (eq. 19)
    model: Annotated[str, one_of(ACTUATOR_MODELS)] = "nonlinear"
    #: overrides of simpro_mj.plant.pneumatics.DEFAULT_PNEUMATIC_PARAMS (only the keys given)
    pneumatics: Annotated[dict, BeforeValidator(check_pneumatics)] = Field(default_factory=dict)


# The as-built plant: the plant's own parameters (simpro_mj.plant.model_params,
# simpro_mj.plant.sensors) with as-built errors. The errors are assumptions chosen
# so that joint-only control shows a Fig. 15a-like steady-state error; the
# controller keeps the nominal geometry.
_MODEL = DEFAULT_MODEL_PARAMS
_SENSORS = DEFAULT_SENSORS


#: Heaviest payload (kg): three DNC-125 cylinders make at most 3 x 12.3 kN at their
#: rated 10 bar (about 3,750 kg); the preflight gives the limit at the scenario's supply.
MAX_PAYLOAD_KG = 5000.0
#: Farthest payload centre of mass from the platform frame's origin (mm, per axis): a
#: cabin on a platform about 1 m across, its seat 0.4 m above.
MAX_COM_MM = 2000.0
#: Largest as-built attachment or guide error (mm, per axis): the defaults are <= 4 mm;
#: beyond a few centimetres the closed chain no longer assembles at home.
MAX_OFFSET_MM = 50.0
#: Loop-constraint time constant (s): at least two physics steps (MuJoCo's own floor
#: for a stable constraint), at most 1 s (a loop that soft opens by centimetres).
LOOP_TIMECONST_RANGE_S = (0.002, 1.0)

_OFFSET = rule(
    lambda v: abs(v) <= MAX_OFFSET_MM,
    f"|offset| <= {MAX_OFFSET_MM:g} mm per axis (as-built errors: the defaults are <= 4 mm; "
    "beyond a few centimetres the closed chain does not assemble)",
)


def _in_plane(value: list) -> list:
    if len(value) == 3 and value[1] != 0:
        raise Problem.invalid(
            value,
            "[x, 0, z]: leg 1 (R-P-S-U) moves in the x-z plane, so its anchors A1 and C1 take "
            "x and z errors only (one across the plane cannot be assembled)",
        )
    return value


def _inertia_leaf(value: Any) -> list | None:
    """``plant.payload.inertia_kg_m2``: null or 6 numbers of a physical inertia tensor
    (the model's own check, :func:`simpro_mj.plant.model_params.inertia_tensor`)."""
    if value is None:
        return None
    if not isinstance(value, list | tuple) or len(value) != 6:
        raise Problem.wrong_type(
            value, "null or a list of 6 numbers [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]"
        )
    out = [below(number, v, f"[{i}]") for i, v in enumerate(value)]
    try:
        inertia_tensor(out)
    except UserInputError as exc:
        raise Problem.invalid(value, str(exc).split("; allowed: ", 1)[1]) from None
    return out


class Payload(Block):
    _path = "plant.payload"
    mass_kg: Annotated[
        float,
        rule(
            lambda v: 0 <= v <= MAX_PAYLOAD_KG,
            f"0 .. {MAX_PAYLOAD_KG:g} kg (three DNC-125 cylinders lift at most about 3,750 kg "
            "at 10 bar; the preflight gives the limit at the supply pressure)",
        ),
    ] = _MODEL["payload"]["mass_kg"]
    # as built: the plant's (0, 0, 400) mm moved 60 mm along x (assumption)
    com_mm: Annotated[
        list[float],
        rule(
            lambda v: abs(v) <= MAX_COM_MM,
            f"|x|, |y|, |z| <= {MAX_COM_MM:g} mm (a cabin on a platform about 1 m across)",
        ),
    ] = [60.0, 0.0, 400.0]
    # [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] about the centre of mass, kg m^2; null: the
    # MJCF's uniform box of the payload's mass (simpro_mj.plant.model_params)
    inertia_kg_m2: Annotated[list[float] | None, BeforeValidator(_inertia_leaf)] = _MODEL[
        "payload"
    ]["inertia_kg_m2"]
    # the payload mass inertia_kg_m2 belongs to; set, the inertia scales with mass_kg /
    # this (the same cabin, lighter or heavier: a sweep over the mass draws whole
    # cabins); null: inertia_kg_m2 as given at any mass
    inertia_mass_kg: Annotated[
        float | None, rule(lambda v: v is None or v > 0, "null or > 0 kg")
    ] = None


class AnchorOffsets(Block):
    """As-built offsets of the leg anchors (mm, assumption)."""

    _path = "plant.anchor_offsets_mm"
    A1: Annotated[list[float], _OFFSET, AfterValidator(_in_plane)] = [0.0, 0.0, 0.0]
    A2: Annotated[list[float], _OFFSET] = [3.0, 0.0, -2.0]
    A3: Annotated[list[float], _OFFSET] = [-2.0, 0.0, 2.5]
    C1: Annotated[list[float], _OFFSET, AfterValidator(_in_plane)] = [2.0, 0.0, 3.0]
    B2: Annotated[list[float], _OFFSET] = [-2.5, 0.0, 3.0]
    B3: Annotated[list[float], _OFFSET] = [2.0, 0.0, -1.5]


class Guide(Block):
    _path = "plant.guide"
    radius_offset_mm: Annotated[float, _OFFSET] = 4.0
    centre_offset_mm: Annotated[list[float], _OFFSET] = [3.0, -2.0]


class PlantBlock(Block):
    """The as-built plant (simpro_mj.plant.model_params) and its preset."""

    _path = "plant"
    payload: Payload = Field(default_factory=Payload)
    platform_mass_kg: Annotated[
        float,
        rule(lambda v: 1 <= v <= 2000, "1 .. 2000 kg (the moving frame: 120 kg as built)"),
    ] = _MODEL["platform_mass_kg"]
    anchor_offsets_mm: AnchorOffsets = Field(default_factory=AnchorOffsets)
    guide: Guide = Field(default_factory=Guide)
    loop_timeconst_s: Annotated[
        float,
        rule(
            lambda v: LOOP_TIMECONST_RANGE_S[0] <= v <= LOOP_TIMECONST_RANGE_S[1],
            f"{LOOP_TIMECONST_RANGE_S[0]:g} .. {LOOP_TIMECONST_RANGE_S[1]:g} s (at least two "
            "physics steps, MuJoCo's floor for a stable constraint; at most 1 s)",
        ),
    ] = _MODEL["loop_timeconst_s"]
    # a shipped preset ("paper", calibrated to eqs. 34-35; "heavy_cabin", 230 kg) or a
    # preset YAML path (`simpro-sim calibrate`); its plant, actuator.pneumatics and
    # controller.inner.identified values lie under the scenario's own
    # (simpro_mj.config.presets)
    preset: str = DEFAULT_PRESET


class Potentiometer(Block):
    """MF624 14-bit potentiometers with as-built calibration errors per leg (assumption)."""

    _path = "sensors.potentiometer"
    bits: Annotated[int, rule(lambda v: POT_BITS[0] <= v <= POT_BITS[1], POT_BITS_TEXT)] = _SENSORS[
        "potentiometer"
    ]["bits"]
    range_v: Annotated[float, rule(lambda v: v > 0, "> 0 V")] = _SENSORS["potentiometer"]["range_v"]
    volts_per_mm: Annotated[float, rule(lambda v: v > 0, "> 0 V/mm")] = _SENSORS["potentiometer"][
        "volts_per_mm"
    ]
    noise_lsb: Annotated[float, rule(lambda v: v >= 0, ">= 0 LSB")] = _SENSORS["potentiometer"][
        "noise_lsb"
    ]
    offset_mm: list[float] = [1.5, -1.0, 2.0]
    gain_error_pct: Annotated[list[float], rule(lambda v: v > -100, "3 numbers > -100 %")] = [
        0.8,
        -0.6,
        0.5,
    ]
    nonlinearity_pct_fs: Annotated[
        float, rule(lambda v: 0 <= v <= 5, "0 .. 5 % of full scale (conductive plastic: 0.05-0.1)")
    ] = _SENSORS["potentiometer"]["nonlinearity_pct_fs"]
    rate_ms: int = _SENSORS["potentiometer"]["rate_ms"]


class HeightEncoder(Block):
    """The 10 um height encoder."""

    _path = "sensors.height_encoder"
    resolution_mm: Annotated[float, rule(lambda v: v >= 0, ">= 0 mm (0: no quantisation)")] = (
        _SENSORS["height_encoder"]["resolution_mm"]
    )
    noise_mm: Annotated[float, rule(lambda v: v >= 0, ">= 0 mm")] = _SENSORS["height_encoder"][
        "noise_mm"
    ]
    rate_ms: int = _SENSORS["height_encoder"]["rate_ms"]


class Imu(Block):
    """The 200 Hz IMU."""

    _path = "sensors.imu"
    noise_deg: Annotated[float, rule(lambda v: v >= 0, ">= 0 deg")] = _SENSORS["imu"]["noise_deg"]
    noise_density_deg_per_sqrt_hz: Annotated[float, rule(lambda v: v >= 0, ">= 0 deg/sqrt(Hz)")] = (
        _SENSORS["imu"]["noise_density_deg_per_sqrt_hz"]
    )
    bias_deg: list[float] = list(_SENSORS["imu"]["bias_deg"])
    bias_walk_deg_per_sqrt_s: Annotated[float, rule(lambda v: v >= 0, ">= 0 deg/sqrt(s)")] = (
        _SENSORS["imu"]["bias_walk_deg_per_sqrt_s"]
    )
    # the attitude's complementary filter: the accelerometer's tilt below this
    # crossover, the gyro above (0: the gyro alone)
    accel_crossover_hz: Annotated[
        float, rule(lambda v: 0 <= v <= 500, "0 (gyro only) .. 500 Hz")
    ] = _SENSORS["imu"]["accel_crossover_hz"]
    bandwidth_hz: Annotated[float, rule(lambda v: v > 0, "> 0 Hz")] = _SENSORS["imu"][
        "bandwidth_hz"
    ]
    rate_ms: int = _SENSORS["imu"]["rate_ms"]


class SensorsBlock(Block):
    """simpro_mj.plant.sensors.DEFAULT_SENSORS with the as-built calibration errors."""

    _path = "sensors"
    potentiometer: Potentiometer = Field(default_factory=Potentiometer)
    height_encoder: HeightEncoder = Field(default_factory=HeightEncoder)
    imu: Imu = Field(default_factory=Imu)
