"""Typed scenario models (pydantic v2): one model per block, validated once at the edge.

:func:`simpro_mj.config.scenario.load_scenario` merges a file and its ``--set``
overrides over :data:`~simpro_mj.config.defaults.DEFAULT_SCENARIO` (the one
source of every default and of every leaf's type, :class:`~simpro_mj.config.rules.Block`),
then validates the merged tree with :class:`Scenario`. The models add what
the defaults cannot say: ranges, enumerations (one tuple each, imported from
the module that uses it: ``controllers``, ``simpro_mj.plant.pneumatics``),
the tagged unions (:mod:`simpro_mj.config.entries`) and cross-field rules.
The ``setpoint.cueing`` block (:class:`Cueing`), which the defaults do not
have, lists its own keys and defaults.
``Scenario.model_validate(tree).model_dump()`` is the resolved scenario, the
plain dict the other rooms read and ``scenario_hash`` hashes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, Any, ClassVar

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    SerializeAsAny,
    SkipValidation,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_serializer,
    model_validator,
)

from controllers.design import ACTUATORS, Plant, paper_plant, redesigned_design
from controllers.design import READINGS as PAPER_UNITS
from controllers.design import VARIANTS as INNER_VARIANTS
from controllers.errors import DesignError
from controllers.joint import METHODS as DISCRETISATIONS
from controllers.mpc_cueing import MpcParamError
from controllers.setpoint_filter import KINDS as SETPOINT_FILTERS
from controllers.task_space import INTEGRATORS
from controllers.task_space import LAGS as FEEDFORWARD_LAGS
from controllers.washout import WashoutParamError
from simpro_mj.config.cueing import (
    ALGORITHMS,
    SINE_CHANNELS,
    default_parameters,
    manoeuvre_spec,
    washout_params,
)
from simpro_mj.config.entries import Components, Faults
from simpro_mj.config.rules import (
    DELAY_SAMPLES,
    DESIGN_PLANTS,
    IDENTIFY_CHOICES,
    MAX_DECIMATION,
    MAX_DURATION_S,
    MIN_DURATION_S,
    MODES,
    NAME_RE,
    OUTER_TYPES,
    PHYSICS_DT_MS,
    SETPOINT_AXES,
    Block,
    Problem,
    below,
    listed,
    number,
    one_of,
    rule,
    user_error,
)
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import check_keys, key_text, value_text
from simpro_mj.core.rates import whole_steps
from simpro_mj.plant.pneumatics.params import ACTUATOR_KINDS as ACTUATOR_MODELS
from simpro_mj.plant.pneumatics.params import DEFAULT_PNEUMATIC_PARAMS, PneumaticParams
from simpro_mj.plant.sensors import POT_BITS, POT_BITS_TEXT

__all__ = [
    "Scenario",
    "Cueing",
    "scenario_model",
    "check_cueing",
    "check_pneumatics",
    "PAPER_UNITS",
    "INNER_VARIANTS",
    "DISCRETISATIONS",
    "SETPOINT_FILTERS",
    "FEEDFORWARD_LAGS",
    "ACTUATOR_MODELS",
]

#: Largest K K_I times the outer period: ten times the delay-free integrator's limit 2.
MAX_GAIN_PERIOD = 20.0

Gains = Annotated[list[float], rule(lambda v: v >= 0, "3 numbers >= 0 (K K_I, 1/s)")]


class Outer(Block):
    """The task-space loop (eqs. 21-27, Fig. 7)."""

    _path = "controller.outer"
    type: Annotated[str, one_of(OUTER_TYPES)]
    gains: Gains
    pi_zero: Annotated[float, rule(lambda v: -1 < v < 1, "-1 < c < 1")]
    integrator: Annotated[str, one_of(INTEGRATORS)]
    period_ms: int
    delay_samples: Annotated[int, one_of(DELAY_SAMPLES)]

    @model_validator(mode="after")
    def _gain_bound(self):
        # a discrete integrator of period T is unstable beyond K T = 2 even around
        # perfect joints; far beyond it the loop only saturates (checked here, at load,
        # before the preflight's analysis of the real limit)
        top = max(self.gains, default=0.0)
        if top * self.period_ms * 1e-3 > MAX_GAIN_PERIOD:
            raise Problem.invalid(
                self.gains,
                f"K K_I * T <= {MAX_GAIN_PERIOD:g} (here T = {self.period_ms} ms: K K_I <= "
                f"{MAX_GAIN_PERIOD / (self.period_ms * 1e-3):.4g} 1/s); an integrator of period "
                "T is unstable beyond K T = 2 around perfect joints, and ten times that only "
                "saturates the joints",
                ".gains",
            )
        return self


class JointModel(Block):
    """``b / (s (s^2 + a1 s + a0))``, SI (m/V): one identified actuator."""

    _path = "controller.inner.identified.actuator1"  # the three have the same keys
    b: Annotated[float, rule(lambda v: v > 0, "> 0 m/V")]
    a1: Annotated[float, rule(lambda v: v >= 0, ">= 0 1/s")]
    a0: Annotated[float, rule(lambda v: v > 0, "> 0 1/s^2")]


class Identified(Block):
    _path = "controller.inner.identified"
    actuator1: JointModel
    actuator2: JointModel
    actuator3: JointModel


class Inner(Block):
    """The joint controllers (eqs. 28-29, 36-37)."""

    _path = "controller.inner"
    variant: Annotated[str, one_of(INNER_VARIANTS)]
    discretisation: Annotated[str, one_of(DISCRETISATIONS)]
    design_plant: Annotated[str, one_of(DESIGN_PLANTS)]
    identify: Annotated[str, one_of(IDENTIFY_CHOICES)]
    identified: Identified
    zeta: Annotated[float, rule(lambda v: 0 < v < 2, "0 < zeta < 2")]
    wn_rad_s: Annotated[float, rule(lambda v: v > 0, "> 0 rad/s")]


class Feedforward(Block):
    """Mode ``feedforward`` (docs/feedforward.md)."""

    _path = "controller.feedforward"
    gains: Gains
    model_tau_ms: Annotated[float, rule(lambda v: 0 <= v <= 10_000, "0..10000 ms")]
    hold_on_saturation: bool
    lag: Annotated[str, one_of(FEEDFORWARD_LAGS)]
    average: bool
    leg_velocity: bool


def _per_leg_steps(times: list[float]) -> list[float]:
    """One time for every leg or three (controllers.setpoint_filter.leg_times), each
    an integer multiple of the 1 ms step (the ramp averages whole steps)."""
    # 0 is allowed (no ramp): whole_steps asks for at least one step
    ok = len(times) in (1, 3) and all(v == 0 or whole_steps(v * 1e-3) is not None for v in times)
    if not ok:
        allowed = f"one or 3 (per leg) multiples of the {PHYSICS_DT_MS:g} ms physics step"
        raise Problem.invalid(times, allowed)
    return times


class SetpointFilter(Block):
    """Fig. 13's filter between the outer loop and the joint loops."""

    _path = "controller.setpoint_filter"
    type: Annotated[str, one_of(SETPOINT_FILTERS)]
    time_ms: Annotated[
        list[float], rule(lambda v: 0 < v <= 1e4, "0 < ms <= 1e4"), AfterValidator(_per_leg_steps)
    ]


