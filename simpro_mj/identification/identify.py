"""``simpro-sim identify``: the paper's actuator identification (Fig. 12) in simulation.

Per actuator i, around mid-stroke under the nominal payload:

1. the closed chain is assembled at q = 250 mm on every leg; the holding
   forces come from the static inverse dynamics
   (:func:`simpro_mj.plant.pneumatics.statics.holding_forces`), the actuators are reset at
   the matching pneumatic equilibrium (valve voltages ``u_h``);
2. every leg runs a proportional position loop
   :math:`u_j = u_{h,j} + K_{p,j}(q_{ref} - q_j)` on its true position
   (:mod:`controllers.experiment_law`); after a settling time a pseudo-random
   binary sequence (maximum-length, ``prbs_clock_ms`` per bit,
   ±``prbs_amplitude_v``) is added to the valve voltage of leg i only
   (``identify.excitation: one_leg``, the paper's; ``all_legs``: to every leg at
   once, leg j's sequence shifted by j/3 of its period, so that the three are
   uncorrelated and one record serves the three fits);
3. the co-simulation runs at 1 ms on the run's own step
   (:mod:`simpro_mj.sim.step`: sensors, that law in place of the joint
   controllers, the actuators, the log;
   :func:`simpro_mj.sim.experiment.step_experiment`), compiled
   inside ``mj_step`` under ``SIMPRO_KERNEL`` as a run, or interpreted;
   MuJoCo warnings and loop closure are checked;
4. eq. (19), :math:`Y/U = b / (s (s^2 + a_1 s + a_0))`, is fitted to the
   recorded valve voltage (deviation from 5 V) and slide motion. Because (19)
   has a pure integrator, it is fitted on the slide velocity
   :math:`sY = b/(s^2 + a_1 s + a_0)\\,(U - d)` by continuous-time output
   error (ZOH-discretised at 1 ms, ``scipy.optimize.least_squares``' trust
   region; ``identify.fit_method: levenberg_marquardt``,
   :func:`levenberg_marquardt`, is an option), with d an input offset (the holding
   voltage's deviation from 5 V), started from a discrete ARX(2, 2) least-squares
   estimate converted to continuous time.

Reported per actuator: b, a1, a0, :math:`ω_n = \\sqrt{a_0}`,
:math:`ζ = a_1 / (2 ω_n)`, velocity gain b/a0 (m/s/V), next to the paper's
eqs. (34) and (35) in SI under the ``paper_units`` reading of the tree
(``"volts"``: Y is the potentiometer signal, b / 20; ``"metres"``: as printed,
:mod:`controllers.design`). The plant is the ``preset`` of the tree
(:mod:`simpro_mj.config.presets`, default ``paper``) with ``--set`` overrides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from controllers.design import (
    ACTUATORS,
    paper_coefficients,
    paper_plant,
    paper_units_info,
)
from controllers.dither import dither_signal
from controllers.experiment_law import XC
from simpro_mj.core.errors import PhysicsError, UserInputError
from simpro_mj.identification.settings import (
    DEFAULT_IDENTIFY_PARAMS,  # noqa: F401 (the tests shorten the experiment through it)
    FIT_METHODS,
    Experiment,
    check_tree,
    default_tree,
    leg_values,
)
from simpro_mj.plant.model import (
    PlantIndex,
    assemble,
    load_model,
)
from simpro_mj.plant.payload import holding_force_model, max_payload
from simpro_mj.plant.platform import set_seal_friction
from simpro_mj.plant.pneumatics.factory import make_actuators
from simpro_mj.plant.pneumatics.params import ACTUATOR_KINDS
from simpro_mj.plant.pneumatics.statics import holding_forces


@dataclass(frozen=True)
class Fit:
    """Eq. (19), :math:`b / (s (s^2 + a_1 s + a_0))`, of one leg in SI.

    ``b`` (m/s^3/V), ``a1`` (1/s), ``a0`` (1/s^2); from them ``wn_rad_s``
    :math:`= \\sqrt{a_0}`, ``zeta`` :math:`= a_1 / (2 ω_n)` and the velocity gain
    ``velocity_gain_m_s_per_v`` :math:`= b / a_0`. A fit (:func:`fit_eq19`) adds its
    input offset ``offset_v`` (V) and ``fit_percent`` (100 (1 - |v - v̂| / |v - mean
    v|), the NRMSE fit), :func:`identify` the leg's ``holding_force_n`` and
    ``holding_voltage_v`` at the operating point; the paper's models have none.
    """

    b: float
    a1: float
    a0: float
    offset_v: float | None = None
    fit_percent: float | None = None
    holding_force_n: float | None = None
    holding_voltage_v: float | None = None

    @property
    def wn_rad_s(self) -> float:
        return math.sqrt(self.a0)

    @property
    def zeta(self) -> float:
        return self.a1 / (2.0 * self.wn_rad_s)

    @property
    def velocity_gain_m_s_per_v(self) -> float:
        return self.b / self.a0

    def model(self) -> dict:
        """``{b, a1, a0}``: the model as a scenario's ``controller.inner.identified``
        holds it."""
        return {"b": self.b, "a1": self.a1, "a0": self.a0}

    def as_dict(self) -> dict:
        """The JSON form (``identify.json``): the model, its three derived numbers,
        then the fit's numbers it has."""
        wn, zeta, gain = self.wn_rad_s, self.zeta, self.velocity_gain_m_s_per_v
        derived = {"wn_rad_s": wn, "zeta": zeta, "velocity_gain_m_s_per_v": gain}
        return self.model() | derived | {k: v for k, v in vars(self).items() if v is not None}


