"""The Fig. 12 experiment stepped on the reduced chain, the pneumatics and seals as they are.

The identification (:mod:`simpro_mj.identification.identify`) runs the whole
closed chain in MuJoCo for 63,000 steps per cabin (three legs x 21 s). The
experiment's *mechanics* barely leave the operating point (a few mm on each
slide): here they are the chain reduced to the slides there
(:mod:`simpro_mj.plant.pneumatics.statics`; mass :math:`M_q`, joint damping
:math:`D_q`, gravity stiffness :math:`K_q = ∂F_h/∂q`, 3 x 3 each, as
:mod:`simpro_mj.identification.linear_experiment` builds them), while
everything that makes the experiment nonlinear is the step's own:

* **Loops, dither, sequence**: the experiment's law
  (:func:`controllers.experiment_law.experiment_volts`, with its saturation at
  0-10 V) on the same excitation array (clock, seed, amplitude, settling).
* **Valves, chambers, supply, the seals' Stribeck and viscous part**: the 1 ms
  step's own :func:`simpro_mj.plant.step_functions.nonlinear_step` (the spool,
  the metering edges, the chambers polytropic or with the energy equation, the
  supply as built, :func:`simpro_mj.plant.friction.seal_friction`), compiled
  from the same source the run compiles (:func:`simpro_mj.sim.step.compiled`).
* **The seals' dry friction**: MuJoCo's ``frictionloss`` constraint solved as
  MuJoCo solves it, on the reduced chain. Per step, with the smooth force
  :math:`f_s = F - F_h - K_q (q - q_0) - D_q v` and its acceleration
  :math:`a_s = M_q^{-1} f_s`, the friction force :math:`f` is the box-constrained
  minimum of MuJoCo's dual

  .. math::
      \\min_{|f_i| \\le F_{S,i}}\\; \\tfrac12 f^T (M_q^{-1} + R) f + f^T (a_s - a_{ref}),
      \\qquad a_{ref} = -b\\,v,

  with MuJoCo's soft-constraint numbers for a friction row (at zero violation):
  impedance :math:`d` = ``solimp[0]``, :math:`b = 2 / (d_{max} τ)`, τ = ``solref[0]``
  raised to two time steps (MuJoCo's ``refsafe``), :math:`R_i = (1 - d)/d`
  ``dof_invweight0``:sub:`i` (its diagonal approximation). Solved by projected
  Gauss-Seidel, warm-started from the last step (three variables; to
  :data:`PGS_TOL` of the breakaway force). Then ``implicitfast``'s Euler step
  :math:`(M_q + h D_q)\\,a = f_s + f`, :math:`v^+ = v + h a`,
  :math:`q^+ = q + h v^+`. With the defaults (τ = 2 ms = 2 h, d = 0.9999) a
  sticking slide's speed goes to :math:`(1 - 1/d_{max})\\,v` in one step, the
  hard constraint's 0 within 1e-4 of it. MuJoCo solves the friction rows together
  with the loop closures (soft equality rows) on the open tree's mass; here the
  closures are rigid and the chain reduced: the same constraint as long as the
  closures' own softness (their time constant) is far below the seals'.

What it leaves out: the chain's configuration dependence (:math:`M_q` and
:math:`K_q` stay at the operating point; the slides move a few mm of 500),
the velocity-product (Coriolis) forces, the closures' softness. Each leg's
record (voltage and speed, from the end of the settling) is fitted to the
experiment's own minimum (:func:`~simpro_mj.identification.identify.fit_eq19`'s
residual, reached by :mod:`simpro_mj.identification.sensitivity_fit`).
"""

from __future__ import annotations

import math
import threading
import types as pytypes
from dataclasses import dataclass, field

import numpy as np

from controllers import experiment_law as xl
from controllers.dither import dither_signal
from simpro_mj.identification.identify import Fit, _prbs, fit_eq19
from simpro_mj.identification.linear_experiment import ExperimentModel, build
from simpro_mj.identification.sensitivity_fit import fit_sensitivity
from simpro_mj.identification.settings import leg_values
from simpro_mj.plant import step_functions as sf

