"""``actuator.pneumatics``: the valve and cylinder parameters of every leg, typed.

The plant owns the numbers (:data:`simpro_mj.plant.pneumatics.params.DEFAULT_PNEUMATIC_PARAMS`,
with their sources) and their plausible ranges (``PneumaticParams.from_tree``, the one
statement of them, which :class:`Pneumatics` runs once its fields are typed).
Here each key is a field with that default, its unit and one line of meaning:
what ``simpro-sim show`` lists, ``scenario.yaml`` holds whole and a refusal
names. A per-leg value is one number (every leg's) or three; it stays as given.

A new plant parameter: its default (and range) in the plant's tree, then one
:func:`_p` line in the block it belongs to here.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import BeforeValidator, StrictBool, TypeAdapter, ValidationError, model_validator

from simpro_mj.config.messages import validated
from simpro_mj.config.rules import Block, Problem, Real, Whole, block, param, yaml_number
from simpro_mj.core.errors import UserInputError
from simpro_mj.plant.pneumatics.params import (
    _PLAUSIBLE,
    DEFAULT_PNEUMATIC_PARAMS,
    FrictionModel,
    PneumaticParams,
    SupplyModel,
    ThermalModel,
)

__all__ = ["Pneumatics", "check_pneumatics"]

_REAL = TypeAdapter(Real)
_PER_LEG = "a number or a list of 3 numbers (one per leg)"


def _number(value: Any, allowed: str) -> float:
    try:
        return _REAL.validate_python(value)
    except ValidationError as exc:
        if exc.errors()[0]["type"] == "finite_number":
            raise Problem.invalid(value, f"a finite number; {allowed}") from None
        raise Problem.wrong_type(value, allowed) from None


def _per_leg(value: Any) -> float | list[float]:
    """One number for every leg, or three; kept as given (the plant broadcasts)."""
    value = yaml_number(value)
    if isinstance(value, list | tuple):
        if len(value) != 3:
            raise Problem.wrong_type(value, _PER_LEG)
        return [_number(v, _PER_LEG) for v in value]
    return _number(value, _PER_LEG)


#: A per-leg value: one number or three.
PerLeg = Annotated[float | list[float], BeforeValidator(_per_leg)]
OptionalPerLeg = Annotated[
    float | list[float] | None, BeforeValidator(lambda v: v if v is None else _per_leg(v))
]


def _p(path: str, unit: str, doc: str) -> Any:
    """The field of ``path`` (``cylinder.bore_mm``): the plant's default and plausible range."""
    node: Any = DEFAULT_PNEUMATIC_PARAMS
    for part in path.split("."):
        node = node[part]
    note = ""
    if path in _PLAUSIBLE:
        lo, hi, open_lo, why = _PLAUSIBLE[path]
        rng = f"{'>' if open_lo else '>='} {lo:g}" + (f" and <= {hi:g}" if hi < math.inf else "")
        note = f"{rng} ({why})"
    return param(node, unit, doc, note=note)


class Thermal(Block):
    """The chamber gas: polytropic, or each chamber's energy equation with wall heat."""

    model: ThermalModel = _p(
        "thermal.model",
        "",
        "polytropic: p V^n with polytropic_index at temperature_c; energy: each chamber's "
        "energy equation, heat exchanged with the wall at temperature_c",
    )
    ratio_of_specific_heats: Real = _p(
        "thermal.ratio_of_specific_heats", "", "gamma of the gas (dry air 1.4; energy model)"
    )
    heat_transfer_w_per_m2_k: Real = _p(
        "thermal.heat_transfer_w_per_m2_k",
        "W/(m^2 K)",
        "convective coefficient gas to wall (energy model; assumption)",
    )


