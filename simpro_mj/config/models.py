"""Typed scenario models (pydantic v2): one model per block, validated once at the edge.

Every key of a scenario is a field here (or in :mod:`~simpro_mj.config.plant_blocks`,
:class:`~simpro_mj.plant.pneumatics.params.Pneumatics`, :mod:`~simpro_mj.config.entries`,
:mod:`~simpro_mj.config.cue_models`), declared with :func:`~simpro_mj.config.rules.param`:
its default, unit, allowed range (pydantic's own constraints) and one line of
meaning, which are what ``simpro-sim show`` prints and what a refusal says.
Choices are ``Literal`` over the tuple of the module that uses them
(``controllers``, ``simpro_mj.plant``); the set-point components and faults
are discriminated unions; the rules across fields are model validators.

:func:`simpro_mj.config.scenario.load_scenario` merges a file and its ``--set``
overrides over the defaults (``Scenario.defaults()``) and validates the result
with :class:`Scenario`; ``model_dump()`` of it is the resolved scenario, the
plain dict that ``scenario.yaml`` holds and ``scenario_hash`` hashes.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Annotated, Any

from pydantic import (
    AfterValidator,
    BeforeValidator,
    Field,
    StrictBool,
    StrictStr,
    model_serializer,
    model_validator,
)

from controllers.dead_band import BandKind
from controllers.design import ACTUATORS, Plant, Reading, Variant, paper_plant, redesigned_design
from controllers.errors import DesignError
from controllers.joint import AntiWindup, Method
from controllers.setpoint_filter import Kind
from controllers.task_space import Integrator, JointLag, Lag
from simpro_mj.config.cue_models import Cueing
from simpro_mj.config.entries import Components, Faults
from simpro_mj.config.messages import validated
from simpro_mj.config.plant_blocks import Actuator, PlantBlock, SensorsBlock
from simpro_mj.config.presets import DEFAULT_PRESET
from simpro_mj.config.rules import (
    MAX_DECIMATION,
    MAX_DURATION_S,
    MIN_DURATION_S,
    NAME_RE,
    PHYSICS_DT_MS,
    DelaySamples,
    DesignPlant,
    Each,
    IdentifyChoice,
    Mode,
    Numbers,
    OuterType,
    Period,
)
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import Block, Problem, Real, Whole, block, integral, param, value_text
from simpro_mj.core.rates import whole_steps

#: Largest K K_I times the outer period: ten times the delay-free integrator's limit 2.
MAX_GAIN_PERIOD = 20.0

Gains = Numbers[list[float], Each(3, ge=0)]
Width = Annotated[Real, Field(ge=0, le=10)]


class OuterDeadBand(Block):
    """Dead band of the task-space loop per axis (0: none; docs/paper-notes.md, dead bands)."""

    roll_deg: Width = param(0.0, "deg", "dead band on the roll error")
    pitch_deg: Width = param(0.0, "deg", "dead band on the pitch error")
    heave_mm: Width = param(0.0, "mm", "dead band on the heave error")
    kind: BandKind = param(
        "subtract",
        "",
        "subtract: the law integrates e -+ w outside the band (continuous); gap: the whole "
        "e outside it (controllers.dead_band.gap), the last step into the band at full rate",
    )
    release: Real = param(
        1.0,
        "",
        "once the error is within the band the law holds until it leaves release times "
        "the band (1: the band alone): a seal's slip landing within it does not restart "
        "the law (docs/paper-notes.md, dead bands)",
        ge=1,
        le=20,
    )


class Outer(Block):
    """The task-space loop (eqs. 21-27, Fig. 7)."""

    type: OuterType = param("I", "", "the outer law: I (eq. 22) or PI (section 4)")
    gains: Gains = param(
        [3.0, 3.0, 3.0],
        "1/s",
        "K K_I per axis (roll, pitch, heave): section 5.2.3's 3; the analysed limit "
        "on the default plant is 11.8 (docs/paper-notes.md)",
    )
    pi_zero: Real = param(
        0.2, "", "c of the PI law T (z + c)/(z - 1), section 4 (type PI only)", gt=-1, lt=1
    )
    integrator: Integrator = param(
        "backward",
        "",
        "eq. (22)'s integral: backward T z/(z - 1) (the newest error at once) or forward "
        "T/(z - 1), Fig. 7 as printed (one more period of delay; docs/paper-notes.md)",
    )
    period_ms: Period = param(60, "ms", "outer sampling period T (a whole number of 1 ms steps)")
    delay_samples: Annotated[DelaySamples, BeforeValidator(integral)] = param(
        1, "samples", "the inner loop as a delay in the analysis: 1 (eq. 21) or 2"
    )
    joint_lag: JointLag = param(
        "none",
        "",
        "what the law integrates: none (the paper: the whole task error) or joints (less "
        "the joint loops' lag beyond their dead bands, J^-1 (q_d - q_meas): no wind-up "
        "while the legs travel; docs/paper-notes.md, controllers for the heavy cabin)",
    )
    dead_band: OuterDeadBand = block(
        OuterDeadBand,
        "dead band on the task error the law integrates (controllers.dead_band): within it "
        "the integrated pose holds, so the loop stops hunting against seal friction",
    )

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

    b: Real = param(12.51, "m/(s^3 V)", "gain b of the identified joint model", gt=0)
    a1: Real = param(15.78, "1/s", "a1 of the identified joint model", ge=0)
    a0: Real = param(78.92, "1/s^2", "a0 of the identified joint model", gt=0)


def _legs_2_3() -> JointModel:
    return JointModel(b=95.66, a1=17.37, a0=467.7)


class Identified(Block):
    """b / (s (s^2 + a1 s + a0)) per actuator, SI (m/V); set by the plant preset
    (plant.preset: what ``simpro-sim identify`` measures on it); the numbers here
    are the schema's only."""

    actuator1: JointModel = block(JointModel, "leg 1's identified model (eq. 34's form)")
    actuator2: JointModel = Field(
        default_factory=_legs_2_3, description="leg 2's identified model (eq. 35's form)"
    )
    actuator3: JointModel = Field(
        default_factory=_legs_2_3, description="leg 3's identified model (eq. 35's form)"
    )

    def plants(self) -> list[Plant]:
        """The three models as :class:`~controllers.design.Plant` (actuator 1, 2, 3)."""
        return [
            Plant(b=j.b, a1=j.a1, a0=j.a0) for j in (self.actuator1, self.actuator2, self.actuator3)
        ]