class Controller(Block):
    _path = "controller"
    mode: Annotated[str, one_of(MODES)]
    outer: Outer
    inner: Inner
    feedforward: Feedforward
    setpoint_filter: SetpointFilter
    clamp_setpoints: bool


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
    model: Annotated[str, one_of(ACTUATOR_MODELS)]
    #: overrides of simpro_mj.plant.pneumatics.DEFAULT_PNEUMATIC_PARAMS (only the keys given)
    pneumatics: Annotated[dict, BeforeValidator(check_pneumatics)]


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


class Payload(Block):
    _path = "plant.payload"
    mass_kg: Annotated[
        float,
        rule(
            lambda v: 0 <= v <= MAX_PAYLOAD_KG,
            f"0 .. {MAX_PAYLOAD_KG:g} kg (three DNC-125 cylinders lift at most about 3,750 kg "
            "at 10 bar; the preflight gives the limit at the supply pressure)",
        ),
    ]
    com_mm: Annotated[
        list[float],
        rule(
            lambda v: abs(v) <= MAX_COM_MM,
            f"|x|, |y|, |z| <= {MAX_COM_MM:g} mm (a cabin on a platform about 1 m across)",
        ),
    ]


class AnchorOffsets(Block):
    _path = "plant.anchor_offsets_mm"
    A1: Annotated[list[float], _OFFSET, AfterValidator(_in_plane)]
    A2: Annotated[list[float], _OFFSET]
    A3: Annotated[list[float], _OFFSET]
    C1: Annotated[list[float], _OFFSET, AfterValidator(_in_plane)]
    B2: Annotated[list[float], _OFFSET]
    B3: Annotated[list[float], _OFFSET]


