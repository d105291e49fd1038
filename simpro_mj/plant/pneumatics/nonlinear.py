"""Nonlinear valve + cylinder actuators (Richer & Hurmuzlu 2000; ISO 6358; Rubio 2009).

*Valve.* The command is saturated to [0, 10] V; the normalised spool position
:math:`s \\in [-1, 1]` follows :math:`s_c = \\mathrm{clip}((u - 5\\,\\mathrm{V})/5\\,\\mathrm{V})`
through a first-order lag (or second order, ``valve.spool_order``),
integrated exactly for the held input. Four metering edges per valve, as
fractions of the full opening (``δ`` underlap, ``ε`` clearance leakage; the
underlap leakage model of Rubio 2009):

.. math::
    a_{P1} = a_{2R} = \\mathrm{clip}(δ + s, ε, 1), \\qquad
    a_{1R} = a_{P2} = \\mathrm{clip}(δ - s, ε, 1).

*Orifice mass flow*: ISO 6358 with a laminar end (:mod:`.flow`), through
the conductance form ψ(r) = φ(r)/(1 - r) tabulated once per actuator.

*Chambers* (cap side 1, rod side 2; q the extension from fully retracted):

.. math::
    V_1 = V_{01} + A_1 q, \\quad V_2 = V_{02} + A_2 (L - q), \\qquad
    \\dot p_i = \\frac{n}{V_i}\\left(R T (\\dot m_{Pi} - \\dot m_{iR}) - p_i \\dot V_i\\right)

(polytropic with index n, gas at the supply temperature, Richer & Hurmuzlu
eq. for the pressures with one index for charging, discharging and volume
change; n = 1 isothermal, 1.4 adiabatic).

*Force on the slide:*
:math:`F = p_1 A_1 - p_2 A_2 - p_a (A_1 - A_2) - F_f(\\dot q)`, with the seal
friction :math:`F_f` (breakaway, Stribeck, Coulomb, viscous) of
:func:`simpro_mj.plant.friction.seal_friction`.

*Integration.* Each chamber pressure obeys a scalar ODE (the chambers only
talk to each other through the piston). Near the end stops the chamber is
small (``V_0`` only) and the laminar orifice is stiff: the explicit time
constant falls below 0.1 ms. Each pressure is therefore advanced by a
linearly implicit (Rosenbrock-Euler) step with the conductances frozen over
the step, :math:`G_P = a_P k ψ(p/p_s)`, :math:`G_R = a_R k ψ(p_a/p)` (ratios
downstream/upstream, inverted on back flow), :math:`c = n R T / V`:

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
has no relief valve. ``integration.substeps`` splits the step further
(default 1; tests compare with a fine reference).

The per-step arithmetic is :mod:`simpro_mj.plant.step_functions` (valve,
chambers, forces), the co-simulation's step; this class configures it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from simpro_mj.core.roots import brentq  # scipy.optimize's steps, without its import
from simpro_mj.plant import step_functions as sf
from simpro_mj.plant.pneumatics.flow import RHO_REF, T_REF, psi_table
from simpro_mj.plant.pneumatics.params import U_CENTRE, PneumaticParams

__all__ = ["NonlinearActuators"]


class ArrayStep:
    """The actuator classes' :meth:`step`: their per-step function on (3,) arrays."""

    _dt: float | None = None
    #: the class's per-step function and the arrays it reads and updates
    step_function: Callable[..., None]
    step_state: np.ndarray
    step_constants: np.ndarray

    def set_timestep(self, dt: float) -> None:
        """The step's constants that depend on ``dt`` (s): each class's own."""
        raise NotImplementedError

    def step(self, u_volts, q, qdot, dt: float) -> np.ndarray:
        """Advance the actuators by ``dt`` (s); return the slide forces (N).

        Inputs are held over the step (zero-order hold, as the rig's 1 ms DAC).
        ``u_volts``, ``q``, ``qdot`` are (3,) arrays or sequences of 3 floats (a
        scalar applies to all legs). Returns a new (3,) array: the force to
        apply during the next physics step. The arithmetic is the class's
        ``step_function`` (:mod:`simpro_mj.plant.step_functions`), the
        co-simulation's step.
        """
        if dt != self._dt:
            self.set_timestep(dt)
        f = np.zeros(3)
        self.step_function(
            _as3(u_volts), _as3(q), _as3(qdot), self.step_state, self.step_constants, f
        )
        return f


