"""Electro-pneumatic actuators of the SIMPRO platform: valve + cylinder, per leg.

Each leg has a FESTO MPYE-5-3/8 proportional 5/3 valve (0-10 V, 5 V closed
centre) feeding a FESTO DNC-125-500 double-acting cylinder. The classes here
turn valve voltages into the net force on each MuJoCo slide joint; the
multibody supplies mass, gravity and load (they are not duplicated here).

Two models share one interface (the co-simulation loop uses exactly this)::

    act = make_actuators("nonlinear", params_tree)   # or "linear"
    act.reset(q, qdot, force=holding_force)          # static equilibrium
    for each 1 ms step:
        force = act.step(u_volts, q, qdot, dt)       # (3,) N
        data.ctrl[idx.actuators] = force
        mujoco.mj_step(model, data)

Nonlinear model (Richer & Hurmuzlu 2000; ISO 6358; Rubio 2009)
-----------------------------------------------------------------
*Valve.* The command is saturated to [0, 10] V; the normalised spool position
:math:`s \\in [-1, 1]` follows :math:`s_c = \\mathrm{clip}((u - 5\\,\\mathrm{V})/5\\,\\mathrm{V})`
through a first-order lag (or second order, ``valve.spool_order``),
integrated exactly for the held input. Four metering edges per valve, as
fractions of the full opening (``δ`` underlap, ``ε`` clearance leakage; the
underlap leakage model of Rubio 2009):

.. math::
    a_{P1} = a_{2R} = \\mathrm{clip}(δ + s, ε, 1), \\qquad
    a_{1R} = a_{P2} = \\mathrm{clip}(δ - s, ε, 1).

*Orifice mass flow* (ISO 6358 with a laminar end, ISO 6358-3):

.. math::
    \\dot m = a\\,C\\,ρ_0 \\sqrt{T_0/T}\\, p_u\\, φ(r), \\qquad r = p_d/p_u,

    φ(r) = \\begin{cases} 1 & r \\le b \\ \\text{(choked)}\\\\
      \\sqrt{1 - ((r - b)/(1 - b))^2} & b < r \\le r_\\ell \\ \\text{(subsonic)}\\\\
      φ(r_\\ell)\\,(1 - r)/(1 - r_\\ell) & r_\\ell < r \\le 1 \\ \\text{(laminar)}
    \\end{cases}

(continuous, finite slope at r = 1: no infinite gain near zero pressure drop).

*Chambers* (cap side 1, rod side 2; q the extension from fully retracted):

.. math::
    V_1 = V_{01} + A_1 q, \\quad V_2 = V_{02} + A_2 (L - q), \\qquad
    \\dot p_i = \\frac{n}{V_i}\\left(R T (\\dot m_{Pi} - \\dot m_{iR}) - p_i \\dot V_i\\right)

(polytropic with index n, gas at the supply temperature, Richer & Hurmuzlu
eq. for the pressures with one index for charging, discharging and volume
change; n = 1 isothermal, 1.4 adiabatic).

*Force on the slide:*
:math:`F = p_1 A_1 - p_2 A_2 - p_a (A_1 - A_2) - β \\dot q - F_c \\tanh(\\dot q / v_s)`.

*Integration.* Each chamber pressure obeys a scalar ODE (the chambers only
talk to each other through the piston). Near the end stops the chamber is
small (``V_0`` only) and the laminar orifice is stiff: the explicit time
constant falls below 0.1 ms. Each pressure is therefore advanced by a
linearly implicit (Rosenbrock-Euler) step,
:math:`p^+ = p + h f(p) / (1 - h \\min(∂f/∂p, 0))`, which is L-stable for the
stiff flow terms and has the exact static equilibrium as fixed point. It is
not bounded: a chamber compressed above the supply pressure flows back to
the supply through its supply edge (ISO 6358 with the chamber upstream, ratio
p_s/p), one expanded below the atmosphere draws air through its exhaust
edge (ratio p/p_a); the MPYE has no relief valve (issue 18). ``integration.substeps``
splits the step further (default 1; tests compare with a fine reference).

Linear model (paper eq. 19)
---------------------------
Per leg a state φ (pressure difference per unit effective mass) around the
static holding force F_h, driven by the voltage deviation and the piston speed:

.. math::
    \\dot φ = b\\,(u - u_h) - a_0 \\dot q - a_1 φ, \\qquad
    F = F_h + M_q φ + D_q \\dot q + K_q (q - q_0),

with M_q, D_q, K_q the closed chain's mass, joint-damping and gravity-stiffness
matrices reduced to the slides at home (:func:`slide_mass_matrix`). Linearised, the multibody gives
:math:`\\ddot q = φ`, so every leg follows exactly
:math:`Q/U = b / (s (s^2 + a_1 s + a_0))` (eqs. 19, 34, 35), decoupled.
"""

from __future__ import annotations

import copy
import math
from bisect import bisect_right
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import apply_overrides, check_keys, closest
from simpro_mj.plant import pneumatics_kernel as _pk

__all__ = [
    "DEFAULT_PNEUMATIC_PARAMS",
    "ACTUATOR_KINDS",
    "PneumaticParams",
    "NonlinearActuators",
    "LinearActuators",
    "make_actuators",
    "fill_linear",
    "pneumatic_params",
    "iso6358_phi",
    "iso6358_mass_flow",
    "slide_mass_matrix",
    "slide_damping_matrix",
    "holding_forces",
]

#: ISO 8778 standard reference atmosphere of ISO 6358 (ANR): 100 kPa, 20 °C, 65 % RH.
RHO_REF = 1.185  # kg/m^3
T_REF = 293.15  # K
U_CENTRE = 5.0  # V, closed centre of the MPYE
U_MAX = 10.0  # V