class Guide(Block):
    _path = "plant.guide"
    radius_offset_mm: Annotated[float, _OFFSET]
    centre_offset_mm: Annotated[list[float], _OFFSET]


class PlantBlock(Block):
    """The as-built plant (simpro_mj.plant.model_params) and its preset."""

    _path = "plant"
    payload: Payload
    platform_mass_kg: Annotated[
        float,
        rule(lambda v: 1 <= v <= 2000, "1 .. 2000 kg (the moving frame: 120 kg as built)"),
    ]
    anchor_offsets_mm: AnchorOffsets
    guide: Guide
    loop_timeconst_s: Annotated[
        float,
        rule(
            lambda v: LOOP_TIMECONST_RANGE_S[0] <= v <= LOOP_TIMECONST_RANGE_S[1],
            f"{LOOP_TIMECONST_RANGE_S[0]:g} .. {LOOP_TIMECONST_RANGE_S[1]:g} s (at least two "
            "physics steps, MuJoCo's floor for a stable constraint; at most 1 s)",
        ),
    ]
    preset: str


class Potentiometer(Block):
    _path = "sensors.potentiometer"
    bits: Annotated[int, rule(lambda v: POT_BITS[0] <= v <= POT_BITS[1], POT_BITS_TEXT)]
    range_v: Annotated[float, rule(lambda v: v > 0, "> 0 V")]
    volts_per_mm: Annotated[float, rule(lambda v: v > 0, "> 0 V/mm")]
    noise_lsb: Annotated[float, rule(lambda v: v >= 0, ">= 0 LSB")]
    offset_mm: list[float]
    gain_error_pct: Annotated[list[float], rule(lambda v: v > -100, "3 numbers > -100 %")]
    rate_ms: int


class HeightEncoder(Block):
    _path = "sensors.height_encoder"
    resolution_mm: Annotated[float, rule(lambda v: v >= 0, ">= 0 mm (0: no quantisation)")]
    noise_mm: Annotated[float, rule(lambda v: v >= 0, ">= 0 mm")]
    rate_ms: int


class Imu(Block):
    _path = "sensors.imu"
    noise_deg: Annotated[float, rule(lambda v: v >= 0, ">= 0 deg")]
    bias_deg: list[float]
    bandwidth_hz: Annotated[float, rule(lambda v: v > 0, "> 0 Hz")]
    rate_ms: int


class SensorsBlock(Block):
    """simpro_mj.plant.sensors.DEFAULT_SENSORS with the as-built calibration errors."""

    _path = "sensors"
    potentiometer: Potentiometer
    height_encoder: HeightEncoder
    imu: Imu


class Logging(Block):
    _path = "logging"
    decimation: Annotated[
        int, rule(lambda v: 1 <= v <= MAX_DECIMATION, f"an integer 1..{MAX_DECIMATION}")
    ]


# ------------------------------------------------------------------ setpoint.cueing
# (simpro_mj.config.cueing). Its keys are not in DEFAULT_SCENARIO (a
# scenario has the block or not), so these models list their own; their messages
# keep the contract of docs/robustness.md (tests/data/scenario_messages.json, the
# cue_braking cases).