__all__ = [
    "PGS_SWEEPS",
    "PGS_TOL",
    "ReducedModel",
    "ReducedRecord",
    "excitation",
    "identify_reduced",
    "reduced_model",
    "run_reduced",
]

#: Most projected Gauss-Seidel sweeps of the friction solve per step.
PGS_SWEEPS = 50
#: The friction solve stops when no force moves by more than this share of its bound.
PGS_TOL = 1e-9


@dataclass
class ReducedModel:
    """The experiment's operating point and its reduced chain with MuJoCo's friction rows."""

    em: ExperimentModel  # the mechanics, the actuators, the loops' constants
    q0: np.ndarray  # m, the operating point
    f_hold: np.ndarray  # N, the holding forces there
    dry: np.ndarray  # N, each slide's frictionloss (the breakaway force; 0: regularised)
    b_ref: np.ndarray  # 1/s, MuJoCo's reference damping of each friction row
    r_reg: np.ndarray  # s^2/kg, its regulariser (dof_invweight0 (1 - d)/d)
    integrator: str


@dataclass
class ReducedRecord:
    """One run of the reduced experiment: per step (rows) and leg (columns) the applied
    volts ``u``, the slides ``q`` (m) and their speeds ``qdot`` (m/s), at the step's
    start, from the end of the settling; ``n_settle`` steps were cut."""

    u: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    dt: float
    n_settle: int
    fits: dict = field(default_factory=dict)


def reduced_model(tree: dict, model=None) -> ReducedModel:
    """The reduced experiment of ``tree`` (an identification tree), built at its
    operating point (module docstring)."""
    import mujoco

    from simpro_mj.identification.settings import check_tree
    from simpro_mj.plant.model import PlantIndex, load_model

    ex = check_tree(tree)
    m = model if model is not None else load_model(ex.model)
    em = build(tree, m)  # sets the seals' frictionloss, solref and solimp on m
    idx = PlantIndex.of(m)
    dofs = np.asarray(idx.slide_dof)
    dt = em.dt
    tau = np.maximum(np.asarray(m.dof_solref[dofs, 0], float), 2.0 * dt)  # refsafe
    dmin = np.asarray(m.dof_solimp[dofs, 0], float)
    dmax = np.asarray(m.dof_solimp[dofs, 1], float)
    b_ref = 2.0 / (dmax * tau)
    r_reg = np.maximum(np.asarray(m.dof_invweight0[dofs], float) * (1.0 - dmin) / dmin, 1e-15)
    names = {int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST): "implicitfast",
             int(mujoco.mjtIntegrator.mjINT_EULER): "Euler",
             int(mujoco.mjtIntegrator.mjINT_IMPLICIT): "implicit"}  # fmt: skip
    integ = names.get(int(m.opt.integrator), "RK4")
    if integ == "RK4":
        raise ValueError("the reduced experiment steps as MuJoCo's Euler-type integrators do")
    q0 = np.full(3, float(em.ip.position_mm) * 1e-3)
    # the holding forces: the actuators' reset force (reset at them, build)
    from simpro_mj.plant.model import assemble
    from simpro_mj.plant.pneumatics.statics import holding_forces

    d = mujoco.MjData(m)
    assemble(m, d, q0, index=idx)
    f_hold = holding_forces(m, d, idx)
    dry = np.array([f[0] for f in em.friction], float)
    return ReducedModel(em, q0, f_hold, dry, b_ref, r_reg, integ)


