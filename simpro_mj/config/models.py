"""Typed scenario models (pydantic v2): one model per block, validated once at the edge.

The models hold the scenario: every key is a field with its default (the one
source of every default and of every leaf's type, :class:`~simpro_mj.config.rules.Block`;
the plant's blocks, :mod:`simpro_mj.config.plant_blocks`, take theirs from the
plant), its range or enumeration (one tuple each, imported from the module
that uses it: ``controllers``, ``simpro_mj.plant.pneumatics``), the tagged
unions (:mod:`simpro_mj.config.entries`) and the cross-field rules.
:func:`simpro_mj.config.scenario.load_scenario` merges a file and its ``--set``
overrides over the defaults as a plain tree
(:data:`~simpro_mj.config.defaults.DEFAULT_SCENARIO`, ``Scenario.defaults()``)
and validates the result with :class:`Scenario`; the ``setpoint.cueing``
block (:class:`Cueing`), present or not, lists its own keys and defaults.
``Scenario.model_validate(tree).model_dump()`` is the resolved scenario, the
plain dict the other rooms read and ``scenario_hash`` hashes.

About 720 lines, over the project's ~500: the scenario's schema in one place
(controller blocks, the cueing block's models, the cross-field rules); the
cueing models are the piece to move out next if it grows.
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
    Field,
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
from simpro_mj.config.plant_blocks import (
    ACTUATOR_MODELS,
    Actuator,
    PlantBlock,
    SensorsBlock,
    check_pneumatics,
)
from simpro_mj.config.presets import DEFAULT_PRESET
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
    listed,
    one_of,
    rule,
    user_error,
)
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import key_text, value_text
from simpro_mj.core.rates import whole_steps
from simpro_mj.plant.pneumatics.params import DEFAULT_PNEUMATIC_PARAMS

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


Width = Annotated[float, rule(lambda v: 0 <= v <= 10, "0..10")]


class OuterDeadBand(Block):
    """Dead band of the task-space loop per axis (0: none; docs/paper-notes.md, dead bands)."""

    _path = "controller.outer.dead_band"
    roll_deg: Width = 0.0
    pitch_deg: Width = 0.0
    heave_mm: Width = 0.0


class Outer(Block):
    """The task-space loop (eqs. 21-27, Fig. 7)."""

    _path = "controller.outer"
    type: Annotated[str, one_of(OUTER_TYPES)] = "I"  # I (eq. 22) | PI (section 4)
    # K * K_I per axis (roll, pitch, heave), 1/s: section 5.2.3's 3 (the analysed
    # limit on the default plant is 11.8; docs/paper-notes.md)
    gains: Gains = [3.0, 3.0, 3.0]
    # c of the PI law T (z + c)/(z - 1), section 4; used with type PI only
    pi_zero: Annotated[float, rule(lambda v: -1 < v < 1, "-1 < c < 1")] = 0.2
    # discretisation of eq. (22)'s integral (I law): backward T z/(z - 1), the newest
    # error reaches q_d at once and Fig. 13's ramp filter spreads it over T | forward
    # T/(z - 1), Fig. 7 as printed (one more period of delay: 23.8 % vs 8 % pitch
    # overshoot at K K_I = 3; docs/paper-notes.md)
    integrator: Annotated[str, one_of(INTEGRATORS)] = "backward"
    # outer sampling period T, an integer multiple of the 1 ms physics step
    period_ms: int = 60
    # inner loop as a delay in the analysis: 1 sample (60 ms, eq. 21) or 2
    delay_samples: Annotated[int, one_of(DELAY_SAMPLES)] = 1
    # dead band on the task error the law integrates (controllers.dead_band): within
    # it the integrated pose holds, so the loop stops hunting against seal friction
    dead_band: OuterDeadBand = Field(default_factory=OuterDeadBand)

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
    b: Annotated[float, rule(lambda v: v > 0, "> 0 m/V")] = 12.51
    a1: Annotated[float, rule(lambda v: v >= 0, ">= 0 1/s")] = 15.78
    a0: Annotated[float, rule(lambda v: v > 0, "> 0 1/s^2")] = 78.92


def _legs_2_3() -> JointModel:
    return JointModel(b=95.66, a1=17.37, a0=467.7)


class Identified(Block):
    """b / (s (s^2 + a1 s + a0)) per actuator, SI (m/V); set by the plant preset
    (plant.preset: what ``simpro-sim identify`` measures on it); the numbers here
    are the schema's only."""

    _path = "controller.inner.identified"
    actuator1: JointModel = Field(default_factory=JointModel)
    actuator2: JointModel = Field(default_factory=_legs_2_3)
    actuator3: JointModel = Field(default_factory=_legs_2_3)


