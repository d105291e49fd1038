"""Parameters of the electro-pneumatic actuators: the typed block and its SI record.

:class:`Pneumatics` is the ``pneumatics`` block (the scenario's
``actuator.pneumatics``): every number of the valve + cylinder model as a
pydantic field with its default, edge unit, plausible range (native
constraints, and why) and meaning, its parts in
:mod:`simpro_mj.plant.pneumatics.parts`; the rules across fields are its model
validators. :meth:`Pneumatics.params` converts a validated block to the SI
record :class:`PneumaticParams` the actuators are built from. A per-leg value
is one number (every leg's) or three, kept as given. This module must not
import MuJoCo: the scenario validates with it (``tests/test_api.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Literal, get_args

import numpy as np
from pydantic import ValidationError

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import (
    Block,
    Problem,
    Real,
    apply_overrides,
    block,
    closest,
    param,
    value_text,
)
from simpro_mj.plant.pneumatics.flow import RHO_REF  # ISO 6358's reference = ANR
from simpro_mj.plant.pneumatics.parts import Cylinder, Integration, Linear, Supply, Thermal, Valve

U_CENTRE = 5.0  # V, closed centre of the MPYE
U_MAX = 10.0  # V

ActuatorKind = Literal["nonlinear", "linear"]
ACTUATOR_KINDS: tuple[ActuatorKind, ...] = get_args(ActuatorKind)


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
