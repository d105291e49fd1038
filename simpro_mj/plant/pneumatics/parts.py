"""The parts of the ``pneumatics`` block: the gas, the supply, the cylinder, the valve.

Typed sub-blocks of :class:`simpro_mj.plant.pneumatics.params.Pneumatics`: every
number with its default, edge unit, plausible range (pydantic's native
constraints, and why) and meaning, and the per-leg value type (:data:`PerLeg`:
one number for every leg or three, kept as given; :class:`Legs`: its range).
Like the block, this module must not import MuJoCo.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import annotated_types as at
import numpy as np
from pydantic import BeforeValidator, StrictBool, TypeAdapter, ValidationError, model_validator
from pydantic_core import PydanticKnownError, core_schema

from simpro_mj.core.keys import Block, Problem, Real, Whole, param, yaml_number

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
