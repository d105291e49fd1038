"""The statistical linearisations of the Fig. 12 experiment's linear model.

Two parts of :mod:`simpro_mj.identification.linear_experiment`'s model are not
differentiable where the experiment runs them, and are replaced by their
random-input describing functions (Booton 1954; Gelb & Vander Velde, *Multiple-input
describing functions*, 1968, ch. 2) at the RMS the linear model's own response gives:

* :func:`pneumatic_matrices`: each leg's valve spool and chambers, the 1 ms step's own
  functions (:mod:`simpro_mj.plant.step_functions`) differentiated by central
  differences about the holding equilibrium, the metering edges' gain averaged over a
  Gaussian spool (Stein's identity, :data:`NODES` points);
* :func:`equivalent_viscous`: a seal's whole friction curve as an equivalent viscous
  coefficient for a Gaussian speed.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from simpro_mj.plant import step_functions as sf
from simpro_mj.plant.friction import seal_friction

if TYPE_CHECKING:
    from simpro_mj.identification.linear_experiment import ExperimentModel

__all__ = ["equivalent_viscous", "pneumatic_matrices", "NODES", "NODE_SPAN", "SIGMA_V_MIN"]

#: Points of the spool's statistical linearisation: a trapezoid rule over the Gaussian
#: within ±NODE_SPAN standard deviations. The edges' kinks make Gauss-Hermite nodes
#: converge slowly (legs 2-3's b on ``paper``: 97.08, 97.51, 97.74, 97.86 with 9, 17,
#: 33, 65 nodes); the trapezoid gives 97.84, 97.95, 97.95 with 25, 49, 97 points.
NODES = 49
NODE_SPAN = 5.0
#: Central-difference steps: pressure (Pa), temperature (K), slide (m), speed (m/s),
#: spool (fraction), volts.
H_P, H_T, H_Q, H_V, H_S, H_U = 50.0, 1e-3, 1e-7, 1e-6, 1e-6, 1e-4
#: The smallest speed standard deviation (m/s): a seal held still has c_eq of F_S
#: sqrt(2/pi) / 1e-7, about 1e9 N s/m at 250 N: locked.
SIGMA_V_MIN = 1e-7
#: Points of the friction's Gaussian expectation (z from -8 to 8).
_Z = np.linspace(-8.0, 8.0, 801)
_PDF = np.exp(-0.5 * _Z**2) / math.sqrt(2.0 * math.pi)


def equivalent_viscous(friction, sigma_v: float) -> float:
    """The seal's dry part as an equivalent viscous coefficient (N s/m) for a Gaussian
    speed of RMS ``sigma_v``: :math:`E[F_f(v) v]/σ_v^2 - β` (module docstring), the
    whole curve (MuJoCo's dry friction and :func:`seal_friction`) less its viscous
    coefficient β, which the model keeps explicit.

    Under the ``stick`` model (``v_reg`` 0) in closed form: with the step's part
    :math:`βv - (F_S - F_C)(1 - e^{-(v/v_S)^2})\\,\\mathrm{sgn}(v)` and MuJoCo's
    ``F_d sgn(v)``, :math:`E[|v|] = σ\\sqrt{2/π}` and
    :math:`E[|v| e^{-(v/v_S)^2}] = σ\\sqrt{2/π}\\, v_S^2/(v_S^2 + 2σ^2)`; under the
    ``regularised`` one by quadrature of :func:`seal_friction` itself.
    """
    dry, args = friction
    f_s, f_c, v_s, beta, v_reg = args
    s = max(float(sigma_v), SIGMA_V_MIN)
    k = math.sqrt(2.0 / math.pi) / s
    if v_reg == 0.0:
        return (dry - (f_s - f_c)) * k + (f_s - f_c) * k * v_s**2 / (v_s**2 + 2.0 * s**2)
    v = s * _Z
    curve = dry * np.sign(v) + np.vectorize(seal_friction)(v, *args)
    dz = _Z[1] - _Z[0]
    return float(np.sum(curve * v * _PDF) * dz / s**2) - beta


def _chambers(em: ExperimentModel, ast: np.ndarray, q, qd) -> np.ndarray:
    """The chamber stage of one step from ``ast`` (spool already moved): the new
    per-leg states and forces, ``(3, n_leg - spool states + 1)``: p1, p2, [T1, T2], F."""
    ac = em.act.step_constants
    st = ast.copy()
    if em.thermal:
        sf.chamber_energy(q, qd, st, ac)
    else:
        sf.chamber_pressures(q, qd, st, ac)
    f = np.zeros(3)
    sf.slide_forces(qd, st, ac, f)
    cols = [st[sf.ACT.p : sf.ACT.p + 3], st[sf.ACT.p + 3 : sf.ACT.p + 6]]
    if em.thermal:
        cols += [st[sf.ACT.t : sf.ACT.t + 3], st[sf.ACT.t + 3 : sf.ACT.t + 6]]
    return np.column_stack([*cols, f])


def _gas_slots(em: ExperimentModel) -> list:
    """Offsets in the actuators' state of leg 0's gas states (p1, p2, [T1, T2]) and
    their difference steps."""
    slots = [(sf.ACT.p, H_P), (sf.ACT.p + 3, H_P)]
    if em.thermal:
        slots += [(sf.ACT.t, H_T), (sf.ACT.t + 3, H_T)]
    return slots


def pneumatic_matrices(em: ExperimentModel, sigma_s: np.ndarray):
    """Per leg the linear pneumatic step ``x+ = A x + B_u du + B_q dq + B_v v``,
    ``F - F_h = C x + D_u du + D_q dq + D_v v`` with the leg's state x = (gas states,
    spool, [rate]), statistically linearised over a Gaussian spool of RMS
    ``sigma_s`` (3,) (module docstring). Returns a list of 3 tuples."""
    ac = em.act.step_constants
    base = em.base
    q0 = np.full(3, float(em.ip.position_mm) * 1e-3)
    z0 = np.zeros(3)
    slots = _gas_slots(em)
    ng = len(slots)
    # the valve stage: spool (and rate) <- spool, rate, command; linear but for the clip
    spool_idx = [sf.ACT.spool] + ([sf.ACT.rate] if em.order2 else [])
    nsp = len(spool_idx)

    def valve(st, u):
        st = st.copy()
        sf.valve_spool(u, st, ac)
        return np.column_stack([st[k : k + 3] for k in spool_idx])  # (3, nsp)

    v_base = valve(base, em.u_hold)
    v_x = []
    for k in spool_idx:
        sp, sm = base.copy(), base.copy()
        sp[k : k + 3] += H_S
        sm[k : k + 3] -= H_S
        v_x.append((valve(sp, em.u_hold) - valve(sm, em.u_hold)) / (2 * H_S))
    v_u = (valve(base, em.u_hold + H_U) - valve(base, em.u_hold - H_U)) / (2 * H_U)

    # the chamber stage averaged over the spool the edges see (after the valve stage)
    s_mid = base.copy()
    s_mid[sf.ACT.spool : sf.ACT.spool + 3] = v_base[:, 0]
    if em.order2:
        s_mid[sf.ACT.rate : sf.ACT.rate + 3] = v_base[:, 1]
    s0 = s_mid[sf.ACT.spool : sf.ACT.spool + 3].copy()
    sig = np.asarray(sigma_s, float)
    if np.all(sig <= 0.0):
        zs, ws = np.zeros(1), np.ones(1)
    else:
        zs = np.linspace(-NODE_SPAN, NODE_SPAN, NODES)
        ws = np.exp(-0.5 * zs**2)
        ws /= ws.sum()
    d_gas = np.zeros((3, ng + 1, ng))  # outputs (gas states, F) per gas state
    d_spool = np.zeros((3, ng + 1))
    d_q = np.zeros((3, ng + 1))
    d_v = np.zeros((3, ng + 1))
    for z, w in zip(zs, ws, strict=True):
        st = s_mid.copy()
        st[sf.ACT.spool : sf.ACT.spool + 3] = s0 + sig * z
        for g, (k, h) in enumerate(slots):
            sp, sm = st.copy(), st.copy()
            sp[k : k + 3] += h
            sm[k : k + 3] -= h
            d_gas[:, :, g] += w * (_chambers(em, sp, q0, z0) - _chambers(em, sm, q0, z0)) / (2 * h)
        d_q += w * (_chambers(em, st, q0 + H_Q, z0) - _chambers(em, st, q0 - H_Q, z0)) / (2 * H_Q)
        d_v += w * (_chambers(em, st, q0, z0 + H_V) - _chambers(em, st, q0, z0 - H_V)) / (2 * H_V)
        if len(zs) > 1:  # Stein's identity: E[g'(s)] = E[g(s) (s - s0)] / sigma^2
            d_spool += w * _chambers(em, st, q0, z0) * (z / np.where(sig > 0, sig, 1.0))[:, None]
    if len(zs) == 1 or np.any(sig <= 0.0):
        st = s_mid.copy()
        sp, sm = st.copy(), st.copy()
        sp[sf.ACT.spool : sf.ACT.spool + 3] += H_S
        sm[sf.ACT.spool : sf.ACT.spool + 3] -= H_S
        point = (_chambers(em, sp, q0, z0) - _chambers(em, sm, q0, z0)) / (2 * H_S)
        if len(zs) == 1:
            d_spool = point
        else:
            d_spool[sig <= 0.0] = point[sig <= 0.0]
    out = []
    for i in range(3):
        fr = em.friction[i][1]
        # the step's own friction slope at rest, less its viscous part: the rest of the
        # curve is the describing function's (implicit, in the mechanics)
        slope = (seal_friction(H_V, *fr) - seal_friction(-H_V, *fr)) / (2 * H_V)
        n = ng + nsp
        a = np.zeros((n, n))
        bu = np.zeros(n)
        bq = np.zeros(n)
        bv = np.zeros(n)
        # valve rows: spool states
        for r in range(nsp):
            for c in range(nsp):
                a[ng + r, ng + c] = v_x[c][i, r]
            bu[ng + r] = v_u[i, r]
        # chamber rows and the force: through the spool the edges see (valve row 0)
        gs = d_spool[i]  # (ng + 1,) per unit of the new spool
        rows = np.zeros((ng + 1, n))
        rows[:, :ng] = d_gas[i]
        for c in range(nsp):
            rows[:, ng + c] += gs * v_x[c][i, 0]
        ru = gs * v_u[i, 0]
        a[:ng] = rows[:ng]
        bu[:ng] = ru[:ng]
        bq[:ng] = d_q[i, :ng]
        bv[:ng] = d_v[i, :ng]
        c_row = rows[ng]
        du = ru[ng]
        dq = d_q[i, ng]
        dv = d_v[i, ng] + slope - fr[3]  # + viscous explicit: -beta
        out.append((a, bu, bq, bv, c_row, du, dq, dv))
    return out