class Supply(Block):
    """The compressed-air supply at the valves: ideal, or compressor, receiver, regulator."""

    model: SupplyModel = _p(
        "supply.model",
        "",
        "ideal: held at supply_pressure_bar_gauge; receiver: a compressor with a pressure "
        "switch fills a receiver, a regulator feeds the line (assumptions)",
    )
    compressor_flow_l_per_min: Real = _p(
        "supply.compressor_flow_l_per_min", "l/min ANR", "free air the compressor delivers"
    )
    receiver_volume_l: Real = _p("supply.receiver_volume_l", "l", "receiver volume")
    cut_in_bar_gauge: Real = _p(
        "supply.cut_in_bar_gauge", "bar gauge", "the pressure switch starts the compressor below"
    )
    cut_out_bar_gauge: Real = _p(
        "supply.cut_out_bar_gauge", "bar gauge", "and stops it above (> cut_in_bar_gauge)"
    )
    regulator_flow_l_per_min_per_bar: Real = _p(
        "supply.regulator_flow_l_per_min_per_bar",
        "l/min ANR per bar",
        "the regulator and line's flow at 1 bar of droop",
    )
    line_volume_l: Real = _p("supply.line_volume_l", "l", "the hoses' volume to the valves")


class Cylinder(Block):
    """The DNC-125-500 cylinder (ISO 15552) and its seals."""

    bore_mm: Real = _p("cylinder.bore_mm", "mm", "bore (DNC-125-500: 125 mm, type code)")
    rod_mm: Real = _p("cylinder.rod_mm", "mm", "rod diameter (ISO 15552 for a 125 bore)")
    stroke_mm: Real = _p("cylinder.stroke_mm", "mm", "stroke (type code: 500 mm)")
    dead_volume_cap_l: PerLeg = _p(
        "cylinder.dead_volume_cap_l", "l", "dead volume, cap side: cushioning, port, hose"
    )
    dead_volume_rod_l: PerLeg = _p(
        "cylinder.dead_volume_rod_l", "l", "dead volume, rod side: cushioning, port, hose"
    )
    viscous_friction_n_s_per_m: PerLeg = _p(
        "cylinder.viscous_friction_n_s_per_m", "N s/m", "viscous friction (calibrated per leg)"
    )
    coulomb_friction_n: PerLeg = _p(
        "cylinder.coulomb_friction_n", "N", "Coulomb (running) seal friction"
    )
    breakaway_friction_n: OptionalPerLeg = _p(
        "cylinder.breakaway_friction_n",
        "N",
        "static (breakaway) seal friction, >= the Coulomb force; null: Coulomb x breakaway_ratio",
    )
    breakaway_ratio: Real = _p(
        "cylinder.breakaway_ratio", "", "breakaway / Coulomb force (breakaway_friction_n null)"
    )
    stribeck_velocity_mm_per_s: Real = _p(
        "cylinder.stribeck_velocity_mm_per_s", "mm/s", "where the breakaway peak has fallen to 1/e"
    )
    friction_model: FrictionModel = _p(
        "cylinder.friction_model",
        "",
        "stick: MuJoCo's joint dry friction carries the breakaway (a seal under a smaller "
        "load sticks); regularised: tanh over coulomb_smoothing_mm_per_s (a loaded seal creeps)",
    )
    coulomb_smoothing_mm_per_s: Real = _p(
        "cylinder.coulomb_smoothing_mm_per_s", "mm/s", "regularising velocity (regularised only)"
    )
    stick_time_constant_ms: Real = _p(
        "cylinder.stick_time_constant_ms",
        "ms",
        "stick only: the time constant of MuJoCo's dry-friction constraint (solreffriction)",
    )
    stick_impedance: Real = _p(
        "cylinder.stick_impedance",
        "",
        "stick only: the impedance of MuJoCo's dry-friction constraint (solimpfriction)",
    )