def _even_steps(value: float) -> float:
    if value != int(value) or int(value) % 2:
        raise Problem.invalid(value, "an even number >= 2 ms")
    return value


class Inner(Block):
    """The joint controllers (eqs. 28-29, 36-37)."""

    variant: Variant = param(
        "corrected", "", "joint controllers: eqs. (36)-(37) printed, corrected or redesigned"
    )
    discretisation: Method = param("tustin", "", "discretisation of the joint controllers")
    design_plant: DesignPlant = param(
        "auto",
        "",
        "plant the joint controllers are placed on: paper (eqs. 34-35), identified (this "
        "plant's, `simpro-sim identify`), auto (paper on the paper preset, else identified; "
        "scenario.yaml names the one used)",
    )
    identify: IdentifyChoice = param(
        "auto",
        "",
        "with design_plant identified: auto identifies the scenario's own plant when it is "
        "not its preset's (cached); preset takes the identified models as given; linearised "
        "fits the experiment's linear model instead of its record (seals that stick "
        "refused; simpro_mj.identification.linearised); reduced runs the experiment on "
        "the chain reduced to the slides with the step's own pneumatics and seals "
        "(simpro_mj.identification.reduced_experiment, cached)",
    )
    identified: Identified = block(Identified)
    zeta: Real = param(0.7, "", "damping of the redesigned pole placement (5.2.2)", gt=0, lt=2)
    wn_rad_s: Real = param(10.0, "rad/s", "natural frequency of the redesigned poles", gt=0)
    dead_band_mm: Numbers[list[float], Each(3, one=True, ge=0, le=50)] = param(
        [0.0, 0.0, 0.0], "mm", "dead band on each leg's error (controllers.dead_band)"
    )
    dead_band_release: Real = param(
        1.0,
        "",
        "once a leg's error has entered its dead band the band holds the leg's integrator "
        "until the error leaves this many bands (a hysteresis; 1: none; "
        "controllers.step_functions.joint_step)",
        ge=1,
        le=10,
    )
    dither_v: Real = param(
        0.0,
        "V",
        "valve dither (controllers.dither): a square wave of +-dither_v added to every valve "
        "command; 0: off",
        ge=0,
        le=5,
    )
    dither_period_ms: Annotated[Real, AfterValidator(_even_steps)] = param(
        40.0, "ms", "the dither's period: an even number of 1 ms steps", ge=2
    )
    anti_windup: AntiWindup = param(
        "back_calculation",
        "",
        "the integrators' anti-windup (controllers.joint): back_calculation (tracking "
        "time below), conditional (held only while growing into a rail: no pull towards "
        "the valve's centre from dither or sensor noise at the rails; docs/paper-notes.md) "
        "or none",
    )
    tracking_time_ms: Real = param(
        50.0, "ms", "back-calculation's tracking time T_t", gt=0, le=10000
    )


