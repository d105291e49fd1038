"""The plant's blocks of the typed scenario: the actuators, the as-built plant, the sensors.

Each physical part owns its parameter record and its defaults
(:mod:`simpro_mj.plant.model_params`, :mod:`simpro_mj.plant.pneumatics.params`,
:mod:`simpro_mj.plant.sensors`); these blocks take them as their defaults and add
the as-built errors a scenario starts from, the ranges and the one-line
messages (:mod:`simpro_mj.config.rules`). :class:`simpro_mj.config.models.Scenario`
holds them.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator, BeforeValidator, StrictStr

from controllers.geometry import PlatformGeometry, geometry_from_rig
from simpro_mj.config.presets import DEFAULT_PRESET
from simpro_mj.config.rig import Rig, rig_value
from simpro_mj.config.rules import Each, Numbers, Period
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import Block, Problem, Real, Whole, block, param
from simpro_mj.plant.model_params import DEFAULT_MODEL_PARAMS, inertia_tensor
from simpro_mj.plant.pneumatics.params import ActuatorKind, Pneumatics
from simpro_mj.plant.sensors import DEFAULT_SENSORS, POT_BITS, POT_BITS_TEXT


class Actuator(Block):
    """The valve + cylinder model of every leg and its parameters."""

    model: ActuatorKind = param("nonlinear", "", "nonlinear (Richer & Hurmuzlu) or linear (eq. 19)")
    pneumatics: Pneumatics = block(Pneumatics)


# The as-built plant: the plant's own parameters (simpro_mj.plant.model_params,
# simpro_mj.plant.sensors) with as-built errors. The errors are assumptions chosen
# so that joint-only control shows a Fig. 15a-like steady-state error; the
# controller keeps the nominal geometry.
_MODEL = DEFAULT_MODEL_PARAMS
_SENSORS = DEFAULT_SENSORS
_POT, _ENC, _IMU = _SENSORS["potentiometer"], _SENSORS["height_encoder"], _SENSORS["imu"]


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

_OFFSET_WHY = (
    "as-built error (assumption): the defaults are <= 4 mm; beyond a few centimetres the "
    "closed chain does not assemble"
)
Offset3 = Numbers[list[float], Each(3, ge=-MAX_OFFSET_MM, le=MAX_OFFSET_MM)]


def _in_plane(value: list) -> list:
    if value[1] != 0:
        raise Problem.invalid(
            value,
            "[x, 0, z]: leg 1 (R-P-S-U) moves in the x-z plane, so its anchors A1 and C1 take "
            "x and z errors only (one across the plane cannot be assembled)",
        )
    return value


def _inertia(value: list | None) -> list | None:
    """A physical inertia tensor (the model's own check,
    :func:`simpro_mj.plant.model_params.inertia_tensor`)."""
    if value is not None:
        try:
            inertia_tensor(value)
        except UserInputError as exc:
            raise Problem.invalid(value, str(exc).split("; allowed: ", 1)[1]) from None
    return value


class Payload(Block):
    """What the platform carries."""

    mass_kg: Real = param(
        _MODEL["payload"]["mass_kg"],
        "kg",
        "payload mass (three DNC-125 cylinders lift at most about 3,750 kg at 10 bar; "
        "the preflight gives the limit at the supply pressure)",
        ge=0,
        le=MAX_PAYLOAD_KG,
    )
    com_mm: Numbers[list[float], Each(3, ge=-MAX_COM_MM, le=MAX_COM_MM)] = param(
        [60.0, 0.0, 400.0],
        "mm",
        "payload centre of mass in the platform frame; as built: the plant's (0, 0, 400) "
        "moved 60 mm along x (assumption)",
    )
    inertia_kg_m2: Annotated[Numbers[list[float], Each(6)] | None, AfterValidator(_inertia)] = (
        param(
            _MODEL["payload"]["inertia_kg_m2"],
            "kg m^2",
            "[Ixx, Iyy, Izz, Ixy, Ixz, Iyz] about the centre of mass; null: the MJCF's uniform "
            "box of the payload's mass",
        )
    )
    inertia_mass_kg: Real | None = param(
        None,
        "kg",
        "the payload mass inertia_kg_m2 belongs to; set, the inertia scales with mass_kg / "
        "this (the same cabin, lighter or heavier); null: inertia_kg_m2 as given at any mass",
        gt=0,
    )


class AnchorOffsets(Block):
    """As-built offsets of the leg anchors (mm, assumption)."""

    A1: Annotated[Offset3, AfterValidator(_in_plane)] = param(
        [0.0, 0.0, 0.0], "mm", f"base anchor of leg 1, [x, 0, z]: {_OFFSET_WHY}"
    )
    A2: Offset3 = param([3.0, 0.0, -2.0], "mm", f"base anchor of leg 2: {_OFFSET_WHY}")
    A3: Offset3 = param([-2.0, 0.0, 2.5], "mm", f"base anchor of leg 3: {_OFFSET_WHY}")
    C1: Annotated[Offset3, AfterValidator(_in_plane)] = param(
        [2.0, 0.0, 3.0], "mm", f"platform joint of leg 1, [x, 0, z]: {_OFFSET_WHY}"
    )
    B2: Offset3 = param([-2.5, 0.0, 3.0], "mm", f"platform joint of leg 2: {_OFFSET_WHY}")
    B3: Offset3 = param([2.0, 0.0, -1.5], "mm", f"platform joint of leg 3: {_OFFSET_WHY}")


class Guide(Block):
    """As-built errors of the passive guide (mm, assumption)."""

    radius_offset_mm: Real = param(
        4.0, "mm", f"guide radius error: {_OFFSET_WHY}", ge=-MAX_OFFSET_MM, le=MAX_OFFSET_MM
    )
    centre_offset_mm: Numbers[list[float], Each(2, ge=-MAX_OFFSET_MM, le=MAX_OFFSET_MM)] = param(
        [3.0, -2.0], "mm", f"guide centre error: {_OFFSET_WHY}"
    )


class PlantBlock(Block):
    """The as-built plant (simpro_mj.plant.model_params) and its preset."""

    rig: Annotated[Rig | None, BeforeValidator(rig_value)] = param(
        None,
        "",
        "the platform's geometry: null (the paper's, section 5.2.1), a rig YAML file (beside "
        "the scenario, here, or a shipped one of scenarios/rigs) or its keys "
        "(simpro_mj.config.rig); the MJCF and the controllers' kinematics both follow it",
    )
    payload: Payload = block(Payload)
    platform_mass_kg: Real = param(
        _MODEL["platform_mass_kg"], "kg", "the moving frame (120 kg as built)", ge=1, le=2000
    )
    anchor_offsets_mm: AnchorOffsets = block(AnchorOffsets)
    guide: Guide = block(Guide)
    loop_timeconst_s: Real = param(
        _MODEL["loop_timeconst_s"],
        "s",
        "loop-closure constraint time constant (at least two physics steps, MuJoCo's floor "
        "for a stable constraint; at most 1 s)",
        ge=LOOP_TIMECONST_RANGE_S[0],
        le=LOOP_TIMECONST_RANGE_S[1],
    )
    preset: StrictStr = param(
        DEFAULT_PRESET,
        "",
        "a shipped preset (paper: calibrated to eqs. 34-35; heavy_cabin: 230 kg) or a preset "
        "YAML path; its plant, pneumatics and identified models lie under the scenario's own",
    )

    def rig_tree(self) -> dict | None:
        """The rig's record (millimetres; ``None``: the paper's rig)."""
        return None if self.rig is None else self.rig.model_dump()

    def geometry(self) -> PlatformGeometry:
        """The controllers' nominal geometry of this rig (:func:`geometry_from_rig`)."""
        return geometry_from_rig(self.rig_tree())

    def tree(self, *, empty: bool = False) -> dict:
        """The parameter tree :func:`simpro_mj.plant.model.load_model` compiles;
        ``empty``: with no payload mass (the preflight's static solves set it)."""
        out = self.model_dump()
        if empty:
            out["payload"]["mass_kg"] = 0.0
        return out