class Valve(Block):
    """The FESTO MPYE-5-3/8 proportional valve (ISO 6358 flow)."""

    sonic_conductance_dm3_per_s_bar: Real = _p(
        "valve.sonic_conductance_dm3_per_s_bar",
        "dm^3/(s bar)",
        "sonic conductance C of one fully open metering edge",
    )
    critical_pressure_ratio: Real = _p(
        "valve.critical_pressure_ratio", "", "ISO 6358 critical pressure ratio b (0 .. 0.528)"
    )
    laminar_pressure_ratio: Real = _p(
        "valve.laminar_pressure_ratio", "", "start of the laminar region (0.9 .. 0.99999)"
    )
    underlap_fraction: PerLeg = _p(
        "valve.underlap_fraction", "", "underlap of each metering edge, fraction of the opening"
    )
    leakage_fraction: Real = _p(
        "valve.leakage_fraction", "", "clearance leakage of a covered edge, fraction of opening"
    )
    spool_order: Whole = _p("valve.spool_order", "", "spool response: 1 (first order) or 2")
    spool_bandwidth_hz: Real = _p("valve.spool_bandwidth_hz", "Hz", "spool bandwidth")
    spool_damping_ratio: Real = _p("valve.spool_damping_ratio", "", "a 2nd-order spool's damping")


class Integration(Block):
    """How the chamber pressures are integrated."""

    substeps: Whole = _p(
        "integration.substeps", "", "pressure sub-steps per 1 ms step (linearly implicit Euler)"
    )


class Linear(Block):
    """The linear model of eq. (19) (``actuator.model: linear``)."""

    b_m_per_s3_v: OptionalPerLeg = _p(
        "linear.b_m_per_s3_v", "m/(s^3 V)", "eq. (19)'s b per leg; null: eqs. (34)-(35)"
    )
    a1_per_s: OptionalPerLeg = _p("linear.a1_per_s", "1/s", "eq. (19)'s a1; null: eqs. (34)-(35)")
    a0_per_s2: OptionalPerLeg = _p(
        "linear.a0_per_s2", "1/s^2", "eq. (19)'s a0; null: eqs. (34)-(35)"
    )
    effective_mass_kg: OptionalPerLeg = _p(
        "linear.effective_mass_kg", "kg", "mass at each slide; null: MuJoCo's, reduced at home"
    )
    saturate_force: StrictBool = _p(
        "linear.saturate_force", "", "bound the force by the cylinder's, as the nonlinear model"
    )


class Pneumatics(Block):
    """Valve + cylinder of every leg (simpro_mj.plant.pneumatics), edge units in the keys."""

    supply_pressure_bar_gauge: Real = _p(
        "supply_pressure_bar_gauge", "bar gauge", "supply pressure at the valves (MPYE: 6 typical)"
    )
    atmospheric_pressure_kpa: Real = _p(
        "atmospheric_pressure_kpa", "kPa", "ambient pressure (ISO 2533 sea level)"
    )
    temperature_c: Real = _p("temperature_c", "deg C", "supply and chamber gas temperature")
    gas_constant_j_per_kg_k: Real = _p(
        "gas_constant_j_per_kg_k", "J/(kg K)", "specific gas constant (dry air)"
    )
    polytropic_index: Real = _p(
        "polytropic_index", "", "chamber gas polytropic index: 1 isothermal .. 1.4 adiabatic"
    )
    thermal: Thermal = block(Thermal)
    supply: Supply = block(Supply)
    cylinder: Cylinder = block(Cylinder)
    valve: Valve = block(Valve)
    integration: Integration = block(Integration)
    linear: Linear = block(Linear)

    def params(self) -> PneumaticParams:
        """The plant's parameter record of this block (SI)."""
        return PneumaticParams.from_tree(self.model_dump())

    @model_validator(mode="after")
    def _plausible(self):
        """The plant's own ranges and rules across its keys (``PneumaticParams.from_tree``)."""
        try:
            PneumaticParams.from_tree(self.model_dump())
        except UserInputError as exc:
            # the plant names its own tree "pneumatics"; the formatter puts it where it hangs
            head, _, rest = str(exc).partition(" at pneumatics")
            raise Problem(head, rest) from None
        return self


def check_pneumatics(value: Any, path: str = "actuator.pneumatics") -> dict:
    """A ``pneumatics`` tree on its own (``identify``'s), every key spelled out.

    Raises
    ------
    UserInputError
        One line naming the dotted key and what is allowed.
    """
    return validated(Pneumatics, value, path).model_dump()
