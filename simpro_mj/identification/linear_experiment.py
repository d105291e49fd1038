"""The linear model of the whole Fig. 12 experiment, and eq. (19) fitted to it.

The identification (:mod:`simpro_mj.identification.identify`) excites one leg of
the closed chain while proportional position loops hold all three, and fits a
one-leg model to that leg's voltage and speed. A linearisation of the *leg*
(the other slides held rigidly, the seals' dry friction left out) is not what
that experiment measures: legs 2 and 3 are a pair coupled through the
platform, and seals that stick have no derivative at rest. Here the
*experiment* is linearised instead, and the same fit runs on its response:

* **Mechanics**: the closed chain reduced to the slides at the operating point
  (:mod:`simpro_mj.plant.pneumatics.statics`): mass :math:`M_q`, joint damping
  :math:`D_q` and gravity stiffness :math:`K_q = ∂F_h/∂q` (3 x 3 each, central
  differences of the holding forces), stepped like MuJoCo's ``implicitfast``
  Euler: :math:`(M_q + h (D_q + C)) v^+ = M_q v + h (F - F_h - K_q (q - q_0))`,
  :math:`q^+ = q + h v^+`.
* **Pneumatics**: each leg's valve spool (first or second order) and chambers
  (pressures, and temperatures under the energy model), the 1 ms step's own
  functions (:mod:`simpro_mj.plant.step_functions`) differentiated by central
  differences about the holding equilibrium. The metering edges are
  piecewise linear in the spool (the underlap ``δ`` is 0.3-2 % of the stroke
  where the experiment swings it by several %): their derivative is
  **statistically linearised** over a Gaussian spool of the standard deviation
  the linear model's own response gives (Booton 1954; Gelb & Vander Velde,
  *Multiple-input describing functions*, 1968, ch. 2): the flows' gain
  :math:`E[g(s)(s - s_0)]/σ_s^2` (Stein's identity) and the other derivatives
  averaged over the same distribution (:mod:`simpro_mj.identification.linear_pneumatics`).
  The supply is held at its pressure (its receiver's dynamics are left out).
* **Seals**: the whole friction curve, MuJoCo's dry friction :math:`F_S\\,
  \\mathrm{sgn}(v)` plus the step's own part (:func:`simpro_mj.plant.friction.seal_friction`),
  by the random-input describing function: for a Gaussian speed of RMS
  :math:`σ_v` the equivalent viscous coefficient :math:`c_{eq} = E[F_f(v) v]/σ_v^2`
  (for a Coulomb force :math:`F_C \\sqrt{2/π}/σ_v`; the Stribeck peak adds
  :math:`(F_S - F_C)\\sqrt{2/π}/σ_v\\; v_S^2/(v_S^2 + 2σ_v^2)`), integrated
  implicitly as MuJoCo's constraint friction is. The viscous part β stays
  explicit, as in the step. What it leaves out: the intervals a seal *sticks*
  (a Gaussian speed is never at rest for a finite time) and the breakaway's
  memory.
* **Loops**: the experiment's own law (:mod:`controllers.experiment_law`):
  :math:`u = u_h + K_p (q_{ref} - q) + w + x_i`, the valves' dither ``w`` and
  the sequence ``x_i`` on leg i (the same ±amplitude maximum-length sequence,
  clock and seed), the valves' saturation left out.

Each leg's experiment is iterated to a fixed point: the standard deviations of
the three speeds and spools over the record (after the settling) set the seals'
:math:`c_{eq}` and the edges' gains, the linear model's response gives them
again (geometric mean of the old and the new, to convergence within
``TOL``). The model is then simulated on the sequence (exactly, in its modes:
no MuJoCo, no step loop) and eq. (19) is fitted to the leg's recorded voltage
and speed by the experiment's own :func:`~simpro_mj.identification.identify.fit_eq19`,
which is what the output-error fit of the experiment does in expectation.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import mujoco
import numpy as np

from controllers.design import paper_coefficients
from controllers.dither import dither_signal
from simpro_mj.core.errors import UserInputError
from simpro_mj.identification.identify import Fit, _prbs, fit_eq19
from simpro_mj.identification.linear_pneumatics import (
    SIGMA_V_MIN,
    equivalent_viscous,
    pneumatic_matrices,
)
from simpro_mj.identification.settings import Settings, check_tree, leg_values
from simpro_mj.plant import step_functions as sf
from simpro_mj.plant.model import PlantIndex, assemble, load_model
from simpro_mj.plant.platform import set_seal_friction
from simpro_mj.plant.pneumatics.factory import make_actuators
from simpro_mj.plant.pneumatics.nonlinear import NonlinearActuators
from simpro_mj.plant.pneumatics.statics import (
    holding_forces,
    holding_stiffness,
    slide_damping_matrix,
    slide_mass_matrix,
)

__all__ = [
    "ExperimentModel",
    "LegResult",
    "build",
    "identify_linear",
    "TOL",
]

#: Relative change of the standard deviations that ends the fixed-point iteration.
TOL = 1e-3
#: Most fixed-point iterations per leg.
MAX_ITER = 60
#: Relative change of a spool's RMS within which its statistical linearisation is reused.
SIGMA_S_REUSE = 0.05
#: A seal whose speed RMS stays below this (m/s) is held (c_eq above ~1e5 N s/m at
#: 1.7 N): the fixed point's convergence ignores it.
SIGMA_V_LOCKED = 1e-5


@dataclass
class LegResult:
    """One leg's experiment on the linear model: the fit and the fixed point."""

    fit: Fit
    sigma_v: np.ndarray  # m/s, the three slides' speed RMS over the record
    sigma_s: np.ndarray  # the three spools' RMS deviation
    c_eq: np.ndarray  # N s/m, the seals' equivalent viscous friction (dry part)
    iterations: int
    u: np.ndarray = field(repr=False)  # V, the leg's voltage over the record
    qdot: np.ndarray = field(repr=False)  # m/s, its speed