class NonlinearActuators(ArrayStep):
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
    """

    kind = "nonlinear"
    step_function = staticmethod(sf.nonlinear_step)

    def __init__(self, params=None):
        P = params if isinstance(params, PneumaticParams) else PneumaticParams.from_tree(params)
        self.params = P
        self._kc = P.conductance * RHO_REF * math.sqrt(T_REF / P.temperature)  # kg/(s Pa)
        self._xp, self._fp = psi_table(P.b_crit, P.r_laminar)
        self._delta = np.broadcast_to(np.asarray(P.underlap, float), (3,)).tolist()
        # volumes V = V0 + dV/dq q: V1 = V01 + A1 q, V2 = V02 + A2 (L - q); V_min: overtravel
        # past the soft end stops must not empty a chamber
        v0 = np.concatenate([P.dead_cap, P.dead_rod + P.area_rod_side * P.stroke])
        dvdq = np.concatenate([np.full(3, P.area_cap), np.full(3, -P.area_rod_side)])
        vmin = 0.5 * np.concatenate([P.dead_cap, P.dead_rod])
        # the per-step function's arrays (simpro_mj.plant.step_functions.nonlinear_step):
        # the state (p1, p2, spool, spool rate are views of it) and the constants
        ast = self.step_state = np.zeros(sf.ACT.LEN)
        self.p1, self.p2 = ast[sf.ACT.p : sf.ACT.p + 3], ast[sf.ACT.p + 3 : sf.ACT.p + 6]
        self.spool = ast[sf.ACT.spool : sf.ACT.spool + 3]
        self.spool_rate = ast[sf.ACT.rate : sf.ACT.rate + 3]
        ast[sf.ACT.ps] = P.p_supply
        ast[sf.ACT.pr], ast[sf.ACT.comp] = P.cut_out, 0.0  # a full receiver, the switch off
        # per leg the seal friction (v_reg 0: the stick model, MuJoCo's dry friction holds
        # F_S; Platform sets it)
        v_reg = P.v_smooth if P.friction_model == "regularised" else 0.0
        fric = [
            sf.FRIC.pack(
                breakaway=P.breakaway[i], coulomb=P.coulomb[i], v_stribeck=P.v_stribeck,
                viscous=P.viscous[i], v_reg=v_reg,
            )
            for i in range(3)
        ]  # fmt: skip
        # the energy model (sf.chamber_energy): wall area A_0 + A_V V per chamber, both
        # ends plus the barrel (and, rod side, the rod) wetted over the length V / A
        bore = 2.0 * math.sqrt(P.area_cap / math.pi)
        rod = 2.0 * math.sqrt(P.area_rod / math.pi)
        a0 = np.concatenate([np.full(3, 2 * P.area_cap), np.full(3, 2 * P.area_rod_side)])
        av = np.concatenate(
            [
                np.full(3, math.pi * bore / P.area_cap),
                np.full(3, math.pi * (bore + rod) / P.area_rod_side),
            ]
        )
        chambers = [
            sf.CH.pack(v0=v0[c], dvdq=dvdq[c], vmin=vmin[c], a0=a0[c], av=av[c]) for c in range(6)
        ]
        thermal = sf.TH.pack(
            on=1.0 if P.thermal_model == "energy" else 0.0, gamma=P.gamma, r=P.gas_constant,
            k=self._kc, tw=P.temperature, hw=P.heat_transfer, h=0.0,
        )  # fmt: skip
        # the supply as built (sf.supply_step): isothermal receiver and line at T
        rt = P.gas_constant * P.temperature
        supply = sf.SUP.pack(
            on=1.0 if P.supply_model == "receiver" else 0.0, rtv_r=rt / P.receiver_volume,
            rtv_l=rt / P.line_volume, kreg=P.regulator_conductance, pset=P.p_supply,
            qc=P.compressor_flow, pon=P.cut_in, poff=P.cut_out, h=0.0,
        )  # fmt: skip
        # the ψ table: grid, values and the slope of each cell (np.interp's)
        n = len(self._xp)
        xl, fl = self._xp.tolist(), self._fp.tolist()
        slopes = [(fl[j + 1] - fl[j]) / (xl[j + 1] - xl[j]) for j in range(n - 1)] + [0.0]
        # h n, the spool's coefficients and the sub-steps' h: set_timestep's
        ac = sf.AC.pack(
            kind=0.0, pa=P.p_atm, a1=P.area_cap, a2=P.area_rod_side, ar=P.area_rod,
            rtk=P.gas_constant * P.temperature * self._kc, eps=P.leakage, hn=0.0, alpha=0.0,
            order=P.spool_order, nsub=int(P.substeps), ntab=n, fric=fric,
            spool=np.zeros(sf.SPOOL.LEN), delta=self._delta, ch=chambers, th=thermal,
            sup=supply, tab=[self._xp, self._fp, slopes],
        )  # fmt: skip
        self.step_constants = ac
        self._table = ([0.0] * sf.ACT.LEN, ac.tolist(), n)  # the ψ table for the static solve
        self.u_hold = np.full(3, U_CENTRE)
        self.reset(np.full(3, 0.5 * P.stroke), np.zeros(3))

    # -- valve ---------------------------------------------------------------
    def set_timestep(self, dt: float) -> None:
        """The step's constants that depend on ``dt`` (s): spool discretisation, ``h n``."""
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        P, ac = self.params, self.step_constants
        self._dt = dt
        ac[sf.AC.hn] = dt / P.substeps * P.n_poly
        ac[sf.AC.th + sf.TH.h] = dt / P.substeps
        ac[sf.AC.sup + sf.SUP.h] = dt
        w = P.spool_omega
        if P.spool_order == 1:
            ac[sf.AC.alpha] = -math.expm1(-w * dt)
        else:  # exact ZOH discretisation of s'' + 2 z w s' + w^2 s = w^2 c
            # scipy on use (a second-order spool only): scipy.linalg and scipy.optimize
            # cost 0.5-2 s to import, and every command that runs a scenario imports
            # this module before it validates its input (errors within a second)
            from scipy.linalg import expm

            a = np.array([[0.0, 1.0, 0.0], [-(w**2), -2 * P.spool_zeta * w, w**2], [0, 0, 0]])
            e = expm(a * dt)
            sf.SPOOL.pack(
                ac[sf.AC.spool : sf.AC.spool + sf.SPOOL.LEN], s_s=e[0, 0], s_r=e[0, 1],
                r_s=e[1, 0], r_r=e[1, 1], s_c=e[0, 2], r_c=e[1, 2],
            )  # fmt: skip

    def psi(self, r):
        """ψ(r) = φ(r)/(1 - r) as used in :meth:`step` (table interpolation)."""
        return np.interp(r, self._xp, self._fp)

    def chamber_net_flow(self, p, spool, chamber: int):
        """Net mass flow into chamber 1 or 2 (kg/s) at pressures p (3,), spools (3,).

        The same flow law as :meth:`step` (ψ table): supply edge
        :math:`a_P k ψ(p/p_s)(p_s - p)` minus exhaust edge :math:`a_R k ψ(p_a/p)(p - p_a)`.
        """
        p, s = np.broadcast_to(p, (3,)), np.broadcast_to(spool, (3,))
        return np.array([self._net_flow(float(p[i]), float(s[i]), i, chamber) for i in range(3)])

    def _net_flow(self, p: float, s: float, leg: int, chamber: int) -> float:
        """:meth:`chamber_net_flow` of one leg in scalar arithmetic (the static solve's).

        Python floats in numpy's order of operations, ψ interpolated by the
        step's own table look-up on lists (the same bits as ``np.interp``): a
        tenth of the array form's cost (the nested Brent iterations of
        :meth:`equilibrium` evaluate it about a thousand times, in the GIL,
        before every run).
        """
        P, d = self.params, self._delta[leg]
        ps, pa, kc, eps = P.p_supply, P.p_atm, self._kc, P.leakage
        # metering edges: supply P->1 and exhaust 2->R open with +s, P->2 and 1->R with -s
        a_in = min(max(d + s if chamber == 1 else d - s, eps), 1.0)
        a_out = min(max(d - s if chamber == 1 else d + s, eps), 1.0)
        m_in = a_in * kc * sf._psi(p / ps, 0, *self._table) * (ps - p)
        m_out = a_out * kc * sf._psi(pa / p, 6, *self._table) * (p - pa)
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
        P, F = self.params, np.broadcast_to(np.asarray(force, float), (3,))
        s_out, p1_out, p2_out = np.zeros(3), np.zeros(3), np.zeros(3)
        for i in range(3):

            def f_of(s, i=i):
                p1, p2 = self._static_pressure(i, s, 1), self._static_pressure(i, s, 2)
                return p1 * P.area_cap - p2 * P.area_rod_side - P.p_atm * P.area_rod - F[i]

            lo, hi = f_of(-1.0), f_of(1.0)
            if lo >= 0:
                s = -1.0
            elif hi <= 0:
                s = 1.0
            else:
                s = brentq(f_of, -1.0, 1.0, xtol=1e-12)
            s_out[i] = s
            p1_out[i] = self._static_pressure(i, s, 1)
            p2_out[i] = self._static_pressure(i, s, 2)
        return s_out, p1_out, p2_out

    def _static_pressure(self, leg: int, s: float, chamber: int) -> float:
        """Pressure of zero net flow into a chamber at spool ``s`` (Brent)."""
        P, args = self.params, (s, leg, chamber)
        return brentq(self._net_flow, P.p_atm, P.p_supply, args=args, xtol=1e-7, rtol=1e-14)

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
        self.step_state[sf.ACT.t : sf.ACT.t + 6] = self.params.temperature  # at the wall's
        self.u_hold[:] = U_CENTRE + 5.0 * s

    def force_now(self, qdot) -> np.ndarray:
        """Net slide force (N) of the present pressures at speed ``qdot``."""
        qd = np.asarray(np.broadcast_to(np.asarray(qdot, float), (3,)), dtype=float)
        f = np.zeros(3)
        sf.slide_forces(qd, self.step_state, self.step_constants, f)
        return f


def _as3(x) -> np.ndarray:
    """Three float64 numbers from a (3,) array, a sequence of 3 or a scalar."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype=float), (3,)))
