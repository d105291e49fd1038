"""Typed scenario models (pydantic v2): one model per block, validated once at the edge.

:func:`simpro_mj.config.scenario.load_scenario` merges a file and its ``--set``
overrides over :data:`~simpro_mj.config.defaults.DEFAULT_SCENARIO` (the one
source of every default and of every leaf's type, :class:`~simpro_mj.config.rules.Block`),
then validates the merged tree with :class:`Scenario`. The models add what
the defaults cannot say: ranges, enumerations (one tuple each, imported from
the module that uses it: ``controllers``, ``simpro_mj.plant.pneumatics``),
the tagged unions (:mod:`simpro_mj.config.entries`) and cross-field rules.
``Scenario.model_validate(tree).model_dump()`` is the resolved scenario, the
plain dict the other rooms read and ``scenario_hash`` hashes.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any

from pydantic import (
    AfterValidator,
    BeforeValidator,
    ValidationError,
    model_serializer,
    model_validator,
)

from controllers.design import ACTUATORS, Plant, paper_plant, redesigned_design
from controllers.design import READINGS as PAPER_UNITS
from controllers.design import VARIANTS as INNER_VARIANTS
from controllers.errors import DesignError
from controllers.joint import METHODS as DISCRETISATIONS
from controllers.setpoint_filter import KINDS as SETPOINT_FILTERS
from controllers.task_space import INTEGRATORS
from controllers.task_space import LAGS as FEEDFORWARD_LAGS
from simpro_mj.config.cueing import check_cueing
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
    number,
    one_of,
    rule,
    user_error,
)
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import check_keys, value_text
from simpro_mj.core.rates import whole_steps
from simpro_mj.plant.pneumatics.params import ACTUATOR_KINDS as ACTUATOR_MODELS
from simpro_mj.plant.pneumatics.params import DEFAULT_PNEUMATIC_PARAMS, PneumaticParams
from simpro_mj.plant.sensors import POT_BITS, POT_BITS_TEXT

__all__ = [
    "Scenario",
    "scenario_model",
    "check_pneumatics",
    "PAPER_UNITS",
    "INNER_VARIANTS",
    "DISCRETISATIONS",
    "SETPOINT_FILTERS",
    "FEEDFORWARD_LAGS",
    "ACTUATOR_MODELS",
]

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


class Payload(Block):
    _path = "plant.payload"
    mass_kg: Annotated[float, rule(lambda v: v >= 0, ">= 0 kg")]
    com_mm: list[float]


class AnchorOffsets(Block):
    _path = "plant.anchor_offsets_mm"
    A1: list[float]
    A2: list[float]
    A3: list[float]
    C1: list[float]
    B2: list[float]
    B3: list[float]


class Guide(Block):
    _path = "plant.guide"
    radius_offset_mm: Annotated[float, rule(lambda v: v > -1000, "> -1000 mm")]
    centre_offset_mm: list[float]


class PlantBlock(Block):
    """The as-built plant (simpro_mj.plant.model_params) and its preset."""

    _path = "plant"
    payload: Payload
    platform_mass_kg: Annotated[float, rule(lambda v: v > 0, "> 0 kg")]
    anchor_offsets_mm: AnchorOffsets
    guide: Guide
    loop_timeconst_s: Annotated[float, rule(lambda v: v > 0, "> 0 s")]
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


class Setpoint(Block):
    """Per axis a list of components summed on top of the home pose; or a cueing block."""

    _path = "setpoint"
    _own = frozenset({*SETPOINT_AXES, "cueing"})
    roll_deg: Components
    pitch_deg: Components
    heave_mm: Components
    # issue 16 (simpro_mj.config.cueing); only in the resolved scenario when given, so
    # that the scenarios without it keep their hash
    cueing: Annotated[
        dict | None, BeforeValidator(lambda v: None if v is None else check_cueing(v))
    ] = None

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