#: A cueing ``sine``'s period (s): 20 physics steps .. 10 minutes, on the 1 ms grid.
CUE_SINE_PERIOD_S = (0.02, 600.0)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class CueBlock(BaseModel):
    """A mapping of the cueing block: a mapping with its own keys, checked before its fields.

    ``_expected`` completes "expected ..." for a value that is not a mapping;
    ``_listed`` is the allowed keys in the order an unknown key's message
    lists them (default: sorted). A field left out takes its default, which
    is validated too (``None`` for a required value: its message says what
    is allowed).
    """

    model_config = ConfigDict(extra="forbid", validate_default=True)
    _expected: ClassVar[str] = "a mapping"
    _listed: ClassVar[tuple[str, ...]] = ()

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data: Any) -> Any:
        if not isinstance(data, Mapping):
            raise Problem("invalid value", f": expected {cls._expected}")
        allowed = list(cls._listed or sorted(cls.model_fields))
        for key in data:
            if key not in cls.model_fields:
                raise Problem("unknown key", f": allowed keys are {allowed}", f".{key_text(key)}")
        return cls._whole(data)

    @classmethod
    def _whole(cls, data: Mapping) -> Mapping:
        """A rule across the given keys, before the fields (none by default)."""
        return data


def _finite(value: Any) -> float:
    # not rules.number: a washout parameter is a YAML number; a string such as '5e-3' is refused
    if not _is_number(value) or not math.isfinite(value):
        raise Problem.invalid(value, "a finite number")
    return float(value)


def _whole_as_int(value: Any) -> int | float:
    # rot_order: an int when whole, as its default (the shipped scenarios' hashes)
    x = _finite(value)
    return int(x) if x == int(x) else x


class _WashoutCheck(CueBlock):
    """The washout's own ranges (:class:`controllers.washout.WashoutParams`), once every
    parameter is a number."""

    _algorithm: ClassVar[str] = "classical_washout"

    @model_validator(mode="after")
    def _washout(self):
        try:
            washout_params({"algorithm": self._algorithm, "parameters": dict(self)})
        except (WashoutParamError, MpcParamError) as exc:
            raise Problem("invalid value", f": {exc}") from None
        return self


class _MpcCheck(_WashoutCheck):
    """The MPC's own ranges (:class:`controllers.mpc_cueing.MpcParams`)."""

    _algorithm: ClassVar[str] = "mpc"


def _parameters_model(name: str, base: type, algorithm: str):
    return create_model(
        name,
        __base__=base,
        __module__=__name__,
        **{
            key: (
                Annotated[int | float, BeforeValidator(_whole_as_int)]
                if isinstance(default, int)
                else Annotated[float, BeforeValidator(_finite)],
                default,
            )
            for key, default in default_parameters(algorithm).items()
        },
    )


#: ``setpoint.cueing.parameters``: the keys of :data:`~simpro_mj.config.cueing.PARAMETER_KEYS`
#: (YAML units), each a finite number, the defaults those of the washout.
WashoutParameters = _parameters_model("WashoutParameters", _WashoutCheck, "classical_washout")
#: ``setpoint.cueing.parameters`` of ``algorithm: mpc``: the keys of
#: :data:`~simpro_mj.config.cueing.MPC_PARAMETER_KEYS`, the defaults those of the MPC.
MpcParameters = _parameters_model("MpcParameters", _MpcCheck, "mpc")


class CueManoeuvre(CueBlock):
    """A generated vehicle input (:mod:`simpro_mj.config.manoeuvres`): its
    ``ManoeuvreSpec``'s fields and defaults; ``type`` and ``speed_kmh`` required.

    The values are kept as given (an integral speed stays an int, as it always
    did: the scenario's hash) and checked by ``ManoeuvreSpec.check``, the one
    statement of their ranges.
    """

    _expected = "a mapping with type and speed_kmh"
    type: SkipValidation[str | None] = None
    speed_kmh: SkipValidation[int | float | None] = None
    vehicle: SkipValidation[str] = "bmw_320i"
    deceleration_mps2: SkipValidation[int | float] = 5.0
    bump_height_m: SkipValidation[int | float] = 0.06
    bump_length_m: SkipValidation[int | float] = 0.5
    lead_s: SkipValidation[int | float] = 1.0

    @model_validator(mode="after")
    def _spec(self):
        # imported on use: manoeuvres loads scipy.signal and scipy.integrate (about
        # 1.5 s), which only a scenario with a manoeuvre needs
        from simpro_mj.config.manoeuvres import MANOEUVRES, ManoeuvreError

        if self.type not in MANOEUVRES:
            raise Problem.invalid(self.type, str(list(MANOEUVRES)), ".type")
        if self.speed_kmh is None:
            raise Problem("invalid value", ": missing; allowed: 10..180", ".speed_kmh")
        try:
            manoeuvre_spec(dict(self)).check()
        except ManoeuvreError as exc:
            # the spec names its field alone ("invalid value at lead_s: ..."): put it below
            key, _, rest = str(exc).removeprefix("invalid value at ").partition(":")
            raise Problem("invalid value", f":{rest}", f".{key}") from None
        return self