@dataclass
class ExperimentModel:
    """The experiment's operating point and the pieces of its linear model."""

    dt: float
    mass: np.ndarray  # (3, 3) kg
    damping: np.ndarray  # (3, 3) N s/m, the mechanism's joints
    stiffness: np.ndarray  # (3, 3) N/m, dF_h/dq
    kp: np.ndarray  # V/m
    u_hold: np.ndarray  # V
    friction: list  # per leg: (dry F_S of MuJoCo, seal_friction's five arguments)
    act: NonlinearActuators  # the actuators, reset at the holding equilibrium
    base: np.ndarray  # their state there
    thermal: bool
    order2: bool
    ip: Settings  # the identify settings
    cache: list = field(
        default_factory=lambda: [[], [], []]
    )  # per leg: (spool RMS, its pneumatics)

    @property
    def n_leg(self) -> int:
        """Pneumatic states per leg: p1, p2, [T1, T2], spool, [spool rate]."""
        return 3 + 2 * self.thermal + self.order2


def build(tree: dict, model=None) -> ExperimentModel:
    """The operating point of ``tree``'s experiment and its mechanics (module docstring)."""
    ex = check_tree(tree)
    ip = ex.settings
    m = model if model is not None else load_model(ex.model)
    d = mujoco.MjData(m)
    idx = PlantIndex.of(m)
    dt = float(m.opt.timestep)
    q0 = np.full(3, float(ip.position_mm) * 1e-3)
    stiffness = holding_stiffness(m, d, q0, 1e-4, idx)
    assemble(m, d, q0, index=idx)
    f_hold = holding_forces(m, d, idx)
    mass = slide_mass_matrix(m, d, idx)
    damping = slide_damping_matrix(m, d, idx)
    act = make_actuators(
        ip.actuator_kind,
        ex.pneumatics,
        model=m,
        linear_plants=paper_coefficients(ex.paper_units),
    )
    if not isinstance(act, NonlinearActuators):
        raise UserInputError(
            "invalid value at identify.actuator_kind: the experiment's linearisation needs "
            "'nonlinear' (eq. 19's linear actuators are their own model)"
        )
    set_seal_friction(m, idx, act)
    dry = np.asarray(m.dof_frictionloss[idx.slide_dof], float).copy()
    act.reset(q0, np.zeros(3), force=f_hold)
    act.set_timestep(dt)
    ac = act.step_constants
    friction = []
    for i in range(3):
        c = sf.AC.fric + sf.FRIC.LEN * i
        f = sf.FRIC
        args = tuple(
            float(ac[c + k]) for k in (f.breakaway, f.coulomb, f.v_stribeck, f.viscous, f.v_reg)
        )
        friction.append((float(dry[i]), args))
    return ExperimentModel(
        dt=dt,
        mass=mass,
        damping=damping,
        stiffness=stiffness,
        kp=np.asarray(leg_values(ip.kp_v_per_m, "kp_v_per_m"), float),
        u_hold=act.u_hold.copy(),
        friction=friction,
        act=act,
        base=act.step_state.copy(),
        thermal=bool(ac[sf.AC.th + sf.TH.on] != 0.0),
        order2=bool(ac[sf.AC.order] != 1.0),
        ip=ip,
    )