class Inner(Block):
    """The joint controllers (eqs. 28-29, 36-37)."""

    _path = "controller.inner"
    # joint controllers: eqs. (36)-(37) printed | corrected | redesigned
    variant: Annotated[str, one_of(INNER_VARIANTS)] = "corrected"
    discretisation: Annotated[str, one_of(DISCRETISATIONS)] = "tustin"  # tustin | zoh
    # plant the joint controllers are designed on: "paper" (eqs. 34-35) or
    # "identified" (the model this simulation identifies, `simpro-sim identify`,
    # which is what the paper's procedure - identify, then place poles - gives)
    # "auto": eqs. 34-35 on the paper preset, the identified models on any other
    # (resolved at load: scenario.yaml names the one used)
    design_plant: Annotated[str, one_of(DESIGN_PLANTS)] = "auto"
    # with design_plant identified: "auto" identifies the scenario's own plant when
    # it is not its preset's (Fig. 12's experiment, cached by the plant's hash:
    # simpro_mj.identification.auto) | "preset": the identified models as given
    identify: Annotated[str, one_of(IDENTIFY_CHOICES)] = "auto"
    identified: Identified = Field(default_factory=Identified)
    # dominant pair of the "redesigned" pole placement (section 5.2.2)
    zeta: Annotated[float, rule(lambda v: 0 < v < 2, "0 < zeta < 2")] = 0.7
    wn_rad_s: Annotated[float, rule(lambda v: v > 0, "> 0 rad/s")] = 10.0
    # dead band on each leg's error (controllers.dead_band), mm: one for every leg or 3
    dead_band_mm: Annotated[list[float], rule(lambda v: 0 <= v <= 50, "0..50 mm")] = [
        0.0,
        0.0,
        0.0,
    ]
    # valve dither (controllers.dither): a square wave of +-dither_v volts added to
    # every valve command, period dither_period_ms (an even number of 1 ms steps); 0: off
    dither_v: Annotated[float, rule(lambda v: 0 <= v <= 5, "0..5 V")] = 0.0
    dither_period_ms: Annotated[
        float, rule(lambda v: v >= 2 and v == int(v) and int(v) % 2 == 0, "an even number >= 2 ms")
    ] = 40.0


class Feedforward(Block):
    """Mode ``feedforward`` (docs/feedforward.md).

    The correction, with its own K K_I per axis (it only removes what the joint
    loops leave: slower than the paper's I law), integrates y_d - y less the
    joint loops' lag (``lag``), with ``lag: model``: M y_d - y, M a first-order
    lag of ``model_tau_ms`` (0: y_d - y), and skips an outer step after which a
    valve was at its rail (``hold_on_saturation``).
    """

    _path = "controller.feedforward"
    gains: Gains = [1.0, 1.0, 1.0]
    model_tau_ms: Annotated[float, rule(lambda v: 0 <= v <= 10_000, "0..10000 ms")] = 200.0
    hold_on_saturation: bool = True
    # the joint loops' lag taken out of the error: joints (measured: J^-1 (q_d -
    # q_meas)) | model (M y_d, above); average: the correction uses the means over the
    # outer period instead of one sample. Chosen by measurement (docs/feedforward.md):
    # the steady-state error after a step below the sensor floor, overshoot 0.4 %
    lag: Annotated[str, one_of(FEEDFORWARD_LAGS)] = "joints"
    average: bool = True
    # leg velocity feed-forward (controllers.velocity_feedforward): a valve voltage
    # (a0/b) J dy_d/dt per leg from the set-point's rate and the identified plants
    # (controller.inner.identified), through the set-point filter when there is one;
    # clipped to the valve's 5 V span. Chosen by measurement (docs/feedforward.md):
    # phase at 1 Hz -40 -> -10 deg, track_cues RMS error halved, steps unchanged
    leg_velocity: bool = True


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
    """Fig. 13's "Filter" between the outer loop (or the joint-only IK) and the joint
    loops (controllers.setpoint_filter).

    ``type``: ramp (the mean of q_d over ``time_ms``; with ``time_ms`` = T the
    60 ms steps of q_d become ramps: no valve kick) | first_order (time constant
    ``time_ms``) | zero_cancel (k_i/(s + k_i), eq. 29's zero) | none. Chosen by
    analysis: docs/paper-notes.md. ``time_ms`` per leg: T for leg 1; T/2 for legs
    2-3, whose k_p (640 V/m) is 8.3 times leg 1's, so a 60 ms step of their q_d
    kicks their valves 8 times less while their ramp's delay halves (step_roll
    overshoot 11.4 % -> 7.9 %).
    """

    _path = "controller.setpoint_filter"
    type: Annotated[str, one_of(SETPOINT_FILTERS)] = "ramp"
    time_ms: Annotated[
        list[float], rule(lambda v: 0 < v <= 1e4, "0 < ms <= 1e4"), AfterValidator(_per_leg_steps)
    ] = [60.0, 30.0, 30.0]