def _sine_period(value: Any) -> float:
    lo, hi = CUE_SINE_PERIOD_S
    if not (_is_number(value) and lo <= value <= hi) or whole_steps(value) is None:
        raise Problem.invalid(value, f"{lo:g}..{hi:g} s on the {PHYSICS_DT_MS:g} ms grid")
    return float(value)


class CueSine(CueBlock):
    """A synthetic vehicle input: the vehicle at rest plus ``amplitude sin(2 pi t /
    period_s)`` (SI) on one ``channel`` (:data:`~simpro_mj.config.cueing.SINE_CHANNELS`)."""

    _listed = ("channel", "amplitude", "period_s")
    _expected = f"a mapping with keys {list(_listed)}"
    channel: Annotated[str, listed(SINE_CHANNELS)] = None
    amplitude: float = None
    period_s: Annotated[float, BeforeValidator(_sine_period)] = None

    @field_validator("amplitude", mode="before")
    @classmethod
    def _up_to_the_channel(cls, value: Any, info: ValidationInfo) -> Any:
        """0 < amplitude <= the channel's limit (1 g, 90 deg/s)."""
        channel = info.data.get("channel")
        if channel is None:  # the channel's own error is the one reported
            return value
        top = SINE_CHANNELS[channel]
        if not (_is_number(value) and 0 < value <= top):
            unit = channel.split("_", 1)[1].replace("mps2", "m/s^2").replace("rad_s", "rad/s")
            raise Problem.invalid(value, f"0 < amplitude <= {top:.4g} ({unit})")
        return float(value)


class CueStep(CueBlock):
    """A large-signal vehicle input: the vehicle at rest plus ``amplitude`` (SI, signed)
    on one ``channel`` from ``start_s``, reached over ``ramp_s`` (0: a step), back from
    ``end_s`` (null: held) (:func:`~simpro_mj.config.cueing.step_input`)."""

    _listed = ("channel", "amplitude", "start_s", "ramp_s", "end_s")
    _expected = f"a mapping with keys {list(_listed)}"
    channel: Annotated[str, listed(SINE_CHANNELS)] = None
    amplitude: float = None
    start_s: Annotated[float, BeforeValidator(_finite)] = 1.0
    ramp_s: Annotated[float, BeforeValidator(_finite)] = 0.0
    end_s: float | None = None

    @field_validator("amplitude", mode="before")
    @classmethod
    def _up_to_the_channel(cls, value: Any, info: ValidationInfo) -> Any:
        """0 < |amplitude| <= the channel's limit (1 g, 90 deg/s)."""
        channel = info.data.get("channel")
        if channel is None:
            return value
        top = SINE_CHANNELS[channel]
        if not (_is_number(value) and 0 < abs(value) <= top):
            raise Problem.invalid(value, f"0 < |amplitude| <= {top:.4g}")
        return float(value)

    @model_validator(mode="after")
    def _times(self):
        if self.start_s < 0:
            raise Problem.invalid(self.start_s, ">= 0 s", ".start_s")
        if self.ramp_s < 0:
            raise Problem.invalid(self.ramp_s, ">= 0 s (0: a step)", ".ramp_s")
        if self.end_s is not None and not self.end_s >= self.start_s + self.ramp_s:
            raise Problem.invalid(self.end_s, "null or >= start_s + ramp_s", ".end_s")
        return self


def _file_name(value: Any) -> str | None:
    # its existence is checked once the scenario's folder is known (cueing.resolve_paths)
    if value is not None and (not isinstance(value, str) or not value.strip()):
        raise Problem.invalid(value, "a file name")
    return value