ACTUATOR_KINDS = ("nonlinear", "linear")

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
        # tanh smoothing velocity of the Coulomb law, mm/s (assumption)
        "coulomb_smoothing_mm_per_s": 5.0,
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


def _per_leg(tree: Mapping, path: str, lo: float = 0.0, hi: float = math.inf, open_lo=False):
    node = tree
    for part in path.split("."):
        node = node[part]
    arr = np.asarray(node, dtype=float)
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    ok = arr.shape == (3,) and np.all(np.isfinite(arr))
    ok = ok and np.all(arr > lo if open_lo else arr >= lo) and np.all(arr <= hi)
    if not ok:
        rng = f"{'>' if open_lo else '>='} {lo}" + (f" and <= {hi}" if hi < math.inf else "")
        raise UserInputError(
            f"invalid value at pneumatics.{path}: {node!r}; expected a number or a list of 3 "
            f"numbers {rng}"
        )
    return arr


def _per_leg_or_none(tree: Mapping, path: str, lo: float = 0.0, open_lo=False):
    node = tree
    for part in path.split("."):
        node = node[part]
    return None if node is None else _per_leg(tree, path, lo, open_lo=open_lo)


def _scalar(tree: Mapping, path: str, lo: float, hi: float = math.inf, open_lo=True) -> float:
    node = tree
    for part in path.split("."):
        node = node[part]
    try:
        x = float(node)
    except (TypeError, ValueError):
        x = math.nan
    if not (math.isfinite(x) and (x > lo if open_lo else x >= lo) and x <= hi):
        raise UserInputError(
            f"invalid value at pneumatics.{path}: {node!r}; allowed {'>' if open_lo else '>='} "
            f"{lo}" + (f" and <= {hi}" if hi < math.inf else "")
        )
    return x


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
    v_smooth: float  # m/s
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
            coulomb=_per_leg(t, "cylinder.coulomb_friction_n"),
            v_smooth=_scalar(t, "cylinder.coulomb_smoothing_mm_per_s", 0.0) * 1e-3,
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


# --------------------------------------------------------------------------- flow law


def iso6358_phi(r, b: float, r_lam: float):
    """Flow function φ(r) of ISO 6358 with a laminar end (r = p_down/p_up).

    Choked (r <= b): 1; subsonic: sqrt(1 - ((r - b)/(1 - b))^2); laminar
    (r > r_lam): linear to 0 at r = 1, continuous at r_lam. r is clipped to [0, 1].
    """
    r = np.clip(np.asarray(r, dtype=float), 0.0, 1.0)
    t_lam = (r_lam - b) / (1.0 - b)
    phi_lam = math.sqrt(1.0 - t_lam * t_lam)
    t = np.clip((r - b) / (1.0 - b), 0.0, t_lam)
    return np.minimum(np.sqrt(1.0 - t * t), phi_lam * (1.0 - r) / (1.0 - r_lam))


def iso6358_mass_flow(conductance, p_up, p_down, temperature, b: float, r_lam: float):
    """Mass flow (kg/s) through an orifice of sonic conductance C (m^3/(s Pa)).

    :math:`\\dot m = C ρ_0 \\sqrt{T_0/T}\\, p_u φ(p_d/p_u)` (ISO 6358), signed:
    positive from ``p_up`` to ``p_down``; a reverse pressure drop gives a
    negative flow with the roles of the ports exchanged.
    """
    p_up, p_down = np.asarray(p_up, float), np.asarray(p_down, float)
    hi, lo = np.maximum(p_up, p_down), np.minimum(p_up, p_down)
    sign = np.where(p_up >= p_down, 1.0, -1.0)
    k = np.asarray(conductance) * RHO_REF * np.sqrt(T_REF / temperature)
    return sign * k * hi * iso6358_phi(lo / hi, b, r_lam)


# ----------------------------------------------------------------- nonlinear model