class Feedforward(Block):
    """Mode ``feedforward`` (docs/feedforward.md).

    The correction, with its own K K_I per axis (it only removes what the joint
    loops leave: slower than the paper's I law), integrates y_d - y less the
    joint loops' lag (``lag``), with ``lag: model``: M y_d - y, M a first-order
    lag of ``model_tau_ms`` (0: y_d - y), and skips an outer step after which a
    valve was at its rail (``hold_on_saturation``).
    """

    gains: Gains = param([1.0, 1.0, 1.0], "1/s", "K K_I of the correction per axis")
    model_tau_ms: Real = param(
        200.0, "ms", "time constant of M, the joint loops' lag (lag: model)", ge=0, le=10_000
    )
    hold_on_saturation: StrictBool = param(
        True, "", "skip an outer step after which a valve was at its rail"
    )
    lag: Lag = param(
        "joints",
        "",
        "the joint loops' lag taken out of the error: joints (measured) or model (M y_d); "
        "chosen by measurement (docs/feedforward.md)",
    )
    average: StrictBool = param(
        True, "", "the correction uses the means over the outer period, not one sample"
    )
    leg_velocity: StrictBool = param(
        True,
        "",
        "leg velocity feed-forward (a0/b) J dy_d/dt per leg (controllers.velocity_feedforward)",
    )


def _per_leg_steps(times: list[float]) -> list[float]:
    """Each time an integer multiple of the 1 ms step (the ramp averages whole steps)."""
    # 0 is refused by the range; whole_steps asks for at least one step
    if not all(whole_steps(v * 1e-3) is not None for v in times):
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

    type: Kind = param("ramp", "", "Fig. 13's filter: ramp, first_order, zero_cancel or none")
    time_ms: Annotated[
        Numbers[list[float], Each(3, one=True, gt=0, le=1e4)], AfterValidator(_per_leg_steps)
    ] = param([60.0, 30.0, 30.0], "ms", "the filter's time per leg (one number: every leg's)")


class Controller(Block):
    """The controllers: the mode, the task-space and joint loops, the feed-forward, the filter."""

    mode: Mode = param(
        "task_space",
        "",
        "joint_only (Fig. 15a), task_space (Fig. 15b) or feedforward (the set-point through "
        "the IK every 1 ms, the outer law adding a correction: docs/feedforward.md)",
    )
    outer: Outer = block(Outer)
    inner: Inner = block(Inner)
    feedforward: Feedforward = block(Feedforward)
    setpoint_filter: SetpointFilter = block(SetpointFilter)
    clamp_setpoints: StrictBool = param(
        False, "", "unreachable set-points: refused at load (false) or clamped (true)"
    )


class Logging(Block):
    """What a run logs."""

    decimation: Whole = param(1, "", "log every n-th 1 ms step", ge=1, le=MAX_DECIMATION)