class Cueing(CueBlock):
    """``setpoint.cueing``: a vehicle input, exactly one of ``telemetry`` (a CSV file),
    ``manoeuvre`` (generated) or ``sine``, through a motion-cueing ``algorithm`` and
    its ``parameters`` (:mod:`simpro_mj.config.cueing`)."""

    _expected = "a mapping with telemetry or manoeuvre"
    _listed = ("telemetry", "manoeuvre", "sine", "step", "algorithm", "parameters", "columns")
    # declared in the order they are checked (the first error is the one reported)
    telemetry: Annotated[str | None, BeforeValidator(_file_name)] = None
    algorithm: Annotated[str, listed(ALGORITHMS)] = "classical_washout"
    # null (or empty) parameters: every default
    parameters: SerializeAsAny[Annotated[WashoutParameters, BeforeValidator(lambda v: v or {})]] = (
        None
    )
    manoeuvre: CueManoeuvre | None = None
    sine: CueSine | None = None
    step: CueStep | None = None
    #: telemetry column mapping (:data:`~simpro_mj.config.telemetry.MAPPING_HELP`)
    columns: dict | None = None

    @field_validator("parameters", mode="wrap")
    @classmethod
    def _of_the_algorithm(cls, value: Any, handler, info: ValidationInfo) -> Any:
        """``parameters`` of the chosen ``algorithm``: the washout's, or the MPC's."""
        if info.data.get("algorithm") != "mpc":
            return handler(value)
        try:
            return MpcParameters.model_validate(value or {})
        except ValidationError as exc:
            err = exc.errors()[0]
            loc = "".join(f".{key_text(k)}" for k in err["loc"])
            msg = str(err.get("msg", "")).removeprefix("Value error, ")
            head, _, rest = msg.partition(" at <here>")
            raise Problem(head or "invalid value", rest, loc) from None

    @field_validator("columns", mode="before")
    @classmethod
    def _mapping(cls, value: Any) -> Any:
        from simpro_mj.config.telemetry import check_mapping

        if value is None or value == {}:
            return None
        try:
            return check_mapping(value)
        except ValueError as exc:
            raise Problem("invalid value", f": {exc}") from None

    @classmethod
    def _whole(cls, data: Mapping) -> Mapping:
        if sum(data.get(k) is not None for k in ("telemetry", "manoeuvre", "sine", "step")) != 1:
            raise Problem(
                "invalid value",
                ": give exactly one of telemetry (a CSV file), manoeuvre, sine or step",
            )
        return data

    @model_serializer(mode="wrap")
    def _as_resolved(self, handler):
        """Every key spelled out (``manoeuvre: null`` when absent), ``sine`` only when given:
        the block the rest of the code reads and the scenario's hash has always seen."""
        out = handler(self)
        resolved = {k: out[k] for k in ("telemetry", "manoeuvre", "algorithm", "parameters")}
        if self.sine is not None:
            resolved["sine"] = out["sine"]
        if self.step is not None:
            resolved["step"] = out["step"]
        if self.columns is not None:
            resolved["columns"] = out["columns"]
        return resolved


def check_cueing(value: Any, path: str = "setpoint.cueing") -> dict:
    """A ``cueing`` block on its own, validated by :class:`Cueing` and spelled out.

    Parameters
    ----------
    value : Any
        The block as written (``{"sine": {...}}``).
    path : str
        Its dotted path, for the messages.

    Returns
    -------
    dict
        The block as the resolved scenario holds it (every parameter given).

    Raises
    ------
    UserInputError
        One line naming the dotted key and what is allowed.
    """
    try:
        return Cueing.model_validate(value).model_dump()
    except ValidationError as exc:
        raise user_error(exc, path) from None


class Setpoint(Block):
    """Per axis a list of components summed on top of the home pose; or a cueing block."""

    _path = "setpoint"
    _own = frozenset({*SETPOINT_AXES, "cueing"})
    roll_deg: Components
    pitch_deg: Components
    heave_mm: Components
    # (simpro_mj.config.cueing); only in the resolved scenario when given, so
    # that the scenarios without it keep their hash
    cueing: Cueing | None = None

    @model_serializer(mode="wrap")
    def _cueing_when_given(self, handler):
        out = handler(self)
        if "cueing" not in self.model_fields_set:
            out.pop("cueing", None)
        return out