def _psi_table(b: float, r_lam: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid and values of the conductance form ψ(r) = φ(r) / (1 - r).

    With it the orifice flow reads :math:`\\dot m = a C ρ_0 \\sqrt{T_0/T}\\,ψ(r)(p_u - p_d)`
    (finite at r = 1: ψ = φ(r_ℓ)/(1 - r_ℓ) in the laminar region). The grid is
    geometric towards r = 1 and holds the branch points b and r_ℓ exactly, so
    the piecewise-linear interpolant is within 2e-5 (relative) of the formula.
    """
    x = np.concatenate(
        [
            np.linspace(0.0, b, 16),
            1.0 - np.geomspace(1.0 - b, 1.0 - r_lam, 600),
            [1.0],
        ]
    )
    x = np.unique(x)
    phi = iso6358_phi(x, b, r_lam)
    with np.errstate(divide="ignore", invalid="ignore"):
        psi = phi / (1.0 - x)
    psi[-1] = math.sqrt(1.0 - ((r_lam - b) / (1.0 - b)) ** 2) / (1.0 - r_lam)
    return x, psi


class NonlinearActuators:
    """Three valve + cylinder actuators, nonlinear (vectorised over the legs).

    Parameters
    ----------
    params : dict or PneumaticParams, optional
        The ``pneumatics`` parameter tree (defaults: :data:`DEFAULT_PNEUMATIC_PARAMS`).

    Attributes
    ----------
    p1, p2 : ndarray (3,)
        Cap- and rod-side chamber pressures, Pa absolute (views of the state).
    spool : ndarray (3,)
        Normalised spool positions in [-1, 1] (+1: supply to the cap side).
    u_hold : ndarray (3,)
        Valve voltages of the static equilibrium found by :meth:`reset`.

    Notes
    -----
    Pressure update (per chamber, conductances frozen over the step, a
    linearly implicit Euler step): with :math:`G_P = a_P k ψ(p/p_s)`,
    :math:`G_R = a_R k ψ(p_a/p)` (ratios downstream/upstream, inverted on back
    flow), :math:`c = n R T / V`,

    .. math::
        p^+ = \\frac{p + h c (G_P p_s + G_R p_a)}
                   {1 + h c (G_P + G_R) + h n \\dot V / V}.

    For :math:`\\dot V \\ge 0` this is a weighted mean of p, p_s, p_a: the
    pressure cannot leave [p_a, p_s] and cannot overshoot the orifice
    equilibrium however small V is (L-stable); its fixed point at rest is the
    exact static equilibrium. Compression (:math:`\\dot V < 0`) is explicit in
    effect (the denominator is kept >= 0.5) and may lift p above p_s; it stays
    positive. No bound is applied: above p_s the supply edge carries the flow
    back to the supply (:math:`ψ(p_s/p)`, the chamber upstream), below p_a the
    exhaust edge draws air in (:math:`ψ(p/p_a)`), as the MPYE's spool does; it
    has no relief valve.
    """

    kind = "nonlinear"

    def __init__(self, params=None):
        P = params if isinstance(params, PneumaticParams) else PneumaticParams.from_tree(params)
        self.params = P
        ps, pa = P.p_supply, P.p_atm
        self._ps, self._pa = ps, pa
        self._A1, self._A2, self._Ar = P.area_cap, P.area_rod_side, P.area_rod
        self._L = P.stroke
        self._n = P.n_poly
        self._kc = P.conductance * RHO_REF * math.sqrt(T_REF / P.temperature)  # kg/(s Pa)
        self._RTk = P.gas_constant * P.temperature * self._kc
        self._xp, self._fp = _psi_table(P.b_crit, P.r_laminar)
        # metering edges as a (4, 3) block: rows P->1, P->2, 1->R, 2->R
        self._sg = np.array([[1.0], [-1.0], [-1.0], [1.0]]) * np.ones((1, 3))
        self._delta = np.broadcast_to(P.underlap, (4, 3)).copy()
        self._eps = P.leakage
        # One work vector z: [p1 (3), p2 (3), qdot (3), tanh(qdot/vs) (3), 1, 3 spare],
        # followed by the spool positions and rates: the head of the compiled
        # kernel's buffer (pneumatics_kernel.py), whose views they are
        self._kb = np.zeros(_pk.buffer_len(len(self._xp)))
        z = self._kb[:16]
        z[12] = 1.0
        self._z = z
        self._p = z[:6]
        self.p1, self.p2 = z[:3], z[3:6]
        self._zqd, self._zth, self._z13 = z[6:9], z[9:12], z[:13]
        # force F = A1 p1 - A2 p2 - pa Ar - beta qdot - Fc tanh(qdot/vs) = Mf @ z[:13]
        mf = np.zeros((3, 13))
        i3 = np.arange(3)
        mf[i3, i3] = self._A1
        mf[i3, 3 + i3] = -self._A2
        mf[i3, 6 + i3] = -P.viscous
        mf[i3, 9 + i3] = -P.coulomb
        mf[:, 12] = -pa * self._Ar
        self._mf = mf
        self._inv_vs = 1.0 / P.v_smooth if P.v_smooth > 0 else 1e12
        # volumes V = Mv @ [1, q]: V1 = V01 + A1 q, V2 = V02 + A2 (L - q) (_chambers below)
        mv = np.zeros((6, 4))
        mv[:3, 0], mv[3:, 0] = P.dead_cap, P.dead_rod + self._A2 * self._L
        mv[i3, 1 + i3] = self._A1
        mv[3 + i3, 1 + i3] = -self._A2
        # overtravel past the soft end stops must not empty a chamber
        self._vmin = 0.5 * np.concatenate([P.dead_cap, P.dead_rod])
        # state (no allocation in step but the returned force)
        self.spool = self._kb[_pk.ST_SPOOL : _pk.ST_SPOOL + 3]
        self.spool_rate = self._kb[_pk.ST_RATE : _pk.ST_RATE + 3]
        self.u_hold = np.full(3, U_CENTRE)
        # Scalar copies for the per-chamber arithmetic of step() (Python floats)
        self._order1 = P.spool_order == 1
        self._delta_l = P.underlap.tolist()
        self._xp_l, self._fp_l = self._xp.tolist(), self._fp.tolist()
        xl, fl = self._xp_l, self._fp_l  # np.interp's slope of each grid cell
        self._slope_l = [(fl[j + 1] - fl[j]) / (xl[j + 1] - xl[j]) for j in range(len(xl) - 1)]
        # the grid cells (x_j, x_j+1, slope_j, ψ_j); each edge keeps its last
        # cell (np.interp's guess) in _cell
        self._cells = [(xl[j], xl[j + 1], self._slope_l[j], fl[j]) for j in range(len(xl) - 1)]
        self._cell = [self._cells[0]] * 12
        # per chamber (cap sides, then rod sides): index, leg, V0, dV/dq, V_min
        self._chambers = tuple(
            (c, c % 3, float(mv[c, 0]), float(mv[c, 1 + c % 3]), float(self._vmin[c]))
            for c in range(6)
        )
        self._n_sub = int(P.substeps)  # pressure sub-steps per step (usually 1)
        self._kernel = None
        if _pk.kernel_choice() == "numba":  # SIMPRO_KERNEL (pneumatics_kernel.py)
            self._init_kernel()
        self._dt = None
        self.reset(np.full(3, 0.5 * self._L), np.zeros(3))

    # -- valve ---------------------------------------------------------------
    def _set_dt(self, dt: float) -> None:
        P = self.params
        self._dt = dt
        self._h = dt / P.substeps
        self._hn = self._h * self._n
        w = P.spool_omega
        if P.spool_order == 1:
            self._alpha = -math.expm1(-w * dt)
        else:  # exact ZOH discretisation of s'' + 2 z w s' + w^2 s = w^2 c
            from scipy.linalg import expm

            a = np.array([[0.0, 1.0, 0.0], [-(w**2), -2 * P.spool_zeta * w, w**2], [0, 0, 0]])
            e = expm(a * dt)
            self._spool_ad = e[:2, :2].copy()
            self._spool_bd = e[:2, 2].copy()
        if self._kernel is not None:
            self._fill_kernel_dt()

    def _init_kernel(self) -> None:
        """Constants of the compiled kernel in its buffer (``pneumatics_kernel``)."""
        pk, kb = _pk, self._kb
        kb[pk.KP_PS], kb[pk.KP_PA], kb[pk.KP_RTK] = self._ps, self._pa, self._RTk
        kb[pk.KP_EPS], kb[pk.KP_IVS] = self._eps, self._inv_vs
        kb[pk.KP_DELTA : pk.KP_DELTA + 3] = self._delta_l
        kb[pk.KP_ORDER], kb[pk.KP_NSUB] = self.params.spool_order, self._n_sub
        for c, _, v0, dv, vmin in self._chambers:
            kb[pk.KP_CH + 3 * c : pk.KP_CH + 3 * c + 3] = (v0, dv, vmin)
        n = len(self._xp_l)
        kb[pk.KP_NTAB] = n
        kb[pk.KP_CELL : pk.KP_CELL + 12] = 0.0
        kb[pk.KP_TAB : pk.KP_TAB + n] = self._xp
        kb[pk.KP_TAB + n : pk.KP_TAB + 2 * n] = self._fp
        kb[pk.KP_TAB + 2 * n : pk.KP_TAB + 3 * n - 1] = self._slope_l
        self._kernel = pk.step_kernel()

    def _fill_kernel_dt(self) -> None:
        pk, kb = _pk, self._kb
        kb[pk.KP_HN] = self._hn
        if self.params.spool_order == 1:
            kb[pk.KP_ALPHA] = self._alpha
        else:
            kb[pk.KP_AD : pk.KP_AD + 4] = self._spool_ad.reshape(4)
            kb[pk.KP_AD + 4 : pk.KP_AD + 6] = self._spool_bd

    def openings(self, spool) -> np.ndarray:
        """Edge openings (4, 3) for spool positions: rows P->1, P->2, 1->R, 2->R."""
        s = np.asarray(spool, float)
        return np.clip(self._delta + self._sg * s, self._eps, 1.0)

    def psi(self, r):
        """ψ(r) = φ(r)/(1 - r) as used in :meth:`step` (table interpolation)."""
        return np.interp(r, self._xp, self._fp)

    def chamber_net_flow(self, p, spool, chamber: int):
        """Net mass flow into chamber 1 or 2 (kg/s) at pressures p (3,), spools (3,).

        The same flow law as :meth:`step` (ψ table): supply edge
        :math:`a_P k ψ(p/p_s)(p_s - p)` minus exhaust edge :math:`a_R k ψ(p_a/p)(p - p_a)`.
        """
        a = self.openings(spool)
        p = np.asarray(p, float)
        m_in = a[chamber - 1] * self._kc * self.psi(p / self._ps) * (self._ps - p)
        m_out = a[chamber + 1] * self._kc * self.psi(self._pa / p) * (p - self._pa)
        return m_in - m_out

    # -- state ---------------------------------------------------------------
    def equilibrium(self, force) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Spool, p1, p2 (each (3,)) at rest holding ``force`` (N, (3,)).

        Each chamber's net flow vanishes (supply leak = exhaust leak through
        the underlapped edges) and :math:`p_1 A_1 - p_2 A_2 - p_a A_r = F`.
        Solved by nested Brent iterations (net flow is monotone in p, force is
        monotone in the spool). A force beyond the cylinder's range gives the
        saturated spool (±1).
        """
        F = np.broadcast_to(np.asarray(force, float), (3,))
        s_out, p1_out, p2_out = np.zeros(3), np.zeros(3), np.zeros(3)
        for i in range(3):

            def f_of(s, i=i):
                p1, p2 = self._static_pressure(i, s, 1), self._static_pressure(i, s, 2)
                return p1 * self._A1 - p2 * self._A2 - self._pa * self._Ar - F[i]

            lo, hi = f_of(-1.0), f_of(1.0)
            if lo >= 0:
                s = -1.0
            elif hi <= 0:
                s = 1.0
            else:
                from scipy.optimize import brentq  # on use: loading a scenario stays light

                s = brentq(f_of, -1.0, 1.0, xtol=1e-12)
            s_out[i] = s
            p1_out[i] = self._static_pressure(i, s, 1)
            p2_out[i] = self._static_pressure(i, s, 2)
        return s_out, p1_out, p2_out

    def _static_pressure(self, leg: int, s: float, chamber: int) -> float:
        """Pressure of zero net flow into a chamber at spool ``s`` (Brent)."""
        sv = np.zeros(3)
        sv[leg] = s

        def g(p):
            return self.chamber_net_flow(np.full(3, p), sv, chamber)[leg]

        from scipy.optimize import brentq

        return brentq(g, self._pa, self._ps, xtol=1e-7, rtol=1e-14)

    def reset(self, q, qdot, force=None) -> None:
        """Set the state at rest: valve centred (``force=None``), or the static
        equilibrium holding ``force`` (N, (3,)), see :meth:`equilibrium`.

        ``q`` and ``qdot`` are accepted for the common interface (the static
        pressures do not depend on them).
        """
        if force is None:
            s = np.zeros(3)
            p1 = np.array([self._static_pressure(i, 0.0, 1) for i in range(3)])
            p2 = np.array([self._static_pressure(i, 0.0, 2) for i in range(3)])
        else:
            s, p1, p2 = self.equilibrium(force)
        self.p1[:] = p1
        self.p2[:] = p2
        self.spool[:] = s
        self.spool_rate[:] = 0.0
        self.u_hold[:] = U_CENTRE + 5.0 * s

    def force_now(self, qdot) -> np.ndarray:
        """Net slide force (N) of the present pressures at speed ``qdot``."""
        self._zqd[:] = qdot
        np.multiply(self._zqd, self._inv_vs, out=self._zth)
        np.tanh(self._zth, out=self._zth)
        return np.dot(self._mf, self._z13)

    # -- step ----------------------------------------------------------------
    def step(self, u_volts, q, qdot, dt: float) -> np.ndarray:
        """Advance valves and chambers by ``dt`` (s); return the slide forces (N).

        Inputs are held over the step (zero-order hold, as the rig's 1 ms DAC).
        ``u_volts``, ``q``, ``qdot`` are (3,) arrays or sequences of 3 floats (a
        scalar applies to all legs). Returns a new (3,) array: the force to
        apply during the next physics step.

        Notes
        -----
        The hot path of the co-simulation (issue 7). Three legs of two
        chambers are too few for numpy: a ufunc on a 3-vector costs about as
        much as 20 float operations in the interpreter. The per-chamber
        arithmetic therefore runs on Python floats, operation for operation
        the same IEEE expressions as the stacked-array version it replaced
        (same grouping, so bit-identical results; ``tests/test_reference_metrics.py``).
        Two steps stay in numpy because a scalar rewrite would round
        differently: ``tanh`` (numpy's SIMD kernel is not libm's) and the
        force product ``Mf @ z`` (BLAS accumulates with FMA).
        """
        if dt != self._dt:
            if not dt > 0:
                raise ValueError(f"dt must be > 0, got {dt}")
            self._set_dt(dt)
        # lists of 3 (the co-simulation's case) are used as they are
        u = u_volts if type(u_volts) is list and len(u_volts) == 3 else _as3(u_volts)
        q = q if type(q) is list and len(q) == 3 else _as3(q)
        qd = qdot if type(qdot) is list and len(qdot) == 3 else _as3(qdot)
        if self._kernel is not None:  # compiled kernel: the same arithmetic, then as below
            u0, u1, u2 = u
            q0, q1, q2 = q
            v0, v1, v2 = qd
            self._kernel(u0, u1, u2, q0, q1, q2, v0, v1, v2, self._kb)
            np.tanh(self._zth, out=self._zth)
            return np.dot(self._mf, self._z13)
        # valve command: saturate 0..10 V, normalise around the 5 V centre;
        # then the spool lag (exact for the held command)
        if self._order1:
            sp = self.spool.tolist()
            alpha = self._alpha
            for i in range(3):
                c = u[i] * 0.2 - 1.0
                if c < -1.0:  # comparisons, not min/max: NaN propagates as in np.maximum
                    c = -1.0
                if c > 1.0:
                    c = 1.0
                sp[i] = sp[i] + (c - sp[i]) * alpha
        else:
            sp = self._spool2(u)
        spool = self.spool  # item stores: cheaper than a slice assignment for 3 values
        spool[0], spool[1], spool[2] = sp
        # metering-edge openings with underlap and clearance leakage (Rubio 2009):
        # a_P1 = a_2R = clip(δ + s), a_1R = a_P2 = clip(δ - s), both in [ε, 1]
        eps, delta = self._eps, self._delta_l
        a_plus, a_minus = [0.0] * 3, [0.0] * 3
        for i in range(3):
            ap, am = sp[i] + delta[i], delta[i] - sp[i]
            if ap < eps:
                ap = eps
            if ap > 1.0:
                ap = 1.0
            if am < eps:
                am = eps
            if am > 1.0:
                am = 1.0
            a_plus[i], a_minus[i] = ap, am
        # the six chambers, cap sides of legs 1-3 then rod sides (the order of
        # p1, p2): supply edges P->1, P->2 and exhaust edges 1->R, 2->R
        a_supply, a_exhaust = a_plus + a_minus, a_minus + a_plus
        z = self._z  # [p1 (3), p2 (3), qdot (3), tanh(qdot/vs) (3), 1, spare (3)]
        p = z.tolist()
        ps, pa, hn, rtk = self._ps, self._pa, self._hn, self._RTk
        ips = 1.0 / ps  # read each step: the supply may change at run time (faults)
        # each edge's current grid cell of the ψ table, (x_j, x_j+1, slope_j, ψ_j):
        # np.interp's arithmetic ψ = slope_j (r - x_j) + ψ_j, starting from the
        # last step's cell (np.interp's guess); _psi_slow finds a new one
        cell = self._cell
        substeps = self._n_sub
        for c, i, v0, dv, vmin in self._chambers:
            # volume V = V0 + dV q, h n / V, and the volume-rate term 1 + h n Vdot / V
            V = v0 + dv * q[i]
            if V < vmin:  # overtravel past the soft end stops must not empty a chamber
                V = vmin
            hnV = hn / V
            den0 = (dv * qd[i]) * hnV + 1.0
            hc = hnV * rtk  # h n R T k / V
            a_s, a_e, pc = a_supply[c], a_exhaust[c], p[c]
            n = substeps
            while n:  # cheaper than a for loop over a range for the usual single substep
                n -= 1
                # ψ of the supply edge (ratio p/p_s) and of the exhaust edge (p_a/p);
                # above the supply the chamber is upstream of the supply edge (back
                # flow to the supply), below the atmosphere downstream of the exhaust
                # edge (air drawn in): ψ of the ratio downstream/upstream either way
                r = pc * ips if pc <= ps else ps / pc
                x0, x1, sl, f0 = cell[c]
                if x0 <= r < x1:
                    psi_s = sl * (r - x0) + f0
                else:
                    psi_s = self._psi_slow(r, c)
                r = pa / pc if pc >= pa else pc / pa
                x0, x1, sl, f0 = cell[c + 6]
                if x0 <= r < x1:
                    psi_e = sl * (r - x0) + f0
                else:
                    psi_e = self._psi_slow(r, c + 6)
                # conductances G = a ψ(r) (times k, folded into hc), then the
                # linearly implicit Euler step with frozen conductances (class notes)
                g_s, g_e = a_s * psi_s, a_e * psi_e
                den = (g_s + g_e) * hc + den0
                if den < 0.5:
                    den = 0.5
                # no clipping at p_a or p_s: the step is the implicit flow balance,
                # positive whenever den > 0 (a weighted mean of p, p_s, p_a for
                # Vdot >= 0; compression can lift p above p_s, which then flows back)
                pc = ((g_s * ps + g_e * pa) * hc + pc) / den
            z[c] = pc
        # force on the slide with friction (viscous + tanh Coulomb): Mf @ z
        ivs = self._inv_vs
        z[6], z[7], z[8] = qd
        z[9], z[10], z[11] = qd[0] * ivs, qd[1] * ivs, qd[2] * ivs
        np.tanh(self._zth, out=self._zth)
        return np.dot(self._mf, self._z13)

    def _spool2(self, cmd_volts) -> list:
        """Second-order spool (exact ZOH), the ``spool_order = 2`` path of :meth:`step`."""
        ad, bd = self._spool_ad.tolist(), self._spool_bd.tolist()
        sp, sr = self.spool.tolist(), self.spool_rate.tolist()
        out = [0.0] * 3
        for i in range(3):
            c = cmd_volts[i] * 0.2 - 1.0
            if c < -1.0:
                c = -1.0
            if c > 1.0:
                c = 1.0
            rate = ad[1][0] * sp[i] + ad[1][1] * sr[i] + bd[1] * c
            out[i] = sp[i] * ad[0][0] + (ad[0][1] * sr[i] + bd[0] * c)
            sr[i] = rate
        self.spool_rate[:] = sr
        return out

    def _psi_slow(self, r: float, edge: int) -> float:
        """ψ(r) off the guessed grid cell of ``edge``: np.interp's rules, then a new guess."""
        xp, fp = self._xp_l, self._fp_l
        if r != r:
            return r  # NaN propagates
        if r < xp[0]:
            return fp[0]
        if r >= xp[-1]:
            return fp[-1]
        j = bisect_right(xp, r) - 1
        self._cell[edge] = self._cells[j]
        return self._slope_l[j] * (r - xp[j]) + fp[j]

    def set_supply_pressure(self, p_pa: float) -> None:
        """Change the supply pressure p_s (Pa absolute) at run time (supply-drop fault).

        :meth:`step` reads ``self._ps`` every step; chambers above the new
        p_s are bounded to it on the next step (the valve lets the excess
        flow back to the supply line).
        """
        p = float(p_pa)
        if not p > self._pa:
            raise ValueError(f"supply pressure must exceed atmospheric {self._pa} Pa, got {p}")
        self._ps = p
        if self._kernel is not None:
            self._kb[_pk.KP_PS] = p


_F64 = np.dtype(np.float64)


def _as3(x) -> list:
    """Three numbers from a (3,) float array, a list of 3 or anything broadcastable.

    A list of 3 is used as it is (its items must be real numbers).
    """
    if type(x) is np.ndarray and x.shape == (3,) and x.dtype is _F64:
        return x.tolist()
    if type(x) is list and len(x) == 3:
        return x
    return np.broadcast_to(np.asarray(x, dtype=float), (3,)).tolist()


# -------------------------------------------------------------------- linear model


class LinearActuators:
    r"""Linearised actuators reproducing eq. (19) on every slide of the closed chain.

    Per leg an acceleration-like state :math:`φ` (a pressure difference per
    unit effective mass) obeys
    :math:`\dot φ = b (u - u_h) - a_0 \dot q - a_1 φ` (integrated exactly over
    the held step), and the slide forces are

    .. math::
        F = F_h + M_q φ + D_q \dot q + K_q (q - q_0),

    with :math:`M_q` the mass matrix of the closed chain reduced to the slides,
    :math:`D_q` the joint damping of the mechanism reduced the same way and
    :math:`K_q = ∂F_h/∂q` the change of the gravity holding forces with the
    configuration (all at home, :func:`slide_mass_matrix`; leg 1 sees a
    negative gravity stiffness of about -4.4 kN/m). Linearised about rest the
    multibody obeys :math:`M_q \ddot q + D_q \dot q = F - F_h - K_q (q - q_0)`, hence
    :math:`\ddot q = φ` and every leg follows
    :math:`Q/U = b/(s(s^2 + a_1 s + a_0))` exactly, decoupled from the other
    legs (the reflected masses of legs 2 and 3 are coupled by about 40 %:
    a diagonal-mass design would not reproduce eq. 35 in the closed chain).

    Parameters
    ----------
    params : dict or PneumaticParams, optional
        The ``pneumatics`` tree; ``linear`` holds b, a1, a0 per leg.
    mass_matrix : array (3, 3) or (3,), optional
        :math:`M_q` in kg (a vector: a diagonal). Default
        ``linear.effective_mass_kg`` (diagonal; required then).
    damping_matrix : array (3, 3), optional
        :math:`D_q` in N s/m (default 0).
    stiffness_matrix : array (3, 3), optional
        :math:`K_q` in N/m (default 0); q_0 is the ``q`` given to :meth:`reset`.

    Attributes
    ----------
    p1, p2 : ndarray (3,)
        Nominal chamber pressures consistent with the force (display only: the
        nonlinear static equilibrium plus the force deviation shared equally).
    spool : ndarray (3,)
        Normalised valve command (no spool dynamics in this model).
    """

    kind = "linear"

    def __init__(self, params=None, mass_matrix=None, damping_matrix=None, stiffness_matrix=None):
        P = params if isinstance(params, PneumaticParams) else PneumaticParams.from_tree(params)
        P = fill_linear(P)  # raises if eq. (19)'s coefficients are left null
        self.params = P
        m = mass_matrix if mass_matrix is not None else P.lin_mass
        if m is None:
            raise UserInputError(
                "linear actuators need the effective slide masses: give a MuJoCo model to "
                "make_actuators(..., model=) or set pneumatics.linear.effective_mass_kg"
            )
        m = np.asarray(m, float)
        self.mass_matrix = np.diag(np.broadcast_to(m, (3,))) if m.ndim <= 1 else m.copy()
        if self.mass_matrix.shape != (3, 3):
            raise ValueError("mass_matrix must be (3, 3) or (3,)")
        self.damping_matrix = (
            np.zeros((3, 3)) if damping_matrix is None else np.asarray(damping_matrix, float)
        )
        self.stiffness_matrix = (
            np.zeros((3, 3)) if stiffness_matrix is None else np.asarray(stiffness_matrix, float)
        )
        self.q_ref = np.zeros(3)
        self._b, self._a0, self._a1 = P.lin_b, P.lin_a0, P.lin_a1
        self._fmin, self._fmax = P.force_range
        self._nl = NonlinearActuators(P)  # static pressures for display
        self.phi = np.zeros(3)
        self.force_hold = np.zeros(3)
        self.u_hold = np.full(3, U_CENTRE)
        self.spool = np.zeros(3)
        self.p1, self.p2 = np.zeros(3), np.zeros(3)
        self._p10, self._p20 = np.zeros(3), np.zeros(3)
        self._dt = None

    def reset(self, q, qdot, force=None) -> None:
        """At rest holding ``force`` (N) with the valve at the nonlinear model's
        holding voltage (5 V and the centred-valve force when ``force`` is None)."""
        self._nl.reset(q, qdot, force)
        if force is None:
            self.force_hold[:] = self._nl.force_now(np.zeros(3))
        else:
            self.force_hold[:] = np.broadcast_to(np.asarray(force, float), (3,))
        self.u_hold[:] = self._nl.u_hold
        self.q_ref[:] = q
        self._p10[:], self._p20[:] = self._nl.p1, self._nl.p2
        self.phi[:] = 0.0
        self.spool[:] = (self.u_hold - U_CENTRE) / 5.0
        self._update_pressures(np.zeros(3))

    def _update_pressures(self, df):
        A1, A2 = self.params.area_cap, self.params.area_rod_side
        self.p1[:] = self._p10 + 0.5 * df / A1
        self.p2[:] = self._p20 - 0.5 * df / A2

    def set_supply_pressure(self, p_pa: float) -> None:
        """Change the supply pressure (Pa absolute) at run time (supply-drop fault).

        Eq. (19) has no supply term; what follows p_s is the force bound
        (``p_s A_cap - p_a A_rod_side - p_a A_rod`` and its mirror) and the
        display pressures' nonlinear model.
        """
        p = float(p_pa)
        self._nl.set_supply_pressure(p)
        self._fmin, self._fmax = self.params.force_range_at(p)

    def step(self, u_volts, q, qdot, dt: float) -> np.ndarray:
        """Advance the states by ``dt`` and return the slide forces (N)."""
        if dt != self._dt:
            if not dt > 0:
                raise ValueError(f"dt must be > 0, got {dt}")
            self._dt = dt
            a1 = self._a1
            self._ea = np.exp(-a1 * dt)
            safe = np.where(a1 > 0, a1, 1.0)
            self._ia = np.where(a1 > 0, -np.expm1(-a1 * dt) / safe, dt)
        u = np.clip(np.asarray(u_volts, float), 0.0, U_MAX)
        qd = np.asarray(qdot, float)
        self.spool[:] = (u - U_CENTRE) / 5.0
        drive = self._b * (u - self.u_hold) - self._a0 * qd
        self.phi *= self._ea
        self.phi += self._ia * drive
        df = (
            self.mass_matrix @ self.phi
            + self.damping_matrix @ qd
            + self.stiffness_matrix @ (np.asarray(q, float) - self.q_ref)
        )
        force = self.force_hold + df
        if self.params.lin_saturate:
            np.clip(force, self._fmin, self._fmax, out=force)
        self._update_pressures(force - self.force_hold)
        return force


# ------------------------------------------------------------ multibody helpers


def slide_mass_matrix(model, data, index=None) -> np.ndarray:
    """Mass matrix of the closed chain in the slide coordinates (3, 3), kg.

    :math:`M_q = N^T M N` with N (nv, 3) the joint velocities produced by unit
    slide velocities while the loops stay closed (``J_c N = 0``, ``S N = I``).
    Its diagonal is the effective mass of a slide with the other two held;
    :math:`1/(M_q^{-1})_{ii}` with the other two free. Uses the current
    configuration (call after :func:`simpro_mj.plant.model.assemble`).
    """
    import mujoco

    from simpro_mj.plant.model import PlantIndex, loop_closure_jacobian

    idx = index or PlantIndex.of(model)
    mujoco.mj_forward(model, data)
    n = _slide_velocity_map(model, data, idx, loop_closure_jacobian)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, M, data.qM) if hasattr(data, "qM") else mujoco.mj_fullM(model, data, M)
    return n.T @ M @ n


