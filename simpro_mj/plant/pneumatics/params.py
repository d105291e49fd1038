"""Parameters of the electro-pneumatic actuators: defaults, the SI record, checks.

Every number of the valve + cylinder model lives here, edge units in the key
names (:data:`DEFAULT_PNEUMATIC_PARAMS`); :meth:`PneumaticParams.from_tree`
validates a ``pneumatics`` tree against it (one-line errors naming the path)
and converts it to SI. The scenario (``simpro_mj.config``) validates its
``actuator.pneumatics`` block with it, so this module must not import MuJoCo
(``tests/test_api.py`` checks it).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal, get_args

import numpy as np

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import apply_overrides, check_keys
from simpro_mj.plant.pneumatics.flow import RHO_REF  # ISO 6358's reference = ANR

__all__ = [
    "DEFAULT_PNEUMATIC_PARAMS",
    "ACTUATOR_KINDS",
    "FRICTION_MODELS",
    "THERMAL_MODELS",
    "SUPPLY_MODELS",
    "U_CENTRE",
    "U_MAX",
    "PneumaticParams",
    "pneumatic_params",
    "fill_linear",
]

U_CENTRE = 5.0  # V, closed centre of the MPYE
U_MAX = 10.0  # V

ActuatorKind = Literal["nonlinear", "linear"]
ACTUATOR_KINDS: tuple[ActuatorKind, ...] = get_args(ActuatorKind)

#: ``cylinder.friction_model``'s values (:mod:`simpro_mj.plant.friction`)
FrictionModel = Literal["stick", "regularised"]
FRICTION_MODELS: tuple[FrictionModel, ...] = get_args(FrictionModel)

#: ``supply.model``'s values (:func:`simpro_mj.plant.step_functions.supply_step`)
SupplyModel = Literal["ideal", "receiver"]
SUPPLY_MODELS: tuple[SupplyModel, ...] = get_args(SupplyModel)

#: ``thermal.model``'s values (:func:`simpro_mj.plant.step_functions.chamber_energy`)
ThermalModel = Literal["polytropic", "energy"]
THERMAL_MODELS: tuple[ThermalModel, ...] = get_args(ThermalModel)

#: Parameters of the actuators, edge units in the key names. Per-leg values
#: are lists [leg1, leg2, leg3]; a scalar applies to all three legs.
DEFAULT_PNEUMATIC_PARAMS: dict = {
    # FESTO MPYE: 6 bar gauge typical supply (brief; Festo operating range 0-10 bar)
    "supply_pressure_bar_gauge": 6.0,
    "atmospheric_pressure_kpa": 101.325,  # ISO 2533 sea level
    "temperature_c": 20.0,  # supply and chamber gas temperature (assumption)
    "gas_constant_j_per_kg_k": 287.05,  # dry air
    # Polytropic index of the chamber gas. 1.4 (adiabatic): the small-signal
    # oscillation (1-6 Hz) is much faster than the wall heat exchange of a
    # 125 mm chamber (seconds), Richer & Hurmuzlu 2000 sec. 2.2. Calibrated
    # (the stiffest physical choice, see docs/paper-notes.md (pneumatics)).
    "polytropic_index": 1.4,
    # The chamber gas: "polytropic", p V^n with polytropic_index and the gas at
    # temperature_c (the calibrated paper preset's); "energy", each chamber's energy
    # equation with its temperature as a state and heat exchanged with the wall at
    # temperature_c (simpro_mj.plant.step_functions.chamber_energy; Richer & Hurmuzlu
    # 2000, Carneiro & de Almeida 2006): charging near adiabatic, discharging cooler,
    # the polytropic behaviour emerging from the heat flow
    "thermal": {
        "model": "polytropic",
        "ratio_of_specific_heats": 1.4,  # dry air
        # convective coefficient gas-to-wall (assumption: forced convection of a
        # charging chamber is tens of W/(m^2 K); the effect of 10 and 100 is shown in
        # docs/paper-notes.md, chamber thermodynamics)
        "heat_transfer_w_per_m2_k": 30.0,
    },
    # The compressed-air supply at the valves: "ideal", a source held at
    # supply_pressure_bar_gauge whatever the valves draw; "receiver", as built: a
    # compressor with a pressure switch fills a receiver, a regulator set to
    # supply_pressure_bar_gauge feeds the line to the valves (simpro_mj.plant.
    # step_functions.supply_step). Assumptions, a workshop installation of the size
    # a 3-4 kW piston compressor makes (no figures of the SIMPRO rig at hand):
    "supply": {
        "model": "ideal",
        "compressor_flow_l_per_min": 400.0,  # free air delivered (ANR)
        "receiver_volume_l": 100.0,
        "cut_in_bar_gauge": 7.0,  # the pressure switch starts the compressor below it
        "cut_out_bar_gauge": 8.0,  # and stops it above it
        # the regulator and line: flow at 1 bar of droop, l/min ANR (a G 1/2
        # regulator's catalogue order), and the hoses' volume to the three valves
        "regulator_flow_l_per_min_per_bar": 2000.0,
        "line_volume_l": 2.0,
    },
    "cylinder": {
        # DNC-125-500 (ISO 15552): bore 125 mm, stroke 500 mm (type code)
        "bore_mm": 125.0,
        # ISO 15552 rod for 125 bore (assumption, not read from a datasheet)
        "rod_mm": 32.0,
        "stroke_mm": 500.0,
        # Dead volume per chamber: end-cap cushioning + port + valve-to-cylinder
        # hose (3/8" hose, ID ~ 10 mm). Calibrated, see docs/paper-notes.md (pneumatics).
        "dead_volume_cap_l": [0.10, 0.10, 0.10],
        "dead_volume_rod_l": [0.10, 0.10, 0.10],
        # Viscous friction coefficient, N s/m. Calibrated per leg (damping
        # ratio of eqs. 34/35), see docs/paper-notes.md (pneumatics).
        "viscous_friction_n_s_per_m": [11000.0, 600.0, 600.0],
        # Coulomb (seal) friction, N: low-friction seals (assumption, kept low:
        # its describing-function damping at PRBS speeds would dominate the
        # paper's small damping of legs 2-3, see docs/paper-notes.md (pneumatics))
        "coulomb_friction_n": [20.0, 20.0, 20.0],
        # Static (breakaway) friction, N, >= the Coulomb force; null: equal to it
        # (no Stribeck peak). The seal law is simpro_mj.plant.friction.seal_friction.
        "breakaway_friction_n": None,
        # breakaway / Coulomb force, used when breakaway_friction_n is null: a
        # seal's breakaway follows its running friction (a sweep over the Coulomb
        # force then draws whole seals); 1: no Stribeck peak
        "breakaway_ratio": 1.0,
        # Stribeck velocity, mm/s: where the breakaway peak has fallen to 1/e
        # (assumption; only a breakaway_friction_n above the Coulomb force uses it)
        "stribeck_velocity_mm_per_s": 10.0,
        # How the dry friction acts. "stick": MuJoCo's joint dry friction
        # (frictionloss, solved with the constraints) carries the breakaway force, so
        # a seal under a smaller load sticks; the drop to the Coulomb force with speed
        # (Stribeck) is added explicitly (simpro_mj.plant.friction). "regularised":
        # the whole map in the pneumatic force, tanh over coulomb_smoothing_mm_per_s
        # (a seal under any load creeps)
        "friction_model": "stick",
        # regularising velocity of the "regularised" dry friction (tanh), mm/s: below
        # it the seal acts as a damper of slope breakaway / velocity (assumption)
        "coulomb_smoothing_mm_per_s": 5.0,
        # the "stick" model's constraint softness (MuJoCo's solreffriction time
        # constant and solimpfriction impedance): a stuck seal yields by about
        # (1 - impedance) of what it holds and recovers within the time constant;
        # 2 ms (two 1 ms steps) and 0.9999 are the stiffest MuJoCo integrates and
        # accepts (numerical choices: halving or doubling them is checked in
        # docs/paper-notes.md, numerical parameters)
        "stick_time_constant_ms": 2.0,
        "stick_impedance": 0.9999,
    },
    "valve": {
        # Sonic conductance C of one fully open metering edge, dm^3/(s bar).
        # From the MPYE-5-3/8 nominal flow 2000 l/min (ANR, 6 -> 5 bar gauge,
        # Festo catalogue; assumption, no datasheet at hand) with b = 0.3:
        # C = qn / (p1 sqrt(1 - ((6/7 - b)/(1 - b))^2)) = 7.87 dm^3/(s bar).
        "sonic_conductance_dm3_per_s_bar": 7.87,
        # ISO 6358 critical pressure ratio b (assumption; spool valves 0.2-0.45)
        "critical_pressure_ratio": 0.3,
        # start of the laminar (linearised) region, ISO 6358-3 uses 0.999
        "laminar_pressure_ratio": 0.999,
        # Underlap of each metering edge as a fraction of the full opening
        # (Rubio 2009's underlap leakage). Calibrated per leg.
        "underlap_fraction": [0.02, 0.02, 0.02],
        # Clearance leakage of a covered edge, fraction of full opening (assumption)
        "leakage_fraction": 0.002,
        # Spool response: 1 (first-order lag) or 2 (second order), bandwidth and
        # damping (assumption: MPYE data not at hand; Project Chrono's valve 35 Hz,
        # servo-valves 50-120 Hz)
        "spool_order": 1,
        "spool_bandwidth_hz": 60.0,
        "spool_damping_ratio": 0.8,
    },
    "integration": {
        # pressure sub-steps per call of step() (linearly implicit Euler each)
        "substeps": 1,
    },
    "linear": {
        # eq. (19) coefficients per leg in SI (slide metres per valve volt). null:
        # eq. (34) actuator 1, eq. (35) actuators 2, 3 in SI under the scenario's
        # paper_units reading (b / 20 for "volts"), filled in by the caller
        # (make_actuators(..., linear_plants=...)); the plant knows no paper reading
        "b_m_per_s3_v": None,
        "a1_per_s": None,
        "a0_per_s2": None,
        # effective mass at each slide, kg (diagonal); null: MuJoCo's full mass
        # matrix reduced to the slides at home (computed by make_actuators)
        "effective_mass_kg": None,
        # force of the linear model is bounded by the cylinder's (same as nonlinear)
        "saturate_force": True,
    },
}


def pneumatic_params(overrides=None, base: dict | None = None) -> dict:
    """Default actuator parameter tree with ``--set``-style overrides applied."""
    return apply_overrides(DEFAULT_PNEUMATIC_PARAMS if base is None else base, overrides or [])


def _range_text(lo: float, hi: float, open_lo: bool, why: str) -> str:
    rng = f"{'>' if open_lo else '>='} {lo:g}" + (f" and <= {hi:g}" if hi < math.inf else "")
    return rng + (f" ({why})" if why else "")


def _per_leg(
    tree: Mapping, path: str, lo: float = 0.0, hi: float = math.inf, open_lo=False, why: str = ""
):
    if not why:
        lo, hi, open_lo, why = _PLAUSIBLE.get(path, (lo, hi, open_lo, why))
    node = tree
    for part in path.split("."):
        node = node[part]
    arr = np.asarray(node, dtype=float)
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    ok = arr.shape == (3,) and np.all(np.isfinite(arr))
    ok = ok and np.all(arr > lo if open_lo else arr >= lo) and np.all(arr <= hi)
    if not ok:
        raise UserInputError(
            f"invalid value at pneumatics.{path}: {node!r}; allowed: a number or a list of 3 "
            f"numbers {_range_text(lo, hi, open_lo, why)}"
        )
    return arr


def _per_leg_or_none(tree: Mapping, path: str, lo: float = 0.0, open_lo=False):
    node = tree
    for part in path.split("."):
        node = node[part]
    return None if node is None else _per_leg(tree, path, lo, open_lo=open_lo)


def _scalar(
    tree: Mapping, path: str, lo: float, hi: float = math.inf, open_lo=True, why: str = ""
) -> float:
    if not why:
        lo, hi, open_lo, why = _PLAUSIBLE.get(path, (lo, hi, open_lo, why))
    node: Any = tree
    for part in path.split("."):
        node = node[part]
    try:
        x = float(node)
    except (TypeError, ValueError):
        x = math.nan
    if not (math.isfinite(x) and (x > lo if open_lo else x >= lo) and x <= hi):
        raise UserInputError(
            f"invalid value at pneumatics.{path}: {node!r}; allowed: "
            f"{_range_text(lo, hi, open_lo, why)}"
        )
    return x


def _choice(tree: Mapping, path: str, allowed: tuple) -> str:
    node = tree
    for part in path.split("."):
        node = node[part]
    if node not in allowed:
        raise UserInputError(
            f"invalid value at pneumatics.{path}: {node!r}; allowed: "
            + ", ".join(repr(a) for a in allowed)
        )
    return str(node)


#: Physically plausible range of each parameter: path -> (low, high, low open, why).
#: A value outside is refused before the simulation, the reason in the message.
_PLAUSIBLE = {
    "atmospheric_pressure_kpa": (
        30.0, 110.0, False, "kPa: from the top of Mount Everest (33) to below sea level (107)"
    ),
    "supply_pressure_bar_gauge": (
        0.0, 12.0, True, "bar: the MPYE valve and DNC cylinders are rated to 10-12 bar"
    ),
    "temperature_c": (-40.0, 100.0, False, "deg C: beyond the seals' and the valve's rating"),
    "gas_constant_j_per_kg_k": (
        200.0, 500.0, False, "J/(kg K): air 287, nitrogen 297; the model is for such gases"
    ),
    "polytropic_index": (1.0, 1.67, False, "isothermal 1 .. adiabatic monatomic 1.67"),
    "cylinder.bore_mm": (8.0, 320.0, False, "mm: ISO 15552 and catalogue bores, 8..320"),
    "cylinder.stroke_mm": (10.0, 3000.0, False, "mm: catalogue strokes; the model has 500"),
    "cylinder.dead_volume_cap_l": (
        1e-4, 10.0, False, "l: the port and hose volume, 0.1 l here; 10 l is a tank"
    ),
    "cylinder.dead_volume_rod_l": (
        1e-4, 10.0, False, "l: the port and hose volume, 0.1 l here; 10 l is a tank"
    ),
    "cylinder.viscous_friction_n_s_per_m": (
        0.0, 1e5, False,
        "N s/m: seal friction of a DNC-125 is hundreds to about 10,000; at 1e5 N s/m "
        "0.1 m/s takes 10 kN, nearly all the cylinder makes",
    ),
    "cylinder.coulomb_friction_n": (
        0.0, 5000.0, False, "N: tens to a few hundred for a DNC-125; 5 kN is 40 % of its force"
    ),
    "cylinder.breakaway_friction_n": (
        0.0, 5000.0, False, "N: at least the Coulomb force; 5 kN is 40 % of the cylinder's force"
    ),
    "cylinder.breakaway_ratio": (
        1.0, 10.0, False, "breakaway / Coulomb force: 1 (no peak) to about 2 for lip seals"
    ),
    "cylinder.stribeck_velocity_mm_per_s": (
        1e-3, 1000.0, True, "mm/s: where the breakaway peak decays, a few to tens of mm/s"
    ),
    "cylinder.coulomb_smoothing_mm_per_s": (
        1e-3, 1000.0, False, "mm/s: the speed over which the friction changes sign"
    ),
    "cylinder.stick_time_constant_ms": (
        2.0, 100.0, False, "ms: two 1 ms steps is the stiffest MuJoCo integrates"
    ),
    "cylinder.stick_impedance": (
        0.9, 0.9999, False, "MuJoCo's impedance: at most 0.9999, its own limit"
    ),
    "valve.sonic_conductance_dm3_per_s_bar": (
        0.01, 100.0, False, "dm^3/(s bar): the MPYE-5-3/8 has 7.87; 100 is a valve far "
        "beyond the cylinder's ports",
    ),
    "valve.spool_bandwidth_hz": (1.0, 1000.0, False, "Hz: the MPYE's spool, about 60-100"),
    "valve.spool_damping_ratio": (0.01, 10.0, False, "a second-order spool's damping"),
}  # fmt: skip


@dataclass(frozen=True)
class PneumaticParams:
    """Actuator parameters in SI units (built from the tree by :meth:`from_tree`).

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
    def from_tree(cls, tree: Mapping | None = None) -> PneumaticParams:
        """Validate a parameter tree (defaults filled in) and convert to SI.

        Raises
        ------
        UserInputError
            For unknown keys or out-of-range values (the message names the path).
        """
        t = copy.deepcopy(DEFAULT_PNEUMATIC_PARAMS)
        if tree is not None:
            check_keys(tree, DEFAULT_PNEUMATIC_PARAMS, "pneumatics")
            for k, v in tree.items():
                if isinstance(v, Mapping):
                    t[k].update(copy.deepcopy(dict(v)))
                else:
                    t[k] = copy.deepcopy(v)
        p_atm = _scalar(t, "atmospheric_pressure_kpa", 0.0) * 1e3
        p_s = _scalar(t, "supply_pressure_bar_gauge", 0.0, 12.0) * 1e5 + p_atm
        bore = _scalar(t, "cylinder.bore_mm", 0.0) * 1e-3
        rod = _scalar(t, "cylinder.rod_mm", 0.0, bore * 1e3 * 0.999) * 1e-3
        a1 = math.pi / 4 * bore**2
        a2 = a1 - math.pi / 4 * rod**2
        order = _scalar(t, "valve.spool_order", 0.0, 2.0)
        if order not in (1.0, 2.0):
            raise UserInputError(
                f"invalid value at pneumatics.valve.spool_order: {order}; allowed 1 or 2"
            )
        sub = _scalar(t, "integration.substeps", 0.0, 1000.0)
        if sub != int(sub):
            raise UserInputError("invalid value at pneumatics.integration.substeps: an integer")
        coulomb = _per_leg(t, "cylinder.coulomb_friction_n")
        ratio = _scalar(t, "cylinder.breakaway_ratio", 1.0)
        if t["cylinder"]["breakaway_friction_n"] is None:
            breakaway = coulomb * ratio
        elif ratio != 1.0:
            raise UserInputError(
                f"invalid value at pneumatics.cylinder.breakaway_ratio: {ratio}; allowed: 1 "
                "when pneumatics.cylinder.breakaway_friction_n is set (set one of the two)"
            )
        else:
            breakaway = _per_leg(t, "cylinder.breakaway_friction_n")
            if np.any(breakaway < coulomb):
                raise UserInputError(
                    "invalid value at pneumatics.cylinder.breakaway_friction_n: "
                    f"{t['cylinder']['breakaway_friction_n']!r}; allowed: null or, per leg, at "
                    f"least pneumatics.cylinder.coulomb_friction_n ({coulomb.tolist()})"
                )
        cut_in = _scalar(t, "supply.cut_in_bar_gauge", 0.0, 16.0)
        cut_out = _scalar(t, "supply.cut_out_bar_gauge", 0.0, 16.0)
        if cut_out <= cut_in:
            raise UserInputError(
                f"invalid value at pneumatics.supply.cut_out_bar_gauge: "
                f"{t['supply']['cut_out_bar_gauge']!r}; allowed: above "
                f"pneumatics.supply.cut_in_bar_gauge ({t['supply']['cut_in_bar_gauge']!r})"
            )
        lin_m = t["linear"]["effective_mass_kg"]
        sat = t["linear"]["saturate_force"]
        if not isinstance(sat, bool):
            raise UserInputError("wrong type at pneumatics.linear.saturate_force: a boolean")
        return cls(
            p_supply=p_s,
            p_atm=p_atm,
            temperature=_scalar(t, "temperature_c", -273.15) + 273.15,
            gas_constant=_scalar(t, "gas_constant_j_per_kg_k", 0.0),
            n_poly=_scalar(t, "polytropic_index", 1.0, 1.67, open_lo=False),
            area_cap=a1,
            area_rod_side=a2,
            stroke=_scalar(t, "cylinder.stroke_mm", 0.0) * 1e-3,
            dead_cap=_per_leg(t, "cylinder.dead_volume_cap_l", 0.0, open_lo=True) * 1e-3,
            dead_rod=_per_leg(t, "cylinder.dead_volume_rod_l", 0.0, open_lo=True) * 1e-3,
            viscous=_per_leg(t, "cylinder.viscous_friction_n_s_per_m"),
            coulomb=coulomb,
            breakaway=breakaway,
            v_stribeck=_scalar(t, "cylinder.stribeck_velocity_mm_per_s", 0.0) * 1e-3,
            v_smooth=_scalar(t, "cylinder.coulomb_smoothing_mm_per_s", 0.0) * 1e-3,
            friction_model=_choice(t, "cylinder.friction_model", FRICTION_MODELS),
            stick_solref=_scalar(t, "cylinder.stick_time_constant_ms", 2.0) * 1e-3,
            stick_solimp=_scalar(t, "cylinder.stick_impedance", 0.9),
            thermal_model=_choice(t, "thermal.model", THERMAL_MODELS),
            supply_model=_choice(t, "supply.model", SUPPLY_MODELS),
            compressor_flow=_scalar(t, "supply.compressor_flow_l_per_min", 0.0, 1e5, False)
            * RHO_REF
            / 60e3,
            receiver_volume=_scalar(t, "supply.receiver_volume_l", 0.0, 1e5) * 1e-3,
            line_volume=_scalar(t, "supply.line_volume_l", 0.0, 1e3) * 1e-3,
            cut_in=cut_in * 1e5 + p_atm,
            cut_out=cut_out * 1e5 + p_atm,
            regulator_conductance=_scalar(t, "supply.regulator_flow_l_per_min_per_bar", 0.0, 1e6)
            * RHO_REF
            / 60e3
            / 1e5,
            gamma=_scalar(t, "thermal.ratio_of_specific_heats", 1.0, 1.67, open_lo=True),
            heat_transfer=_scalar(t, "thermal.heat_transfer_w_per_m2_k", 0.0, 1e4, open_lo=False),
            conductance=_scalar(t, "valve.sonic_conductance_dm3_per_s_bar", 0.0) * 1e-3 / 1e5,
            b_crit=_scalar(t, "valve.critical_pressure_ratio", 0.0, 0.528, open_lo=False),
            r_laminar=_scalar(t, "valve.laminar_pressure_ratio", 0.9, 0.99999),
            underlap=_per_leg(t, "valve.underlap_fraction", 0.0, 0.5),
            leakage=_scalar(t, "valve.leakage_fraction", 0.0, 0.5),
            spool_order=int(order),
            spool_omega=2 * math.pi * _scalar(t, "valve.spool_bandwidth_hz", 0.0),
            spool_zeta=_scalar(t, "valve.spool_damping_ratio", 0.0),
            substeps=int(sub),
            lin_b=_per_leg_or_none(t, "linear.b_m_per_s3_v"),
            lin_a1=_per_leg_or_none(t, "linear.a1_per_s"),
            lin_a0=_per_leg_or_none(t, "linear.a0_per_s2", 0.0, open_lo=True),
            lin_mass=None if lin_m is None else _per_leg(t, "linear.effective_mass_kg", 0.0, True),
            lin_saturate=sat,
        )

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