def closed_loop(em: ExperimentModel, leg: int, pm: list, c_eq):
    """``(Phi, Gamma)`` of the experiment's closed loop per step, state
    ``(dq (3), v (3), leg 1's x, leg 2's, leg 3's)``, inputs (dither on every valve,
    the sequence on ``leg`` 1-3); and the rows of the outputs ``du`` (3) and the
    spool (3) as ``(rows_u, cols_u, spool_rows)``; ``pm`` the legs' pneumatics
    (:func:`pneumatic_matrices`), ``c_eq`` (3,) the seals' equivalent viscous friction."""
    nl = pm[0][0].shape[0]
    n = 6 + 3 * nl
    dt = em.dt
    phi = np.zeros((n, n))
    gam = np.zeros((n, 2))
    # du = -Kp dq + w + [leg] x
    du_x = np.zeros((3, n))
    du_x[:, :3] = -np.diag(em.kp)
    du_in = np.zeros((3, 2))
    du_in[:, 0] = 1.0
    du_in[leg - 1, 1] = 1.0
    f_x = np.zeros((3, n))
    f_in = np.zeros((3, 2))
    for i, (a, bu, bq, bv, c_row, du, dq, dv) in enumerate(pm):
        s = slice(6 + i * nl, 6 + (i + 1) * nl)
        phi[s, s] += a
        phi[s, :] += np.outer(bu, du_x[i])
        gam[s, :] += np.outer(bu, du_in[i])
        phi[s, i] += bq
        phi[s, 3 + i] += bv
        f_x[i, s] += c_row
        f_x[i, :] += du * du_x[i]
        f_in[i] += du * du_in[i]
        f_x[i, i] += dq
        f_x[i, 3 + i] += dv
    # mechanics: (M + h (D + C)) v+ = M v + h (F - K dq); dq+ = dq + h v+
    lhs = em.mass + dt * (em.damping + np.diag(c_eq))
    inv = np.linalg.inv(lhs)
    v_x = dt * inv @ (f_x - np.hstack([em.stiffness, np.zeros((3, n - 3))]))
    v_x[:, 3:6] += inv @ em.mass
    v_in = dt * inv @ f_in
    phi[3:6] = v_x
    gam[3:6] = v_in
    phi[:3] = dt * v_x
    phi[:3, :3] += np.eye(3)
    gam[:3] = dt * v_in
    spool_rows = [6 + i * nl + (nl - 1 - em.order2) for i in range(3)]
    return phi, gam, du_x, du_in, spool_rows


def simulate(phi: np.ndarray, gam: np.ndarray, inputs: np.ndarray) -> np.ndarray:
    """States at each step's start, ``(n_steps, n)``, from rest, for ``inputs``
    ``(n_steps, 2)``: exactly, mode by mode (``scipy.signal.lfilter`` per eigenvalue),
    or step by step when the modes are ill-conditioned."""
    from scipy.signal import lfilter

    lam, vec = np.linalg.eig(phi)
    if np.linalg.cond(vec) < 1e8:
        drive = inputs @ np.linalg.solve(vec, gam.astype(complex)).T  # (n_steps, n)
        z = np.empty_like(drive)
        for j in range(lam.size):
            z[:, j] = lfilter([0.0, 1.0], [1.0, -lam[j]], drive[:, j])
        return (z @ vec.T).real
    x = np.zeros(phi.shape[0])
    out = np.empty((inputs.shape[0], phi.shape[0]))
    g_in = inputs @ gam.T
    for k in range(inputs.shape[0]):
        out[k] = x
        x = phi @ x + g_in[k]
    return out