# ------------------------------------------------------------------ the scenario


class Scenario(Block):
    """A resolved scenario (:func:`simpro_mj.config.scenario.load_scenario`), typed.

    ``Scenario.model_validate(tree)`` takes a tree with every key present (the
    defaults merged); ``model_dump()`` gives back the plain dict the modules
    read and :func:`~simpro_mj.config.scenario.scenario_hash` hashes.
    """

    _own = frozenset({"faults"})
    name: Annotated[
        str,
        rule(
            lambda v: bool(NAME_RE.match(v)) and len(v) <= 100,
            "letters, digits, '_', '-', '.' (a file-name-safe word of at most 100 characters)",
        ),
    ]
    paper_units: Annotated[str, one_of(PAPER_UNITS)]
    description: str
    duration_s: Annotated[
        float,
        rule(lambda v: v > 0, "> 0 s"),
        rule(lambda v: v >= MIN_DURATION_S, f">= {MIN_DURATION_S:g} s"),
        rule(lambda v: v <= MAX_DURATION_S, f"<= {MAX_DURATION_S:g} s (one hour)"),
    ]
    seed: Annotated[int, rule(lambda v: 0 <= v < 2**63, "an integer >= 0")]
    controller: Controller
    actuator: Actuator
    plant: PlantBlock
    sensors: SensorsBlock
    setpoint: Setpoint
    faults: Faults
    logging: Logging

    @model_validator(mode="after")
    def _across_blocks(self):
        _check_redesign(self)
        _check_fault_values(self)
        return self

    def supply_bar_gauge(self) -> float:
        """The supply pressure (bar gauge): the scenario's or the plant's default."""
        value = self.actuator.pneumatics.get("supply_pressure_bar_gauge")
        if value is None:
            value = DEFAULT_PNEUMATIC_PARAMS["supply_pressure_bar_gauge"]
        return float(value)


def _check_redesign(s: Scenario) -> None:
    """The pole placement of ``variant: redesigned`` must be feasible for every leg."""
    inner = s.controller.inner
    if inner.variant != "redesigned":
        return
    for act in ACTUATORS:
        if inner.design_plant == "identified":
            plant = Plant(**getattr(inner.identified, act).model_dump())
        else:
            plant = paper_plant(act, s.paper_units)
        try:
            redesigned_design(act, zeta=inner.zeta, wn=inner.wn_rad_s, plant=plant)
        except DesignError as exc:
            raise UserInputError(
                f"infeasible joint design at controller.inner.wn_rad_s: zeta = {inner.zeta}, "
                f"wn = {inner.wn_rad_s} rad/s for {act}: {exc}; allowed: a zeta, wn_rad_s "
                "pair the pole placement can meet (e.g. the paper's 0.7, 10)"
            ) from exc


def _check_fault_values(s: Scenario) -> None:
    """Fault times within the run and a supply drop below the supply pressure."""
    duration, supply = s.duration_s, s.supply_bar_gauge()
    for i, f in enumerate(s.faults):
        here = f"faults[{i}]"
        if f.time_s >= duration:
            raise _absolute(f"{here}.time_s", f.time_s, f"< duration_s = {duration} s")
        end = getattr(f, "end_s", None)
        if end is not None and end > duration:
            raise _absolute(f"{here}.end_s", end, f"null or <= duration_s = {duration} s")
        if f.type == "supply_drop" and not 0.0 <= f.pressure_bar_gauge < supply:
            raise _absolute(
                f"{here}.pressure_bar_gauge",
                f.pressure_bar_gauge,
                f"0 (atmospheric) <= p < the supply {supply:g} bar gauge "
                "(actuator.pneumatics.supply_pressure_bar_gauge)",
            )


def _absolute(path: str, value: Any, allowed: str) -> UserInputError:
    return UserInputError(f"invalid value at {path}: {value_text(value)}; allowed: {allowed}")


def scenario_model(tree: Mapping) -> Scenario:
    """Validate a merged scenario tree (every key present) into a :class:`Scenario`.

    Raises
    ------
    UserInputError
        One line naming the dotted path of the first offending field and what
        is allowed.
    """
    try:
        return Scenario.model_validate(tree)
    except ValidationError as exc:
        raise user_error(exc) from None