def excitation(rm: ReducedModel, legs: tuple) -> tuple[np.ndarray, int]:
    """The experiment's law's input by step, ``(n + 1, 3)`` (the dither, the sequence on
    ``legs``' columns as :func:`simpro_mj.identification.identify.run_experiment` and its
    all-legs form build it), and the settling's steps."""
    ip, dt = rm.em.ip, rm.em.dt
    n_settle = int(round(float(ip.settle_s) / dt))
    n_exc = int(round(float(ip.duration_s) / dt))
    clock = max(1, int(round(float(ip.prbs_clock_ms) * 1e-3 / dt)))
    bits, seed = int(ip.prbs_bits), int(ip.seed)
    amp = leg_values(ip.prbs_amplitude_v, "prbs_amplitude_v")
    n_all = n_settle + n_exc
    dither = dither_signal(n_all, dt, float(ip.dither_v), float(ip.dither_period_ms) * 1e-3)
    exc = np.zeros((n_all + 1, 3))
    if len(legs) == 1:
        (leg,) = legs
        exc[:n_all, 0] = dither[:, 0]
        exc[n_settle:n_all, 1] = amp[leg - 1] * _prbs(n_exc, clock, bits, seed)
    else:
        period = 2**bits - 1
        for j in range(3):
            exc[:n_all, j] = dither[:, 0]
            shift = seed + j * (period // 3)
            exc[n_settle:n_all, j] += amp[j] * _prbs(n_exc, clock, bits, shift)
    return exc, n_settle


def reduced_steps(n, dt, xc, exc, ast, ac, q0, fhold, stiff, damp, minv, lhs_inv, dry, b_ref,
                  r_reg, q, v, fc, u_log, q_log, v_log, sweeps, tol):  # fmt: skip
    """Step the reduced experiment ``n`` times from ``q``, ``v`` (changed in place),
    logging each step's start; the steps done (fewer on a non-finite state). The
    friction solve runs at most ``sweeps`` sweeps, to ``tol`` of each breakaway force."""
    u = np.zeros(3)
    f = np.zeros(3)
    fs = np.zeros(3)
    g = np.zeros(3)
    for k in range(n):
        for i in range(3):
            q_log[k, i] = q[i]
            v_log[k, i] = v[i]
        xl.experiment_volts(k, q, xc, exc, u)
        for i in range(3):
            u_log[k, i] = u[i]
        sf.nonlinear_step(u, q, v, ast, ac, f)
        for i in range(3):
            s = f[i] - fhold[i]
            for j in range(3):
                s -= stiff[i, j] * (q[j] - q0[j]) + damp[i, j] * v[j]
            fs[i] = s
        for i in range(3):  # the friction rows' free acceleration less their reference
            a = 0.0
            for j in range(3):
                a += minv[i, j] * fs[j]
            g[i] = a + b_ref[i] * v[i]
        for _ in range(sweeps):  # MuJoCo's dual: a box QP, projected Gauss-Seidel
            moved = 0.0
            for i in range(3):
                if dry[i] <= 0.0:
                    fc[i] = 0.0
                    continue
                r = g[i] + r_reg[i] * fc[i]
                for j in range(3):
                    r += minv[i, j] * fc[j]
                new = fc[i] - r / (minv[i, i] + r_reg[i])
                new = sf.clip(new, -dry[i], dry[i])
                dm = abs(new - fc[i]) / dry[i]
                if dm > moved:
                    moved = dm
                fc[i] = new
            if moved < tol:
                break
        ok = True
        for i in range(3):
            a = 0.0
            for j in range(3):
                a += lhs_inv[i, j] * (fs[j] + fc[j])
            v[i] = v[i] + dt * a
            if not math.isfinite(v[i]):
                ok = False
        for i in range(3):
            q[i] = q[i] + dt * v[i]
        if not ok:
            return k + 1
    return n


_compiled = None
_lock = threading.Lock()


def _stepper():
    """:func:`reduced_steps` compiled with the step's own compiled functions bound
    (:func:`simpro_mj.sim.step.compiled`), or interpreted when the run's kernel is."""
    global _compiled
    from simpro_mj.plant.kernels import kernel_choice

    if kernel_choice() != "numba":
        return reduced_steps
    with _lock:
        if _compiled is None:
            from simpro_mj.core.cache import source_digest
            from simpro_mj.sim.numba_cache import jit
            from simpro_mj.sim.step import compiled

            comp = compiled()
            glob = dict(reduced_steps.__globals__)
            glob["xl"] = _view(xl, experiment_volts=comp.experiment_volts)
            glob["sf"] = _view(sf, nonlinear_step=comp.nonlinear_step, clip=comp.clip)
            clone = pytypes.FunctionType(
                reduced_steps.__code__, glob, reduced_steps.__name__, reduced_steps.__defaults__
            )
            clone.__qualname__, clone.__module__ = reduced_steps.__qualname__, __name__
            # beside the step's own cache, whose folder is named by the step's sources
            # (the callees' code is linked into this function's cache entry)
            folder = comp.cache_folder + "-reduced-" + source_digest([__file__])[:16]
            _compiled = jit(folder)(clone)
        return _compiled


def _view(module, **compiled):
    """``module`` as the compiled stepper sees it: ``compiled`` functions swapped in."""
    view = pytypes.ModuleType(module.__name__)
    view.__dict__.update(module.__dict__)
    view.__dict__.update(compiled)
    return view


def run_reduced(
    rm: ReducedModel, legs: tuple, sweeps: int = PGS_SWEEPS, tol: float = PGS_TOL
) -> ReducedRecord:
    """The experiment exciting ``legs`` (one leg, or all three) on the reduced chain;
    its record from the end of the settling (module docstring); ``sweeps`` and ``tol``
    the friction solve's (:data:`PGS_SWEEPS`, :data:`PGS_TOL`)."""
    em = rm.em
    exc, n_settle = excitation(rm, legs)
    n = exc.shape[0] - 1
    law_leg = legs[0] - 1 if len(legs) == 1 else 3
    xc = xl.XC.pack(on=1.0, leg=law_leg, qref=float(rm.q0[0]), kp=em.kp, hold=em.u_hold,
                    lo=0.0, hi=10.0)  # fmt: skip
    ast = em.base.copy()
    ac = np.asarray(em.act.step_constants, float)
    dt = em.dt
    minv = np.linalg.inv(em.mass)
    lhs_inv = np.linalg.inv(em.mass + dt * em.damping)
    q, v, fc = rm.q0.copy(), np.zeros(3), np.zeros(3)
    u_log, q_log, v_log = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    done = _stepper()(
        n, dt, xc, exc, ast, ac, rm.q0, rm.f_hold, em.stiffness, em.damping, minv, lhs_inv,
        rm.dry, rm.b_ref, rm.r_reg, q, v, fc, u_log, q_log, v_log, int(sweeps), float(tol),
    )  # fmt: skip
    if done != n:
        from simpro_mj.core.errors import PhysicsError

        raise PhysicsError(f"the reduced experiment diverged at t = {done * dt:.3f} s")
    rows = slice(n_settle, n)
    return ReducedRecord(u_log[rows], q_log[rows], v_log[rows], dt, n_settle)


def identify_reduced(tree: dict, legs=(1, 2, 3), model=None, records: dict | None = None,
                     rm: ReducedModel | None = None) -> dict[str, Fit]:  # fmt: skip
    """Eq. (19) per leg fitted to the reduced experiment's records; ``{"actuator<i>": Fit}``
    as :func:`simpro_mj.identification.identify.identify` returns (its excitation:
    one leg at a time, or ``all_legs``; the default trust region's minimum reached by
    :func:`~simpro_mj.identification.sensitivity_fit.fit_sensitivity` at about a
    quarter of its CPU). ``records``, when given, receives each leg's
    :class:`ReducedRecord` (the whole run's, with the leg's fit)."""
    rm = rm if rm is not None else reduced_model(tree, model)
    ip = rm.em.ip
    together = ip.excitation == "all_legs" and len(legs) > 1
    runs = {}
    if together:
        rec = run_reduced(rm, tuple(legs))
        runs = {leg: rec for leg in legs}
    out = {}
    skip = int(round(float(ip.fit_skip_s) / rm.em.dt))
    for leg in legs:
        rec = runs[leg] if together else run_reduced(rm, (leg,))
        j = leg - 1
        if ip.fit_method == "trust_region":  # its minimum, by the exact Jacobian
            fit = fit_sensitivity(rec.u[:, j], rec.qdot[:, j], rec.dt, skip=skip)
        else:
            fit = fit_eq19(rec.u[:, j], rec.qdot[:, j], rec.dt, skip=skip, method=ip.fit_method)
        name = f"actuator{leg}"
        out[name] = Fit(fit.b, fit.a1, fit.a0, fit.offset_v, fit.fit_percent,
                        float(rm.f_hold[j]), float(rm.em.u_hold[j]))  # fmt: skip
        rec.fits[name] = out[name]
        if records is not None:
            records[name] = rec
    return out