def _inputs(em: ExperimentModel, leg: int) -> tuple[np.ndarray, int]:
    """The dither and the sequence by step (as the experiment's ``exc``) and the
    first row of the record."""
    ip, dt = em.ip, em.dt
    n_settle = int(round(float(ip.settle_s) / dt))
    n_exc = int(round(float(ip.duration_s) / dt))
    clock = max(1, int(round(float(ip.prbs_clock_ms) * 1e-3 / dt)))
    amp = leg_values(ip.prbs_amplitude_v, "prbs_amplitude_v")
    inp = np.zeros((n_settle + n_exc, 2))
    inp[:, 0] = dither_signal(
        n_settle + n_exc, dt, float(ip.dither_v), float(ip.dither_period_ms) * 1e-3
    )[:, 0]
    inp[n_settle:, 1] = amp[leg - 1] * _prbs(n_exc, clock, int(ip.prbs_bits), int(ip.seed))
    return inp, n_settle


def stationary_rms(em: ExperimentModel, leg: int, phi: np.ndarray, gam: np.ndarray):
    """RMS of each state of the closed loop ``(phi, gam)`` in its stationary response to
    leg ``leg``'s experiment: the sequence as independent ±amplitude bits held for its
    clock (a maximum-length sequence's autocorrelation is -1/period off its peak), by a
    discrete Lyapunov equation at the bit boundaries and each phase within a bit; the
    dither's periodic response by its exact periodic steady state; the two add
    (uncorrelated). Costs a few 18 x 18 products where a simulation steps 21 s."""
    from scipy.linalg import solve_discrete_lyapunov

    ip, n = em.ip, phi.shape[0]
    clock = max(1, int(round(float(ip.prbs_clock_ms) * 1e-3 / em.dt)))
    amp = leg_values(ip.prbs_amplitude_v, "prbs_amplitude_v")[leg - 1]
    g = gam[:, 1]
    pj, gj = np.eye(n), np.zeros(n)
    phases = []
    for _ in range(clock):
        phases.append((pj, gj))
        pj, gj = phi @ pj, phi @ gj + g
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        p = solve_discrete_lyapunov(pj, amp**2 * np.outer(gj, gj))  # bilinear, fast
    if said:  # ill-posed (locked seals' modes at 1, others near -1): the record's own RMS
        inp, start = _inputs(em, leg)
        return np.sqrt(np.mean(simulate(phi, gam, inp)[start:] ** 2, axis=0))
    var = np.zeros(n)
    for pk, gk in phases:
        var += np.einsum("ij,jk,ik->i", pk, p, pk) + amp**2 * gk**2
    var /= clock
    a_w = float(ip.dither_v)
    if a_w > 0.0:
        half = int(round(float(ip.dither_period_ms) * 1e-3 / em.dt / 2.0))
        w = np.where(np.arange(2 * half) < half, a_w, -a_w)
        x = np.zeros(n)
        for wk in w:
            x = phi @ x + gam[:, 0] * wk
        x = np.linalg.solve(np.eye(n) - np.linalg.matrix_power(phi, 2 * half), x)
        ms = np.zeros(n)
        for wk in w:
            ms += x**2
            x = phi @ x + gam[:, 0] * wk
        var += ms / w.size
    return np.sqrt(np.maximum(var, 0.0))