def slide_damping_matrix(model, data, index=None) -> np.ndarray:
    """Joint damping of the mechanism reduced to the slides, :math:`N^T D N` (N s/m)."""
    from simpro_mj.plant.model import PlantIndex, loop_closure_jacobian

    idx = index or PlantIndex.of(model)
    n = _slide_velocity_map(model, data, idx, loop_closure_jacobian)
    return n.T @ np.diag(model.dof_damping) @ n


def _slide_velocity_map(model, data, idx, jac_fn):
    _, jc = jac_fn(model, data, idx)
    sel = np.zeros((3, model.nv))
    sel[np.arange(3), idx.slide_dof] = 1.0
    a = np.vstack([jc, sel])
    rhs = np.vstack([np.zeros((jc.shape[0], 3)), np.eye(3)])
    return np.linalg.lstsq(a, rhs, rcond=None)[0]


def holding_forces(model, data, index=None) -> np.ndarray:
    """Static slide forces (N) that hold the closed chain at rest where it is.

    :math:`F = N^T τ_{bias}` (gravity; ``qvel`` = 0): the constraint forces
    do no work along N, so this is the inverse-dynamics static solve.
    """
    import mujoco

    from simpro_mj.plant.model import PlantIndex, loop_closure_jacobian

    idx = index or PlantIndex.of(model)
    saved = data.qvel.copy()
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    n = _slide_velocity_map(model, data, idx, loop_closure_jacobian)
    out = n.T @ data.qfrc_bias
    data.qvel[:] = saved
    mujoco.mj_forward(model, data)
    return out