def _pot_bits(value: int) -> int:
    if not POT_BITS[0] <= value <= POT_BITS[1]:
        raise Problem.invalid(value, POT_BITS_TEXT)
    return value


class Potentiometer(Block):
    """MF624 14-bit potentiometers with as-built calibration errors per leg (assumption)."""

    # the plant's own range and words (one statement: plant.sensors)
    bits: Annotated[Whole, AfterValidator(_pot_bits)] = param(
        _POT["bits"], "bit", "ADC resolution", note=POT_BITS_TEXT
    )
    range_v: Real = param(_POT["range_v"], "V", "ADC input range", gt=0)
    volts_per_mm: Real = param(_POT["volts_per_mm"], "V/mm", "potentiometer gain", gt=0)
    noise_lsb: Real = param(_POT["noise_lsb"], "LSB", "noise per sample", ge=0)
    offset_mm: Numbers[list[float], Each(3)] = param(
        [1.5, -1.0, 2.0], "mm", "calibration offset per leg"
    )
    gain_error_pct: Numbers[list[float], Each(3, gt=-100)] = param(
        [0.8, -0.6, 0.5], "%", "calibration gain error per leg"
    )
    nonlinearity_pct_fs: Real = param(
        _POT["nonlinearity_pct_fs"],
        "% of full scale",
        "independent linearity (conductive plastic: 0.05-0.1)",
        ge=0,
        le=5,
    )
    rate_ms: Period = param(_POT["rate_ms"], "ms", "sampling period")


class HeightEncoder(Block):
    """The 10 um height encoder."""

    resolution_mm: Real = param(_ENC["resolution_mm"], "mm", "quantisation (0: none)", ge=0)
    noise_mm: Real = param(_ENC["noise_mm"], "mm", "noise per sample", ge=0)
    rate_ms: Period = param(_ENC["rate_ms"], "ms", "sampling period")


class Imu(Block):
    """The 200 Hz IMU."""

    noise_deg: Real = param(_IMU["noise_deg"], "deg", "white noise per sample", ge=0)
    noise_density_deg_per_sqrt_hz: Real = param(
        _IMU["noise_density_deg_per_sqrt_hz"], "deg/sqrt(Hz)", "attitude noise density", ge=0
    )
    bias_deg: Numbers[list[float], Each(2)] = param(
        list(_IMU["bias_deg"]), "deg", "bias (roll, pitch)"
    )
    bias_walk_deg_per_sqrt_s: Real = param(
        _IMU["bias_walk_deg_per_sqrt_s"], "deg/sqrt(s)", "bias random walk", ge=0
    )
    accel_crossover_hz: Real = param(
        _IMU["accel_crossover_hz"],
        "Hz",
        "the attitude's complementary filter: the accelerometer's tilt below this crossover, "
        "the gyro above (0: the gyro alone)",
        ge=0,
        le=500,
    )
    bandwidth_hz: Real = param(_IMU["bandwidth_hz"], "Hz", "attitude filter bandwidth", gt=0)
    rate_ms: Period = param(_IMU["rate_ms"], "ms", "sampling period")


class SensorsBlock(Block):
    """simpro_mj.plant.sensors.DEFAULT_SENSORS with the as-built calibration errors."""

    potentiometer: Potentiometer = block(Potentiometer)
    height_encoder: HeightEncoder = block(HeightEncoder)
    imu: Imu = block(Imu)