def _matrices(em: ExperimentModel, sigma_s: np.ndarray) -> list:
    """The pneumatics statistically linearised at ``sigma_s``, leg by leg (each leg's
    depends on its own spool only) reused for a spool RMS within ``SIGMA_S_REUSE`` of
    one already computed: they move little near the fixed point, the legs take each
    other's swings in turn, and each computation costs some 450 interpreted chamber
    steps."""
    out: list = [None, None, None]
    for i in range(3):
        for done, block in em.cache[i]:
            if abs(done - sigma_s[i]) <= SIGMA_S_REUSE * max(sigma_s[i], 1e-3):
                out[i] = block
                break
    if any(b is None for b in out):
        pm = pneumatic_matrices(em, sigma_s)
        for i in range(3):
            em.cache[i].append((float(sigma_s[i]), pm[i]))
            out[i] = out[i] if out[i] is not None else pm[i]
    return out


def experiment_leg(em: ExperimentModel, leg: int) -> LegResult:
    """Leg ``leg``'s experiment on the linear model, iterated to its fixed point, and
    eq. (19) fitted to it (module docstring)."""
    # start: the spools as the valves' commands alone would swing them (the dither on
    # every valve, the sequence on the leg's), the seals at 1 mm/s
    amp = leg_values(em.ip.prbs_amplitude_v, "prbs_amplitude_v")[leg - 1]
    sigma_s = np.full(3, float(em.ip.dither_v) / 5.0)
    sigma_s[leg - 1] = math.hypot(sigma_s[leg - 1], amp / 5.0)
    sigma_v = np.full(3, 1e-3)
    it = 0
    for it in range(1, MAX_ITER + 1):
        c_eq = np.array([equivalent_viscous(em.friction[j], sigma_v[j]) for j in range(3)])
        pm = _matrices(em, sigma_s)
        phi, gam, du_x, du_in, spool_rows = closed_loop(em, leg, pm, c_eq)
        if np.max(np.abs(np.linalg.eigvals(phi))) >= 1.0:
            # no stationary response: a loop unstable in the small grows until the
            # valves' gains fall: a larger spool swing, and again
            sigma_s = np.minimum(2.0 * sigma_s + 1e-3, 1.0)
            continue
        rms = stationary_rms(em, leg, phi, gam)
        new_v = np.maximum(rms[3:6], SIGMA_V_MIN)
        new_s = rms[spool_rows]
        moving = (new_v > SIGMA_V_LOCKED) | (sigma_v > SIGMA_V_LOCKED)
        change = float(np.max(np.abs(np.log(new_v / sigma_v))[moving], initial=0.0))
        if it > 1:
            change = max(change, float(np.max(np.abs(new_s - sigma_s) / np.maximum(new_s, 1e-9))))
        sigma_v = new_v
        sigma_s = new_s if it == 1 else 0.5 * (sigma_s + new_s)
        if change < TOL:
            break
    if np.max(np.abs(np.linalg.eigvals(phi))) >= 1.0:
        raise UserInputError(
            f"invalid value at identify.kp_v_per_m: the experiment's linear model of "
            f"actuator {leg} is unstable at every swing tried with K_p "
            f"{[float(k) for k in em.kp]} V/m"
        )
    inp, start = _inputs(em, leg)
    x = simulate(phi, gam, inp)[start:]
    du = x @ du_x.T + inp[start:] @ du_in.T
    u = em.u_hold[leg - 1] + du[:, leg - 1]
    v = x[:, 3 + leg - 1]
    skip = int(round(float(em.ip.fit_skip_s) / em.dt))
    fit = fit_eq19(u, v, em.dt, skip=skip, method=em.ip.fit_method)
    return LegResult(fit, sigma_v, sigma_s, c_eq, it, u, v)


def identify_linear(
    tree: dict,
    legs=(1, 2, 3),
    model=None,
    details: dict | None = None,
    experiment: ExperimentModel | None = None,
) -> dict:
    """Eq. (19) per leg fitted to the experiment's linear model; ``{"actuator<i>": fit}``
    as :func:`simpro_mj.identification.identify.identify` returns. ``details``, when
    given, receives each leg's :class:`LegResult`; ``experiment``, the model
    :func:`build` made of ``tree`` (else built here)."""
    em = experiment if experiment is not None else build(tree, model)
    out = {}
    for leg in legs:
        res = experiment_leg(em, leg)
        out[f"actuator{leg}"] = res.fit
        if details is not None:
            details[f"actuator{leg}"] = res
    return out