def paper_models(reading: str = "volts") -> dict[str, Fit]:
    """Eqs. (34)-(35) in SI under ``reading``, per actuator."""
    return {a: Fit(**vars(paper_plant(a, reading))) for a in ACTUATORS}


def _prbs(n_steps: int, clock: int, bits: int, seed: int) -> np.ndarray:
    """±1 maximum-length sequence, rolled by ``seed`` bits, each bit held ``clock`` steps."""
    # scipy.signal is imported where used: its import costs 0.6-1.2 s of CPU, and
    # every run imports this module for its models (a batch's workers have it from
    # their forkserver: simpro_mj/batch/warm.py)
    from scipy.signal import max_len_seq

    seq = max_len_seq(bits)[0].astype(float) * 2.0 - 1.0
    seq = np.roll(seq, int(seed))
    n_bits = -(-n_steps // clock)
    reps = -(-n_bits // seq.size)
    return np.repeat(np.tile(seq, reps)[:n_bits], clock)[:n_steps]


@dataclass
class Record:
    """One leg's record of the experiment, from the start of the excitation.

    ``t`` (s), ``u`` (V, the leg's applied valve voltage, saturated), ``q`` (m) and
    ``qdot`` (m/s) of the leg; ``u_hold`` (V) and ``force_hold`` (N) of all legs at
    the operating point, ``q_all`` (m, all legs), the sample time ``dt`` (s); ``fit``
    the leg's fit of eq. (19) once :func:`identify` made it.
    """

    t: np.ndarray
    u: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    u_hold: np.ndarray
    force_hold: np.ndarray
    q_all: np.ndarray
    dt: float
    fit: Fit | None = None


def run_experiment(tree: dict | Experiment, leg: int, model=None) -> Record:
    """Run the Fig. 12 experiment on ``leg`` (1..3); return its :class:`Record`.

    Raises
    ------
    PhysicsError
        On a MuJoCo warning, a non-finite state or an opened loop.
    """
    return _experiment(tree, (leg,), model)[leg]


def run_experiment_all_legs(tree: dict | Experiment, model=None) -> dict:
    """The experiment with the three legs excited at once (``excitation: all_legs``);
    ``{leg: Record}``, from one run."""
    return _experiment(tree, (1, 2, 3), model)


def _experiment(tree: dict | Experiment, legs: tuple, model=None) -> dict:
    """One run of the experiment exciting ``legs`` (one leg, or all three); per leg its
    record (:func:`run_experiment`)."""
    ex = check_tree(tree)
    ip = ex.settings
    kind = ip.actuator_kind
    if kind not in ACTUATOR_KINDS:
        raise UserInputError(
            f"invalid value at identify.actuator_kind: '{kind}'; allowed {list(ACTUATOR_KINDS)}"
        )
    m = model if model is not None else load_model(ex.model)
    d = mujoco.MjData(m)
    idx = PlantIndex.of(m)
    dt = float(m.opt.timestep)
    q_ref = float(ip.position_mm) * 1e-3
    if not 0.05 <= q_ref <= 0.45:
        raise UserInputError(
            f"invalid value at identify.position_mm: {ip.position_mm}; allowed 50..450 mm"
        )
    q0 = np.full(3, q_ref)
    assemble(m, d, q0, index=idx)
    f_hold = holding_forces(m, d, idx)

    act = make_actuators(
        kind, ex.pneumatics, model=m, linear_plants=paper_coefficients(ex.paper_units)
    )
    set_seal_friction(m, idx, act)  # the seals that stick (simpro_mj.plant.friction)
    force_range = act.params.force_range
    if np.any(f_hold > force_range[1]) or np.any(f_hold < force_range[0]):
        f0, slope = holding_force_model(m, d, idx, 100.0)  # affine in the mass: any probe
        cap = np.where(f_hold >= 0, force_range[1], force_range[0])
        worst = int(np.argmax(f_hold / cap))
        raise UserInputError(
            f"payload too heavy at model.payload.mass_kg: {ex.model['payload']['mass_kg']:g} "
            f"kg needs {abs(f_hold[worst]) / 1e3:.2f} kN on cylinder {worst + 1} at q = "
            f"{ip.position_mm:g} mm, which makes at most "
            f"{abs(force_range[1] if f_hold[worst] >= 0 else force_range[0]) / 1e3:.2f} kN; "
            f"allowed: <= {max(0.0, max_payload(f0, slope, force_range)):.0f} kg at this supply "
            "pressure (pneumatics.supply_pressure_bar_gauge)"
        )
    act.reset(q0, np.zeros(3), force=f_hold)
    u_hold = act.u_hold.copy()
    kp = leg_values(ip.kp_v_per_m, "kp_v_per_m")
    amp = leg_values(ip.prbs_amplitude_v, "prbs_amplitude_v")
    n_settle = int(round(float(ip.settle_s) / dt))
    n_exc = int(round(float(ip.duration_s) / dt))
    if n_exc < 500:
        raise UserInputError("invalid value at identify.duration_s: allowed >= 0.5 s")
    clock = max(1, int(round(float(ip.prbs_clock_ms) * 1e-3 / dt)))
    bits, seed = int(ip.prbs_bits), int(ip.seed)
    # the joint loops' dither on every valve, from the settling on (controllers.dither)
    dither = dither_signal(
        n_settle + n_exc, dt, float(ip.dither_v), float(ip.dither_period_ms) * 1e-3
    )
    loop_bound = float(ip.loop_bound_mm) * 1e-3

    # the excitation by step (controllers.experiment_law): the dither, the sequence
    n_all = n_settle + n_exc
    exc = np.zeros((n_all + 1, 3))
    if len(legs) == 1:
        (leg,) = legs
        exc[:n_all, 0] = dither[:, 0]  # one wave on the three valves (controllers.dither)
        exc[n_settle:n_all, 1] = amp[leg - 1] * _prbs(n_exc, clock, bits, seed)
        law_leg = leg - 1
    else:  # every leg, column j leg j's: the dither and its own shift of the sequence
        period = 2**bits - 1
        for j in range(3):
            exc[:n_all, j] = dither[:, 0]
            shift = seed + j * (period // 3)
            exc[n_settle:n_all, j] += amp[j] * _prbs(n_exc, clock, bits, shift)
        law_leg = 3
    xp = XC.pack(on=1.0, leg=law_leg, qref=q_ref, kp=kp, hold=u_hold, lo=0.0, hi=10.0)
    from simpro_mj.sim.experiment import step_experiment  # the run's own step

    rec = step_experiment(m, d, idx, act, xp, exc, loop_bound)
    rows = slice(n_settle, n_all)
    q_all = rec["q"][rows].copy()
    if np.any(q_all < 0.0) or np.any(q_all > 0.5):
        which = f" {legs[0]}" if len(legs) == 1 else "s 1-3"
        raise PhysicsError(
            f"identification of actuator{which} hit an end stop: lower "
            "identify.prbs_amplitude_v or raise identify.kp_v_per_m"
        )
    t = np.arange(n_exc) * dt
    u, qdot = rec["u"][rows], rec["qdot"][rows]
    cols = {leg: leg - 1 for leg in legs}
    return {
        leg: Record(t, u[:, j].copy(), q_all[:, j].copy(), qdot[:, j].copy(), u_hold, f_hold,
                    q_all, dt)
        for leg, j in cols.items()
    }  # fmt: skip


def _expm3(m: np.ndarray) -> np.ndarray:
    """``exp(m)`` of a small matrix: Taylor series to the 14th power after scaling
    ``m`` to an infinity norm <= 1/2 (remainder below ``0.5^15 / 15! ~ 2e-17``
    relative), squared back. scipy.linalg.expm's Pade is as exact and costs ~50
    times more on a 3 x 3 matrix (its checks and dispatch)."""
    norm = float(np.abs(m).sum(axis=1).max())
    s = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    a = m / 2.0**s
    e = np.eye(m.shape[0]) + a
    term = a
    for k in range(2, 15):
        term = term @ a / k
        e = e + term
    for _ in range(s):
        e = e @ e
    return e


def zoh_velocity_filter(b: float, a1: float, a0: float, dt: float):
    """``(num, den)`` of v = b/(s^2 + a1 s + a0) u discretised with the input held (ZOH).

    The controllable form ``A = [[-a1, -a0], [1, 0]]``, ``B = [1, 0]^T``,
    ``C = [0, b]`` (as ``scipy.signal.tf2ss``); ``exp([[A, B], [0, 0]] dt)`` gives
    ``A_d`` and ``B_d`` (as ``scipy.signal.cont2discrete``), and for 2 states the
    transfer function in closed form: ``den = z^2 - tr(A_d) z + det(A_d)``,
    ``num = C adj(zI - A_d) B_d = b (B_d1 z + A_d21 B_d0 - A_d11 B_d1)``. The
    filter of ``cont2discrete`` (which forms ``num`` as a difference of two
    polynomials: it is the less exact of the two, by up to 1e-7 relative on a
    stiff pair), at a fraction of its cost: the fit evaluates it hundreds of times.
    """
    m = np.zeros((3, 3))
    m[0, 0], m[0, 1], m[0, 2], m[1, 0] = -a1, -a0, 1.0, 1.0
    e = _expm3(m * dt)
    ad, bd = e[:2, :2], e[:2, 2]
    den = np.array([1.0, -(ad[0, 0] + ad[1, 1]), ad[0, 0] * ad[1, 1] - ad[0, 1] * ad[1, 0]])
    num = b * np.array([0.0, bd[1], ad[1, 0] * bd[0] - ad[0, 0] * bd[1]])
    return num, den


def simulate_velocity(theta, u, dt):
    """ZOH simulation of v = b/(s^2 + a1 s + a0) (u - d); theta = (b, a1, a0, d)."""
    from scipy.signal import lfilter

    b, a1, a0, d = theta
    num, den = zoh_velocity_filter(b, a1, a0, dt)
    return lfilter(num, den, u - d)


def _arx_guess(u, v, dt):
    """ARX(2,2) with a constant, converted to (b, a1, a0, d) in continuous time."""
    phi = np.column_stack([-v[1:-1], -v[:-2], u[1:-1], u[:-2], np.ones(v.size - 2)])
    th = np.linalg.lstsq(phi, v[2:], rcond=None)[0]
    al1, al2, be1, be2, c = th
    zp = np.roots([1.0, al1, al2])
    with np.errstate(all="ignore"):
        sp = np.log(zp.astype(complex)) / dt
    a1 = float(-np.real(sp.sum()))
    a0 = float(np.real(np.prod(sp)))
    dc = (be1 + be2) / (1.0 + al1 + al2)
    b = dc * a0
    d = -c / (be1 + be2) if abs(be1 + be2) > 1e-12 else 0.0
    return b, a1, a0, d


def fit_eq19(u, qdot, dt: float, skip: int = 0, guess=None, method: str = "trust_region") -> Fit:
    """Fit eq. (19) to a record (continuous output error on the velocity).

    Parameters
    ----------
    u : array
        Valve voltage, V (absolute: 5 V is the centre).
    qdot : array
        Slide velocity, m/s (the derivative of eq. 19's output Y).
    dt : float
        Sample time, s.
    skip : int
        Samples excluded at the start from the residual.
    guess : (b, a1, a0), optional
        Starting point; default the ARX estimate (the paper's values if the
        ARX poles are unusable).
    method : str
        The solver (:data:`simpro_mj.identification.settings.FIT_METHODS`):
        ``trust_region`` (``scipy.optimize.least_squares``, bounded trust region
        reflective) or ``levenberg_marquardt`` (:func:`levenberg_marquardt`).

    Returns
    -------
    Fit
        b, a1, a0, the input offset d (``offset_v``) and ``fit_percent``.
    """
    u = np.asarray(u, float) - 5.0
    v = np.asarray(qdot, float)
    if guess is None:
        b0, a10, a00, d0 = _arx_guess(u, v, dt)
        if not (b0 > 0 and a10 > 0 and a00 > 0 and np.isfinite(b0 + a10 + a00)):
            b0, a10, a00, d0 = 100.0, 10.0, 300.0, float(np.mean(u))
    else:
        b0, a10, a00 = guess
        d0 = float(np.mean(u))
    sl = slice(skip, None)
    scale = np.array([b0, max(a10, 1.0), a00, 1.0])

    def res(x):
        return (simulate_velocity(x * scale, u, dt) - v)[sl]

    x0 = np.array([1.0, a10 / scale[1], 1.0, d0])
    lo = np.array([1e-6, 0.0, 1e-6, -5.0])
    hi = np.array([np.inf, np.inf, np.inf, 5.0])
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    from threadpoolctl import threadpool_limits

    # one BLAS thread: the problem is small (4 parameters; a 3 x 3 matrix exponential per
    # evaluation) and BLAS threads spinning on a busy machine cost ten times its CPU time
    with threadpool_limits(limits=1, user_api="blas"):
        if method == "levenberg_marquardt":
            x, err = levenberg_marquardt(res, x0, lo, hi)
        elif method == "trust_region":
            from scipy.optimize import least_squares

            sol = least_squares(res, x0, bounds=(lo, hi), x_scale="jac", max_nfev=400)
            x, err = sol.x, sol.fun
        else:
            raise ValueError(f"invalid fit method {method!r}; allowed: {', '.join(FIT_METHODS)}")
    b, a1, a0, d = x * scale
    vv = v[sl] - v[sl].mean()
    fit = 100.0 * (1.0 - np.linalg.norm(err) / max(np.linalg.norm(vv), 1e-300))
    return Fit(float(b), float(a1), float(a0), float(d), float(fit))


#: The Levenberg-Marquardt damping's start (:func:`levenberg_marquardt`): 0.1, a first
#: step a tenth of the way from Gauss-Newton's towards gradient descent. With 1e-3 the
#: first steps (near Gauss-Newton's) jump out of the basin least_squares' trust region
#: stays in on a leg its seals dominate (a sweep cabin's leg 1: cost 3 % higher).
LAM0 = 0.1


def levenberg_marquardt(fun, x0, lo, hi, ftol: float = 1e-8, max_nfev: int = 400):
    """Minimise ``|fun(x)|^2 / 2`` over the box ``lo <= x <= hi``; ``(x, fun(x))``.

    Levenberg-Marquardt with Marquardt's scaling: from the Jacobian ``J`` by forward
    differences (step ``sqrt(eps) max(1, |x_j|)``, backwards at an upper bound) and the
    residual ``r``, the step ``(J^T J + λ diag(J^T J)) δ = -J^T r``, clipped to the
    box; a step that lowers the cost is taken and λ divided by 3, else λ is
    multiplied by 4 and the step solved again. It stops when a step lowers the cost
    by less than ``ftol`` of it, or after ``max_nfev`` evaluations of ``fun``.

    For eq. (19)'s four parameters the normal equations are 4 x 4: an iteration
    costs its five evaluations (a 20 s record filtered five times), where
    ``scipy.optimize.least_squares``' trust region (the default solver) adds an SVD
    of the whole Jacobian and its scaling per iteration: on the 450/750 N cabin's
    nine records (seeds 1-3) the nine fits took 0.54-0.63 s of CPU against
    0.90-1.10 s (three repeats in one process, a loaded machine). Both reach the same
    minimum within the flatness of its valley: b, a1 and a0 within 0.3 % there, and
    within 0.5 % on the 24 legs of ``sweep_robustness.yaml``'s first eight cabins.
    It is not the default: the 450/750 N cabin's ``step_all`` on loops placed on
    its models leaves the default's seed spread (pitch settling 1.91-2.90 s
    against 1.12-1.93 s, roll overshoot up to 3.4 % against 2.3 %), as any change
    of a micrometre does under stick-slip (``benchmarks/excitation_spread.py
    --options levenberg_marquardt``).
    """
    eps = np.finfo(float).eps
    x = np.clip(np.asarray(x0, dtype=float), lo, hi)
    r = fun(x)
    cost, lam, nfev = 0.5 * float(r @ r), LAM0, 1
    while nfev < max_nfev:
        h = eps**0.5 * np.maximum(1.0, np.abs(x))
        jac = np.empty((r.size, x.size))
        for j in range(x.size):
            xj = x.copy()
            back = xj[j] + h[j] > hi[j]
            xj[j] += -h[j] if back else h[j]
            jac[:, j] = (r - fun(xj)) / h[j] if back else (fun(xj) - r) / h[j]
        nfev += x.size
        a, g = jac.T @ jac, jac.T @ r
        damp = np.diag(np.maximum(np.diag(a), eps))
        while nfev < max_nfev:
            try:
                step = np.linalg.solve(a + lam * damp, -g)
            except np.linalg.LinAlgError:
                step = np.zeros_like(x)
            xn = np.clip(x + step, lo, hi)
            rn = fun(xn)
            nfev += 1
            cn = 0.5 * float(rn @ rn)
            if cn < cost:
                lam = max(lam / 3.0, 1e-12)
                break
            lam *= 4.0
            if lam > 1e12:  # no step lowers the cost: a minimum
                return x, r
        else:
            return x, r
        done = cost - cn <= ftol * cn
        x, r, cost = xn, rn, cn
        if done:
            break
    return x, r


def identify(
    tree: dict | Experiment | None = None, legs=(1, 2, 3), records: dict | None = None
) -> dict[str, Fit]:
    """Identify eq. (19) for each leg in ``legs``; ``{"actuator<i>": Fit}``.

    ``records``, when given, receives each leg's experiment record and fit.
    """
    ex = check_tree(default_tree() if tree is None else tree)
    ip = ex.settings
    model = load_model(ex.model)
    out = {}
    together = ip.excitation == "all_legs" and len(legs) > 1
    recs = _experiment(ex, tuple(legs), model) if together else {}
    for leg in legs:
        rec = recs[leg] if together else run_experiment(ex, leg, model=model)
        skip = int(round(float(ip.fit_skip_s) / rec.dt))
        res = replace(
            fit_eq19(rec.u, rec.qdot, rec.dt, skip=skip, method=ip.fit_method),
            holding_force_n=float(rec.force_hold[leg - 1]),
            holding_voltage_v=float(rec.u_hold[leg - 1]),
        )
        out[f"actuator{leg}"] = res
        if records is not None:
            records[f"actuator{leg}"] = replace(rec, fit=res)
    return out


def document(results: dict[str, Fit], ex: Experiment) -> dict:
    """What ``identify.json`` and ``--json`` hold: the reading, the preset, per actuator
    the identified model (SI) with the paper's in SI and the ratios."""

    reading = ex.paper_units
    paper = paper_models(reading)
    acts = {}
    for name, r in results.items():
        p = paper[name]
        acts[name] = r.as_dict() | {
            "paper": p.as_dict(),
            "wn_ratio": r.wn_rad_s / p.wn_rad_s,
            "zeta_difference": r.zeta - p.zeta,
            "velocity_gain_ratio": r.velocity_gain_m_s_per_v / p.velocity_gain_m_s_per_v,
        }
    return {
        "paper_units": paper_units_info(reading),
        "units": {"b": "m/s^3/V", "a1": "1/s", "a0": "1/s^2", "velocity_gain": "m/s/V"},
        "preset": ex.preset,
        "actuators": acts,
    }