class Controller(Block):
    _path = "controller"
    # joint_only (Fig. 15a) | task_space (Fig. 15b) | feedforward (the set-point
    # through the IK every 1 ms, the outer law adding a correction: docs/feedforward.md)
    mode: Annotated[str, one_of(MODES)] = "task_space"
    outer: Outer = Field(default_factory=Outer)
    inner: Inner = Field(default_factory=Inner)
    feedforward: Feedforward = Field(default_factory=Feedforward)
    setpoint_filter: SetpointFilter = Field(default_factory=SetpointFilter)
    # unreachable set-points: reject at load time (false) or clamp (true)
    clamp_setpoints: bool = False


class Logging(Block):
    _path = "logging"
    decimation: Annotated[
        int, rule(lambda v: 1 <= v <= MAX_DECIMATION, f"an integer 1..{MAX_DECIMATION}")
    ] = 1


# ------------------------------------------------------------------ setpoint.cueing
# (simpro_mj.config.cueing). A scenario has the block or not (it is not in the
# default tree), so these models list their own keys; their messages
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
    tyre_offsets: SkipValidation[str] = "none"

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
    roll_deg: Components = []
    pitch_deg: Components = []
    heave_mm: Components = []
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
    ] = ""  # a name for the run (file stem if empty)
    # Unit of Y in the paper's eqs. (34)-(37) (controllers.design.READINGS): "volts"
    # (the joint potentiometer's signal, 10 V over the 500 mm stroke = 20 V/m, as the
    # rig reads it through the MF624, section 5) or "metres". Sets the SI gains of
    # the printed joint controllers, the paper's design plants and the linear
    # actuators' default coefficients (docs/paper-notes.md, section 3).
    paper_units: Annotated[str, one_of(PAPER_UNITS)] = "volts"
    description: str = ""
    duration_s: Annotated[
        float,
        rule(lambda v: v > 0, "> 0 s"),
        rule(lambda v: v >= MIN_DURATION_S, f">= {MIN_DURATION_S:g} s"),
        rule(lambda v: v <= MAX_DURATION_S, f"<= {MAX_DURATION_S:g} s (one hour)"),
    ] = 15.0
    # seed of every random draw of the run (sensor noise)
    seed: Annotated[int, rule(lambda v: 0 <= v < 2**63, "an integer >= 0")] = 1
    controller: Controller = Field(default_factory=Controller)
    actuator: Actuator = Field(default_factory=Actuator)
    plant: PlantBlock = Field(default_factory=PlantBlock)
    sensors: SensorsBlock = Field(default_factory=SensorsBlock)
    setpoint: Setpoint = Field(default_factory=Setpoint)
    # scheduled faults (simpro_mj.plant.faults)
    faults: Faults = []
    logging: Logging = Field(default_factory=Logging)

    @model_validator(mode="after")
    def _across_blocks(self):
        _resolve_design_plant(self)
        _check_redesign(self)
        _check_fault_values(self)
        return self

    def supply_bar_gauge(self) -> float:
        """The supply pressure (bar gauge): the scenario's or the plant's default."""
        value = self.actuator.pneumatics.get("supply_pressure_bar_gauge")
        if value is None:
            value = DEFAULT_PNEUMATIC_PARAMS["supply_pressure_bar_gauge"]
        return float(value)


def _resolve_design_plant(s: Scenario) -> None:
    """``design_plant: auto``: eqs. (34)-(35) on the preset calibrated to them
    (``paper``), the plant's own identified models on any other: the paper's
    procedure, identify then place poles (simpro_mj.identification.auto)."""
    inner = s.controller.inner
    if inner.design_plant == "auto":
        inner.design_plant = "paper" if s.plant.preset == DEFAULT_PRESET else "identified"


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
