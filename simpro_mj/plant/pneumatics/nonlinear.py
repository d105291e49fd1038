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
linearly implicit (Rosenbrock-Euler) step,
:math:`p^+ = p + h f(p) / (1 - h \\min(∂f/∂p, 0))`, which is L-stable for the
stiff flow terms and has the exact static equilibrium as fixed point. It is
not bounded: a chamber compressed above the supply pressure flows back to
the supply through its supply edge (ISO 6358 with the chamber upstream, ratio
p_s/p), one expanded below the atmosphere draws air through its exhaust
edge (ratio p/p_a); the MPYE has no relief valve. ``integration.substeps``
splits the step further (default 1; tests compare with a fine reference).

The per-step arithmetic runs on Python floats, or in the optional compiled
kernel (:mod:`.kernel`, numba) with the same bits.
"""

from __future__ import annotations

import math
from bisect import bisect_right

import numpy as np

from simpro_mj.plant.friction import seal_friction
from simpro_mj.plant.kernels import kernel_choice
from simpro_mj.plant.pneumatics import kernel as _pk
from simpro_mj.plant.pneumatics.flow import RHO_REF, T_REF, psi_table
from simpro_mj.plant.pneumatics.params import U_CENTRE, PneumaticParams

__all__ = ["NonlinearActuators"]


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
        self._xp, self._fp = psi_table(P.b_crit, P.r_laminar)
        # metering edges as a (4, 3) block: rows P->1, P->2, 1->R, 2->R
        self._sg = np.array([[1.0], [-1.0], [-1.0], [1.0]]) * np.ones((1, 3))
        self._delta = np.broadcast_to(P.underlap, (4, 3)).copy()
        self._eps = P.leakage
        # One work vector z: [p1 (3), p2 (3), qdot (3), seal friction (3), 1, 3 spare],
        # followed by the spool positions and rates: the head of the compiled
        # kernel's buffer (kernel.py), whose views they are
        self._kb = np.zeros(_pk.buffer_len(len(self._xp)))
        z = self._kb[:16]
        z[12] = 1.0
        self._z = z
        self._p = z[:6]
        self.p1, self.p2 = z[:3], z[3:6]
        self._zqd, self._zfr, self._z13 = z[6:9], z[9:12], z[:13]
        # force F = A1 p1 - A2 p2 - pa Ar - F_f(qdot) = Mf @ z[:13]
        mf = np.zeros((3, 13))
        i3 = np.arange(3)
        mf[i3, i3] = self._A1
        mf[i3, 3 + i3] = -self._A2
        mf[i3, 9 + i3] = -1.0
        mf[:, 12] = -pa * self._Ar
        self._mf = mf
        # seal friction per leg: (breakaway, Coulomb, Stribeck velocity, viscous, v_reg)
        self._fric = tuple(
            (float(P.breakaway[i]), float(P.coulomb[i]), P.v_stribeck, float(P.viscous[i]),
             P.v_smooth)
            for i in range(3)
        )  # fmt: skip
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
        if kernel_choice() == "numba":  # SIMPRO_KERNEL (simpro_mj.plant.kernels)
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
            # scipy on use (a second-order spool only): scipy.linalg and scipy.optimize
            # cost 0.5-2 s to import, and every command that runs a scenario imports
            # this module before it validates its input (errors within a second)
            from scipy.linalg import expm

            a = np.array([[0.0, 1.0, 0.0], [-(w**2), -2 * P.spool_zeta * w, w**2], [0, 0, 0]])
            e = expm(a * dt)
            self._spool_ad = e[:2, :2].copy()
            self._spool_bd = e[:2, 2].copy()
        if self._kernel is not None:
            self._fill_kernel_dt()

    def _init_kernel(self) -> None:
        """Constants of the compiled kernel in its buffer (:mod:`.kernel`)."""
        pk, kb = _pk, self._kb
        kb[pk.KP_PS], kb[pk.KP_PA], kb[pk.KP_RTK] = self._ps, self._pa, self._RTk
        kb[pk.KP_EPS] = self._eps
        for i, fr in enumerate(self._fric):
            kb[pk.KP_FRIC + 5 * i : pk.KP_FRIC + 5 * i + 5] = fr
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
                from scipy.optimize import brentq  # on use, see _set_dt

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

        from scipy.optimize import brentq  # on use, see _set_dt

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
        qd = _as3(qdot)
        self._zqd[:] = qd
        for i, fr in enumerate(self._fric):
            self._zfr[i] = seal_friction(qd[i], *fr)
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
        The hot path of the co-simulation. Three legs of two
        chambers are too few for numpy: a ufunc on a 3-vector costs about as
        much as 20 float operations in the interpreter. The per-chamber
        arithmetic therefore runs on Python floats, operation for operation
        the same IEEE expressions as the compiled kernel (:mod:`.kernel`), so
        both give the same bits. The force product ``Mf @ z`` stays in numpy
        (BLAS accumulates with FMA; a scalar rewrite would round differently).
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
        z = self._z  # [p1 (3), p2 (3), qdot (3), seal friction (3), 1, spare (3)]
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
        # force on the slide less the seal friction: Mf @ z
        z[6], z[7], z[8] = qd
        fr = self._fric
        z[9] = seal_friction(qd[0], *fr[0])
        z[10] = seal_friction(qd[1], *fr[1])
        z[11] = seal_friction(qd[2], *fr[2])
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
