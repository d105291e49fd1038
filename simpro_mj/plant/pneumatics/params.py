"""Parameters of the electro-pneumatic actuators: the typed block and its SI record.

:class:`Pneumatics` is the ``pneumatics`` block (the scenario's
``actuator.pneumatics``): every number of the valve + cylinder model as a
pydantic field with its default, edge unit, plausible range (native
constraints, and why) and meaning; the rules across fields are its model
validators. :meth:`Pneumatics.params` converts a validated block to the SI
record :class:`PneumaticParams` the actuators are built from. A per-leg value
is one number (every leg's) or three, kept as given. This module must not
import MuJoCo: the scenario validates with it (``tests/test_api.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Annotated, Any, Literal, get_args

import annotated_types as at
import numpy as np
from pydantic import BeforeValidator, StrictBool, TypeAdapter, ValidationError, model_validator
from pydantic_core import PydanticKnownError, core_schema

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import (
    Block,
    Problem,
    Real,
    Whole,
    apply_overrides,
    block,
    closest,
    param,
    value_text,
    yaml_number,
)
from simpro_mj.plant.pneumatics.flow import RHO_REF  # ISO 6358's reference = ANR

U_CENTRE = 5.0  # V, closed centre of the MPYE
U_MAX = 10.0  # V

ActuatorKind = Literal["nonlinear", "linear"]
ACTUATOR_KINDS: tuple[ActuatorKind, ...] = get_args(ActuatorKind)
#: ``cylinder.friction_model``'s values (:mod:`simpro_mj.plant.friction`)
FrictionModel = Literal["stick", "regularised"]
#: ``supply.model``'s values (:func:`simpro_mj.plant.step_functions.supply_step`)
SupplyModel = Literal["ideal", "receiver"]
#: ``thermal.model``'s values (:func:`simpro_mj.plant.step_functions.chamber_energy`)
ThermalModel = Literal["polytropic", "energy"]

_REAL = TypeAdapter(Real)
_PER_LEG = "a number or a list of 3 numbers (one per leg)"


def _number(value: Any) -> float:
    try:
        return _REAL.validate_python(value)
    except ValidationError as exc:
        if exc.errors()[0]["type"] == "finite_number":
            raise Problem.invalid(value, f"a finite number; {_PER_LEG}") from None
        raise Problem.wrong_type(value, _PER_LEG) from None


def _per_leg(value: Any) -> Any:
    """One number for every leg, or three; kept as given (the record broadcasts)."""
    value = yaml_number(value)
    if isinstance(value, list | tuple):
        if len(value) != 3:
            raise Problem.wrong_type(value, _PER_LEG)
        return [_number(v) for v in value]
    return _number(value)


class Legs:
    """The range of each leg's value (``Annotated[PerLeg, Legs(ge=0, le=5000)]``):
    pydantic's own bound errors, the bounds where the error formatter and
    ``simpro-sim show`` read them (``metadata``)."""

    _ERRORS: dict[str, Literal["greater_than", "greater_than_equal", "less_than_equal"]] = {
        "gt": "greater_than",
        "ge": "greater_than_equal",
        "le": "less_than_equal",
    }

    def __init__(self, **bounds: float) -> None:
        self.bounds = bounds
        self.metadata = list(at.Interval(**bounds))

    def __get_pydantic_core_schema__(self, source: Any, handler: Any) -> Any:
        return core_schema.no_info_after_validator_function(self._check, handler(source))

    def _check(self, value: Any) -> Any:
        for x in [] if value is None else np.atleast_1d(value):
            for key, bound in self.bounds.items():
                if not {"gt": x > bound, "ge": x >= bound, "le": x <= bound}[key]:
                    raise PydanticKnownError(self._ERRORS[key], {key: bound})
        return value


#: A per-leg value: one number or three (``OptionalPerLeg``: or null).
PerLeg = Annotated[float | list[float], BeforeValidator(_per_leg)]
OptionalPerLeg = Annotated[
    float | list[float] | None, BeforeValidator(lambda v: v if v is None else _per_leg(v))
]


class Thermal(Block):
    """The chamber gas: polytropic, or each chamber's energy equation with wall heat.

    "polytropic": p V^n with polytropic_index and the gas at temperature_c (the
    calibrated paper preset's); "energy": each chamber's energy equation with its
    temperature as a state and heat exchanged with the wall at temperature_c
    (simpro_mj.plant.step_functions.chamber_energy; Richer & Hurmuzlu 2000,
    Carneiro & de Almeida 2006): charging near adiabatic, discharging cooler, the
    polytropic behaviour emerging from the heat flow.
    """

    model: ThermalModel = param(
        "polytropic",
        "",
        "polytropic: p V^n with polytropic_index at temperature_c; energy: each chamber's "
        "energy equation, heat exchanged with the wall at temperature_c",
    )
    ratio_of_specific_heats: Real = param(
        1.4, "", "gamma of the gas (dry air 1.4; energy model)", gt=1.0, le=1.67
    )
    # forced convection of a charging chamber is tens of W/(m^2 K) (assumption; the
    # effect of 10 and 100 is shown in docs/paper-notes.md, chamber thermodynamics)
    heat_transfer_w_per_m2_k: Real = param(
        30.0,
        "W/(m^2 K)",
        "convective coefficient gas to wall (energy model; assumption)",
        ge=0.0,
        le=1e4,
    )


class Supply(Block):
    """The compressed-air supply at the valves: ideal, or compressor, receiver, regulator.

    "ideal": a source held at supply_pressure_bar_gauge whatever the valves draw;
    "receiver", as built: a compressor with a pressure switch fills a receiver, a
    regulator set to supply_pressure_bar_gauge feeds the line to the valves
    (simpro_mj.plant.step_functions.supply_step). The numbers are assumptions, a
    workshop installation of the size a 3-4 kW piston compressor makes (no figures
    of the SIMPRO rig at hand); the regulator's flow is a G 1/2 regulator's
    catalogue order.
    """

    model: SupplyModel = param(
        "ideal",
        "",
        "ideal: held at supply_pressure_bar_gauge; receiver: a compressor with a pressure "
        "switch fills a receiver, a regulator feeds the line (assumptions)",
    )
    compressor_flow_l_per_min: Real = param(
        400.0, "l/min ANR", "free air the compressor delivers", ge=0.0, le=1e5
    )
    receiver_volume_l: Real = param(100.0, "l", "receiver volume", gt=0.0, le=1e5)
    cut_in_bar_gauge: Real = param(
        7.0, "bar gauge", "the pressure switch starts the compressor below", gt=0.0, le=16.0
    )
    cut_out_bar_gauge: Real = param(
        8.0, "bar gauge", "and stops it above (> cut_in_bar_gauge)", gt=0.0, le=16.0
    )
    regulator_flow_l_per_min_per_bar: Real = param(
        2000.0,
        "l/min ANR per bar",
        "the regulator and line's flow at 1 bar of droop",
        gt=0.0,
        le=1e6,
    )
    line_volume_l: Real = param(2.0, "l", "the hoses' volume to the valves", gt=0.0, le=1e3)

    @model_validator(mode="after")
    def _switch(self) -> Supply:
        """The pressure switch stops the compressor above where it starts it."""
        if self.cut_out_bar_gauge <= self.cut_in_bar_gauge:
            raise Problem.invalid(
                self.cut_out_bar_gauge,
                f"above supply.cut_in_bar_gauge ({self.cut_in_bar_gauge!r})",
                ".cut_out_bar_gauge",
            )
        return self


_DEAD = "the port and hose volume, 0.1 l here; 10 l is a tank"
_SEAL = "5 kN is 40 % of the cylinder's force"


class Cylinder(Block):
    """The DNC-125-500 cylinder (ISO 15552) and its seals.

    The dead volume of a chamber is its end-cap cushioning, port and
    valve-to-cylinder hose (3/8", ID ~ 10 mm); it and the viscous friction (the
    damping ratio of eqs. 34/35) are calibrated per leg, docs/paper-notes.md
    (pneumatics). The Coulomb force is kept low: its describing-function damping
    at PRBS speeds would dominate the paper's small damping of legs 2-3. The seal
    law is simpro_mj.plant.friction.seal_friction. "stick": MuJoCo's joint dry
    friction (frictionloss, solved with the constraints) carries the breakaway
    force, so a seal under a smaller load sticks, the drop to the Coulomb force
    with speed (Stribeck) added explicitly; "regularised": the whole map in the
    pneumatic force, tanh over coulomb_smoothing_mm_per_s (a seal under any load
    creeps). The stick model's constraint yields by about (1 - impedance) of what
    it holds and recovers within its time constant; 2 ms (two 1 ms steps) and
    0.9999 are the stiffest MuJoCo integrates and accepts (halving or doubling
    them: docs/paper-notes.md, numerical parameters).
    """

    bore_mm: Real = param(
        125.0,
        "mm",
        "bore (DNC-125-500: 125 mm, type code)",
        why="ISO 15552 and catalogue bores",
        ge=8.0,
        le=320.0,
    )
    # ISO 15552 rod for a 125 bore (assumption, not read from a datasheet)
    rod_mm: Real = param(32.0, "mm", "rod diameter (ISO 15552 for a 125 bore)", gt=0.0)
    stroke_mm: Real = param(
        500.0,
        "mm",
        "stroke (type code: 500 mm)",
        why="catalogue strokes; the model has 500",
        ge=10.0,
        le=3000.0,
    )
    dead_volume_cap_l: Annotated[PerLeg, Legs(ge=1e-4, le=10.0)] = param(
        [0.10, 0.10, 0.10], "l", "dead volume, cap side: cushioning, port, hose", why=_DEAD
    )
    dead_volume_rod_l: Annotated[PerLeg, Legs(ge=1e-4, le=10.0)] = param(
        [0.10, 0.10, 0.10], "l", "dead volume, rod side: cushioning, port, hose", why=_DEAD
    )
    viscous_friction_n_s_per_m: Annotated[PerLeg, Legs(ge=0.0, le=1e5)] = param(
        [11000.0, 600.0, 600.0],
        "N s/m",
        "viscous friction (calibrated per leg)",
        why="seal friction of a DNC-125 is hundreds to about 10,000; at 1e5 N s/m 0.1 m/s "
        "takes 10 kN, nearly all the cylinder makes",
    )
    coulomb_friction_n: Annotated[PerLeg, Legs(ge=0.0, le=5000.0)] = param(
        [20.0, 20.0, 20.0],
        "N",
        "Coulomb (running) seal friction",
        why=f"tens to a few hundred for a DNC-125; {_SEAL}",
    )
    breakaway_friction_n: Annotated[OptionalPerLeg, Legs(ge=0.0, le=5000.0)] = param(
        None,
        "N",
        "static (breakaway) seal friction, >= the Coulomb force; null: Coulomb x breakaway_ratio",
        why=f"at least the Coulomb force; {_SEAL}",
    )
    # a seal's breakaway follows its running friction: a sweep over the Coulomb force
    # then draws whole seals
    breakaway_ratio: Real = param(
        1.0,
        "",
        "breakaway / Coulomb force (breakaway_friction_n null)",
        why="1 (no peak) to about 2 for lip seals",
        ge=1.0,
        le=10.0,
    )
    stribeck_velocity_mm_per_s: Real = param(
        10.0,
        "mm/s",
        "where the breakaway peak has fallen to 1/e",
        why="where the breakaway peak decays, a few to tens of mm/s (assumption)",
        gt=1e-3,
        le=1000.0,
    )
    friction_model: FrictionModel = param(
        "stick",
        "",
        "stick: MuJoCo's joint dry friction carries the breakaway (a seal under a smaller "
        "load sticks); regularised: tanh over coulomb_smoothing_mm_per_s (a loaded seal creeps)",
    )
    coulomb_smoothing_mm_per_s: Real = param(
        5.0,
        "mm/s",
        "regularising velocity (regularised only)",
        why="the speed over which the friction changes sign (assumption)",
        ge=1e-3,
        le=1000.0,
    )
    stick_time_constant_ms: Real = param(
        2.0,
        "ms",
        "stick only: the time constant of MuJoCo's dry-friction constraint (solreffriction)",
        why="two 1 ms steps is the stiffest MuJoCo integrates",
        ge=2.0,
        le=100.0,
    )
    stick_impedance: Real = param(
        0.9999,
        "",
        "stick only: the impedance of MuJoCo's dry-friction constraint (solimpfriction)",
        why="MuJoCo's impedance: at most 0.9999, its own limit",
        ge=0.9,
        le=0.9999,
    )
    # A stuck seal held without creep: MuJoCo's noslip pass (opt.noslip_iterations, a
    # projected Gauss-Seidel solve of the friction rows without the constraint's
    # softness) after each step's solve. Without it a held seal creeps at
    # (1 - impedance) a0 / b, a0 the acceleration its load alone gives the slide: 4-12
    # um/s on the cabin's legs at 250-750 N breakaway, enough to walk a held pose out of
    # the loops' bands within seconds (docs/paper-notes.md, a stick without creep). The
    # pass stops at MuJoCo's tolerance: the count bounds the work (5 and 20 give the
    # same runs). 0 (off): the paper's calibration was made without it and its 1.7 N
    # seals hold too little to creep; heavy_cabin ships 10.
    stick_noslip_iterations: Whole = param(
        0,
        "",
        "stick only: MuJoCo's noslip passes per step, a stuck seal held without creep "
        "(opt.noslip_iterations; 0: off)",
        why="MuJoCo's noslip passes per step: 0 (off) to 1000",
        ge=0,
        le=1000,
    )

    @model_validator(mode="after")
    def _seals(self) -> Cylinder:
        """The rod inside the bore; the breakaway force given once, at least the Coulomb's."""
        if self.rod_mm > self.bore_mm * 0.999:
            rest = f"> 0 and <= {self.bore_mm * 0.999:g} (inside the bore)"
            raise Problem.invalid(self.rod_mm, rest, ".rod_mm")
        if self.breakaway_friction_n is None:
            return self
        if self.breakaway_ratio != 1.0:
            raise Problem.invalid(
                self.breakaway_ratio,
                "1 when cylinder.breakaway_friction_n is set (set one of the two)",
                ".breakaway_ratio",
            )
        coulomb = np.broadcast_to(np.asarray(self.coulomb_friction_n, float), (3,))
        if np.any(np.asarray(self.breakaway_friction_n, float) < coulomb):
            raise Problem.invalid(
                self.breakaway_friction_n,
                f"null or, per leg, at least cylinder.coulomb_friction_n ({coulomb.tolist()})",
                ".breakaway_friction_n",
            )
        return self


class Valve(Block):
    """The FESTO MPYE-5-3/8 proportional valve (ISO 6358 flow).

    The sonic conductance of one fully open metering edge follows from the
    MPYE-5-3/8 nominal flow 2000 l/min (ANR, 6 -> 5 bar gauge, Festo catalogue;
    assumption, no datasheet at hand) with b = 0.3:
    C = qn / (p1 sqrt(1 - ((6/7 - b)/(1 - b))^2)) = 7.87 dm^3/(s bar). The
    critical pressure ratio is an assumption (spool valves 0.2-0.45); ISO 6358-3
    starts the laminar region at 0.999. The underlap (Rubio 2009's underlap
    leakage) is calibrated per leg; the clearance leakage is an assumption. The
    spool (MPYE data not at hand): Project Chrono's valve 35 Hz, servo-valves
    50-120 Hz.
    """

    sonic_conductance_dm3_per_s_bar: Real = param(
        7.87,
        "dm^3/(s bar)",
        "sonic conductance C of one fully open metering edge",
        why="the MPYE-5-3/8 has 7.87; 100 is a valve far beyond the cylinder's ports",
        ge=0.01,
        le=100.0,
    )
    critical_pressure_ratio: Real = param(
        0.3, "", "ISO 6358 critical pressure ratio b", ge=0.0, le=0.528
    )
    laminar_pressure_ratio: Real = param(
        0.999, "", "start of the laminar region", gt=0.9, le=0.99999
    )
    underlap_fraction: Annotated[PerLeg, Legs(ge=0.0, le=0.5)] = param(
        [0.02, 0.02, 0.02], "", "underlap of each metering edge, fraction of the opening"
    )
    leakage_fraction: Real = param(
        0.002, "", "clearance leakage of a covered edge, fraction of opening", gt=0.0, le=0.5
    )
    spool_order: Whole = param(1, "", "spool response: 1 (first order) or 2", ge=1, le=2)
    spool_bandwidth_hz: Real = param(
        60.0, "Hz", "spool bandwidth", why="the MPYE's spool, about 60-100", ge=1.0, le=1000.0
    )
    spool_damping_ratio: Real = param(
        0.8, "", "a 2nd-order spool's damping", why="a second-order spool's damping", ge=0.01,
        le=10.0,
    )  # fmt: skip


class Integration(Block):
    """How the chamber pressures are integrated."""

    substeps: Whole = param(
        1, "", "pressure sub-steps per 1 ms step (linearly implicit Euler)", gt=0, le=1000
    )


class Linear(Block):
    """The linear model of eq. (19) (``actuator.model: linear``).

    Null coefficients: eq. (34) for actuator 1 and eq. (35) for actuators 2, 3 in
    SI under the scenario's paper_units reading, filled in by the caller
    (:func:`fill_linear`; the plant knows no paper reading). A null mass: MuJoCo's
    full mass matrix reduced to the slides at home (make_actuators).
    """

    b_m_per_s3_v: Annotated[OptionalPerLeg, Legs(ge=0.0)] = param(
        None, "m/(s^3 V)", "eq. (19)'s b per leg; null: eqs. (34)-(35)"
    )
    a1_per_s: Annotated[OptionalPerLeg, Legs(ge=0.0)] = param(
        None, "1/s", "eq. (19)'s a1; null: eqs. (34)-(35)"
    )
    a0_per_s2: Annotated[OptionalPerLeg, Legs(gt=0.0)] = param(
        None, "1/s^2", "eq. (19)'s a0; null: eqs. (34)-(35)"
    )
    effective_mass_kg: Annotated[OptionalPerLeg, Legs(gt=0.0)] = param(
        None, "kg", "mass at each slide; null: MuJoCo's, reduced at home"
    )
    saturate_force: StrictBool = param(
        True, "", "bound the force by the cylinder's, as the nonlinear model"
    )


def _legs(value: Any) -> Any:
    """A per-leg value as 3 floats; None stays None."""
    if value is None:
        return None
    arr = np.asarray(value, dtype=float)
    return np.full(3, float(arr)) if arr.ndim == 0 else arr


class Pneumatics(Block):
    """Valve + cylinder of every leg (simpro_mj.plant.pneumatics), edge units in the keys.

    The supply: a FESTO MPYE's typical 6 bar gauge (Festo operating range
    0-10 bar). The polytropic index 1.4 (adiabatic): the small-signal oscillation
    (1-6 Hz) is much faster than the wall heat exchange of a 125 mm chamber
    (seconds), Richer & Hurmuzlu 2000 sec. 2.2; calibrated, the stiffest physical
    choice (docs/paper-notes.md, pneumatics).
    """

    supply_pressure_bar_gauge: Real = param(
        6.0,
        "bar gauge",
        "supply pressure at the valves (MPYE: 6 typical)",
        why="the MPYE valve and DNC cylinders are rated to 10-12 bar",
        gt=0.0,
        le=12.0,
    )
    atmospheric_pressure_kpa: Real = param(
        101.325,
        "kPa",
        "ambient pressure (ISO 2533 sea level)",
        why="from the top of Mount Everest (33) to below sea level (107)",
        ge=30.0,
        le=110.0,
    )
    temperature_c: Real = param(
        20.0,
        "deg C",
        "supply and chamber gas temperature",
        why="the seals' and the valve's rating",
        ge=-40.0,
        le=100.0,
    )
    gas_constant_j_per_kg_k: Real = param(
        287.05,
        "J/(kg K)",
        "specific gas constant (dry air)",
        why="air 287, nitrogen 297; the model is for such gases",
        ge=200.0,
        le=500.0,
    )
    polytropic_index: Real = param(
        1.4,
        "",
        "chamber gas polytropic index: 1 isothermal .. 1.4 adiabatic",
        why="isothermal 1 .. adiabatic monatomic 1.67",
        ge=1.0,
        le=1.67,
    )
    thermal: Thermal = block(Thermal)
    supply: Supply = block(Supply)
    cylinder: Cylinder = block(Cylinder)
    valve: Valve = block(Valve)
    integration: Integration = block(Integration)
    linear: Linear = block(Linear)

    def params(self) -> PneumaticParams:
        """The plant's parameter record of this block (SI)."""
        cyl, valve, sup, lin = self.cylinder, self.valve, self.supply, self.linear
        p_atm = self.atmospheric_pressure_kpa * 1e3
        bore, rod = cyl.bore_mm * 1e-3, cyl.rod_mm * 1e-3
        a1 = math.pi / 4 * bore**2
        coulomb = _legs(cyl.coulomb_friction_n)
        breakaway = _legs(cyl.breakaway_friction_n)
        return PneumaticParams(
            p_supply=self.supply_pressure_bar_gauge * 1e5 + p_atm,
            p_atm=p_atm,
            temperature=self.temperature_c + 273.15,
            gas_constant=self.gas_constant_j_per_kg_k,
            n_poly=self.polytropic_index,
            area_cap=a1,
            area_rod_side=a1 - math.pi / 4 * rod**2,
            stroke=cyl.stroke_mm * 1e-3,
            dead_cap=_legs(cyl.dead_volume_cap_l) * 1e-3,
            dead_rod=_legs(cyl.dead_volume_rod_l) * 1e-3,
            viscous=_legs(cyl.viscous_friction_n_s_per_m),
            coulomb=coulomb,
            breakaway=coulomb * cyl.breakaway_ratio if breakaway is None else breakaway,
            v_stribeck=cyl.stribeck_velocity_mm_per_s * 1e-3,
            v_smooth=cyl.coulomb_smoothing_mm_per_s * 1e-3,
            friction_model=cyl.friction_model,
            stick_solref=cyl.stick_time_constant_ms * 1e-3,
            stick_solimp=cyl.stick_impedance,
            stick_noslip=cyl.stick_noslip_iterations,
            thermal_model=self.thermal.model,
            supply_model=sup.model,
            compressor_flow=sup.compressor_flow_l_per_min * RHO_REF / 60e3,
            receiver_volume=sup.receiver_volume_l * 1e-3,
            line_volume=sup.line_volume_l * 1e-3,
            cut_in=sup.cut_in_bar_gauge * 1e5 + p_atm,
            cut_out=sup.cut_out_bar_gauge * 1e5 + p_atm,
            regulator_conductance=sup.regulator_flow_l_per_min_per_bar * RHO_REF / 60e3 / 1e5,
            gamma=self.thermal.ratio_of_specific_heats,
            heat_transfer=self.thermal.heat_transfer_w_per_m2_k,
            conductance=valve.sonic_conductance_dm3_per_s_bar * 1e-3 / 1e5,
            b_crit=valve.critical_pressure_ratio,
            r_laminar=valve.laminar_pressure_ratio,
            underlap=_legs(valve.underlap_fraction),
            leakage=valve.leakage_fraction,
            spool_order=valve.spool_order,
            spool_omega=2 * math.pi * valve.spool_bandwidth_hz,
            spool_zeta=valve.spool_damping_ratio,
            substeps=self.integration.substeps,
            lin_b=_legs(lin.b_m_per_s3_v),
            lin_a1=_legs(lin.a1_per_s),
            lin_a0=_legs(lin.a0_per_s2),
            lin_mass=_legs(lin.effective_mass_kg),
            lin_saturate=lin.saturate_force,
        )


#: The block's defaults as a plain tree, edge units in the key names.
DEFAULT_PNEUMATIC_PARAMS: dict = dict(Pneumatics.defaults())


def pneumatic_params(overrides=None, base: dict | None = None) -> dict:
    """Default actuator parameter tree with ``--set``-style overrides applied."""
    return apply_overrides(DEFAULT_PNEUMATIC_PARAMS if base is None else base, overrides or [])


def typed(tree: Any = None) -> Pneumatics:
    """A ``pneumatics`` tree (None: the defaults) as the typed block, or one line.

    The scenario validates its block with the scenario's formatter; this one
    serves a tree handed to the plant directly.

    Raises
    ------
    UserInputError
        ``<what> at pneumatics.<dotted key>: <value>; allowed: ...``.
    """
    if isinstance(tree, Pneumatics):
        return tree
    try:
        return Pneumatics.model_validate({} if tree is None else tree)
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        err = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
        where = ".".join(map(str, ("pneumatics", *err["loc"])))
        cause = (err.get("ctx") or {}).get("error")
        if isinstance(cause, Problem):
            raise UserInputError(f"{cause.head} at {where}{cause.suffix}{cause.rest}") from None
        kind, allowed = err["type"], str(err["msg"])
        head = "wrong type" if kind.endswith("_type") else "invalid value"
        if kind == "extra_forbidden":
            model: Any = Pneumatics
            for part in err["loc"][:-1]:
                model = model.model_fields[part].annotation
            head, key = "unknown key", str(err["loc"][-1])
            allowed = f"one of {sorted(model.model_fields)}{closest(key, model.model_fields)}"
        got = value_text(err.get("input"))
        raise UserInputError(f"{head} at {where}: {got}; allowed: {allowed}") from None


@dataclass(frozen=True)
class PneumaticParams:
    """Actuator parameters in SI units (:meth:`Pneumatics.params`).

    Arrays have one entry per leg.
    """

    p_supply: float  # Pa absolute
    p_atm: float  # Pa
    temperature: float  # K
    gas_constant: float  # J/(kg K)
    n_poly: float
    area_cap: float  # m^2
    area_rod_side: float  # m^2 (annulus)
    stroke: float  # m
    dead_cap: np.ndarray  # m^3
    dead_rod: np.ndarray  # m^3
    viscous: np.ndarray  # N s/m
    coulomb: np.ndarray  # N
    breakaway: np.ndarray  # N, >= coulomb
    v_stribeck: float  # m/s
    v_smooth: float  # m/s, the regularising velocity of the seal friction
    friction_model: str  # "stick" or "regularised"
    stick_solref: float  # s, the stick model's constraint time constant
    stick_solimp: float  # the stick model's constraint impedance
    stick_noslip: int  # the stick model's noslip passes per step (0: off)
    thermal_model: str  # "polytropic" or "energy"
    supply_model: str  # "ideal" or "receiver"
    compressor_flow: float  # kg/s
    receiver_volume: float  # m^3
    line_volume: float  # m^3
    cut_in: float  # Pa absolute
    cut_out: float  # Pa absolute
    regulator_conductance: float  # kg/(s Pa)
    gamma: float  # ratio of specific heats
    heat_transfer: float  # W/(m^2 K)
    conductance: float  # m^3/(s Pa)
    b_crit: float
    r_laminar: float
    underlap: np.ndarray
    leakage: float
    spool_order: int
    spool_omega: float  # rad/s
    spool_zeta: float
    substeps: int
    lin_b: np.ndarray | None  # None: to be filled by make_actuators(linear_plants=)
    lin_a1: np.ndarray | None
    lin_a0: np.ndarray | None
    lin_mass: np.ndarray | None
    lin_saturate: bool

    @classmethod
    def from_tree(cls, tree: Any = None) -> PneumaticParams:
        """The record of a ``pneumatics`` tree or block (:func:`typed`; None: defaults).

        Raises
        ------
        UserInputError
            For unknown keys or out-of-range values (the message names the path).
        """
        return typed(tree).params()

    @property
    def area_rod(self) -> float:
        """Rod cross-section A_1 - A_2 (m^2), where the atmosphere pushes."""
        return self.area_cap - self.area_rod_side

    @property
    def force_range(self) -> tuple[float, float]:
        """(min, max) pneumatic force with the chambers at the pressure bounds (N)."""
        return self.force_range_at(self.p_supply)

    def force_range_at(self, ps: float) -> tuple[float, float]:
        """:attr:`force_range` for a supply pressure ``ps`` (Pa absolute)."""
        pa = self.p_atm
        return (
            pa * self.area_cap - ps * self.area_rod_side - pa * self.area_rod,
            ps * self.area_cap - pa * self.area_rod_side - pa * self.area_rod,
        )


def fill_linear(P: PneumaticParams, linear_plants=None) -> PneumaticParams:
    """``P`` with its null ``linear`` coefficients taken from ``linear_plants``.

    ``linear_plants`` is ``(b, a1, a0)``, three per-leg sequences in SI (the
    caller's eqs. 34-35 under its units reading). Raises
    :class:`UserInputError` if a coefficient stays undefined.
    """
    have: dict[str, Any] = {"lin_b": P.lin_b, "lin_a1": P.lin_a1, "lin_a0": P.lin_a0}
    keys = {"lin_b": "b_m_per_s3_v", "lin_a1": "a1_per_s", "lin_a0": "a0_per_s2"}
    for i, name in enumerate(have):
        if have[name] is None:
            if linear_plants is None:
                raise UserInputError(
                    f"missing value at pneumatics.linear.{keys[name]}: null; allowed: a number "
                    "or 3 numbers (eq. 19 in SI), or a caller that supplies eqs. 34-35"
                )
            have[name] = np.broadcast_to(np.asarray(linear_plants[i], float), (3,)).copy()
    return replace(P, **have)