# ----------------------------------------------------------------------- factory


def _pneu_tree(params_tree):
    if params_tree is None:
        return None
    if isinstance(params_tree, PneumaticParams):
        return params_tree
    if "pneumatics" in params_tree:
        return params_tree["pneumatics"]
    return params_tree


def fill_linear(P: PneumaticParams, linear_plants=None) -> PneumaticParams:
    """``P`` with its null ``linear`` coefficients taken from ``linear_plants``.

    ``linear_plants`` is ``(b, a1, a0)``, three per-leg sequences in SI (the
    caller's eqs. 34-35 under its units reading). Raises
    :class:`UserInputError` if a coefficient stays undefined.
    """
    from dataclasses import replace

    have = {"lin_b": P.lin_b, "lin_a1": P.lin_a1, "lin_a0": P.lin_a0}
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


def make_actuators(kind: str, params_tree=None, *, model=None, linear_plants=None):
    """Build the actuators of one kind.

    Parameters
    ----------
    kind : {"nonlinear", "linear"}
    params_tree : dict, optional
        The ``pneumatics`` tree, or a whole scenario tree with a ``pneumatics`` key.
    model : mujoco.MjModel, optional
        For ``"linear"`` without ``linear.effective_mass_kg``: the effective
        slide masses are taken from this model at the home pose (mid-stroke).
    linear_plants : (b, a1, a0), optional
        For ``"linear"``: per-leg eq. (19) coefficients in SI for the
        ``linear`` keys left null (:func:`fill_linear`).

    Raises
    ------
    UserInputError
        Unknown ``kind`` (the message lists the allowed values).
    """
    if kind not in ACTUATOR_KINDS:
        raise UserInputError(
            f"unknown actuator kind '{kind}': allowed values are {list(ACTUATOR_KINDS)}"
            f"{closest(str(kind), ACTUATOR_KINDS)}"
        )
    tree = _pneu_tree(params_tree)
    if kind == "nonlinear":
        return NonlinearActuators(tree)
    P = tree if isinstance(tree, PneumaticParams) else PneumaticParams.from_tree(tree)
    P = fill_linear(P, linear_plants)
    if P.lin_mass is not None:
        return LinearActuators(P, mass_matrix=P.lin_mass)
    import mujoco

    from simpro_mj.plant.model import assemble, load_model

    m = model if model is not None else load_model()
    d = mujoco.MjData(m)
    q0 = np.full(3, 0.5 * P.stroke)
    assemble(m, d, q0)
    mq, dq = slide_mass_matrix(m, d), slide_damping_matrix(m, d)
    kq, h = np.zeros((3, 3)), 1e-3
    for j in range(3):  # K_q = dF_h/dq by central differences
        fp = []
        for sgn in (1.0, -1.0):
            assemble(m, d, q0 + sgn * h * np.eye(3)[j])
            fp.append(holding_forces(m, d))
        kq[:, j] = (fp[0] - fp[1]) / (2 * h)
    return LinearActuators(P, mass_matrix=mq, damping_matrix=dq, stiffness_matrix=kq)