class Setpoint(Block):
    """Per axis a list of components summed on top of the home pose; or a cueing block."""

    roll_deg: Components = param([], "deg", "roll set-point: components on top of home")
    pitch_deg: Components = param([], "deg", "pitch set-point: components on top of home")
    heave_mm: Components = param([], "mm", "heave set-point: components on top of home")
    # only in the resolved scenario when given, so that the scenarios without it
    # keep their hash
    cueing: Cueing | None = param(
        None, "", "set-points from vehicle motion through a cueing law (config.cueing)"
    )

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

    name: StrictStr = param(
        "",
        "",
        "the run's name (the file's stem if empty): letters, digits, '_', '-', '.' "
        "(a file-name-safe word of at most 100 characters)",
        pattern=NAME_RE.pattern,
        max_length=100,
    )
    paper_units: Reading = param(
        "volts",
        "",
        "unit of Y in eqs. (34)-(37): volts (the potentiometer's 20 V/m, as the rig reads "
        "it) or metres; sets the printed joint gains and the paper's design plants "
        "(docs/paper-notes.md, section 3)",
    )
    description: StrictStr = param("", "", "one line saying what the scenario is for")
    duration_s: Real = param(
        15.0, "s", "simulated time (at most one hour)", ge=MIN_DURATION_S, le=MAX_DURATION_S
    )
    seed: Whole = param(1, "", "seed of every random draw of the run (sensor noise)", ge=0,
                        lt=2**63)  # fmt: skip
    controller: Controller = block(Controller)
    actuator: Actuator = block(Actuator)
    plant: PlantBlock = block(PlantBlock)
    sensors: SensorsBlock = block(SensorsBlock)
    setpoint: Setpoint = block(Setpoint)
    faults: Faults = param([], "", "scheduled faults (simpro_mj.plant.faults)")
    logging: Logging = block(Logging)

    @model_validator(mode="after")
    def _across_blocks(self):
        _resolve_design_plant(self)
        _check_redesign(self)
        _check_fault_values(self)
        return self

    def supply_bar_gauge(self) -> float:
        """The supply pressure (bar gauge)."""
        return self.actuator.pneumatics.supply_pressure_bar_gauge


def _resolve_design_plant(s: Scenario) -> None:
    """``design_plant: auto``: ``paper`` (eqs. 34-35) on the preset calibrated to them, the
    plant's own identified models on any other (simpro_mj.identification.auto)."""
    inner = s.controller.inner
    if inner.design_plant == "auto":
        inner.design_plant = "paper" if s.plant.preset == DEFAULT_PRESET else "identified"


def _check_redesign(s: Scenario) -> None:
    """The pole placement of ``variant: redesigned`` must be feasible for every leg."""
    inner = s.controller.inner
    if inner.variant != "redesigned":
        return
    identified = inner.identified.plants()
    for i, act in enumerate(ACTUATORS):
        if inner.design_plant == "identified":
            plant = identified[i]
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
    return validated(Scenario, tree)


def as_scenario(scenario: Scenario | Mapping) -> Scenario:
    """The typed scenario of a resolved one: itself when typed, else validated
    (:func:`scenario_model`); what the run's readers take, a dict or the model."""
    return scenario if isinstance(scenario, Scenario) else scenario_model(scenario)


def as_tree(scenario: Scenario | Mapping) -> Mapping:
    """The resolved scenario's dict: itself when a mapping, else the model's dump."""
    return scenario.model_dump() if isinstance(scenario, Scenario) else scenario


def merge(base: Mapping, over: Mapping) -> dict:
    """Deep merge: a copy of ``base`` with ``over`` applied (mappings merge, others replace)."""
    out = copy.deepcopy(dict(base))
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


#: Every key of a scenario with its default (the typed scenario's), as a plain dict: what
#: a file is merged over (:func:`simpro_mj.config.scenario.load_scenario`) and what a
#: sweep's paths are checked against (:mod:`simpro_mj.config.sweep`).
DEFAULT_SCENARIO: dict = copy.deepcopy(dict(Scenario.defaults()))
