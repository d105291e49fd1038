"""The cueing bound: the best a roll-pitch-heave platform can do with the whole drive known.

:class:`~controllers.mpc_cueing.ModelPredictiveCueing` plans 1.2 s at a time with at most
its preview of the future. The bound plans the whole recording at once: one QP over every
period of the drive, from rest, knowing every sample, with the MPC's model, cost and
constraints (:class:`~controllers.cue_mpc_params.MpcParams`: the otolith and canal models,
each error in units of its threshold; the workspace box, the tilt and heave rates and
accelerations, the felt-rotation and wrong-way-jolt limits) and the car's sensation at
full scale (``gain_x = gain_y = gain_z = gain_rot = 1``): the platform chooses its own
scale. No law with the same model and limits can reach a lower cost on that drive; what
the bound's head feels, through the same vestibular model and metrics as a run, is what
this platform could give the driver.

Formulation (per axis; the three are decoupled in the model, so three QPs), sparse: the
decision is ``z = (x_1 .. x_N, j_0 .. j_{N-1})`` with the model's states ``x`` (platform
``a, a', a''``, otolith and canal errors, the vehicle's canal) and the jerk ``j`` held over
a period ``T``::

    x_{k+1} = A x_k + B_j j_k + B_d d_k,  x_0 = 0
    min  sum_k |C x_k + D d_k|^2 + r j_k^2   s.t.  l_k <= S x_k <= u_k

``C``, ``D``, ``r`` and ``S`` are the MPC's own rows (:meth:`ModelPredictiveCueing._build`),
so the QP has ``(n + 1) N`` variables and its matrices grow linearly with the drive (OSQP,
Stellato et al. 2020). Where the felt-rotation or jolt limits cannot be met the QP is
solved again without the jolt limit, then without both, as the MPC does (``status`` says
so).

The platform is ideal here: it follows the plan exactly (the loop's lag, the valves and
the pneumatics are the run's, not the bound's).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .cue_mpc_params import MpcParams
from .frames import GRAVITY
from .mpc_cueing import WITHOUT, ModelPredictiveCueing


@dataclass
class CueBound:
    """The bound's platform motion and what it gives the head, on the input's grid.

    ``t`` (n,), ``pose_iso`` (n, 3): ISO roll, ISO pitch (rad) and heave from home (m);
    ``f``, ``w`` (n, 3): the head's specific force and angular velocity (V frame, SI; a
    rigid cabin, the head ``head_height`` above the roll axis and ``head_height_pitch``
    above the pitch motion's); ``status`` per axis (pitch, roll, heave), ``solve_s`` the
    three solves' wall time, ``periods`` the QP's length, ``limits`` the box's half-range
    (roll, pitch rad, heave m) the plan kept to.
    """

    t: np.ndarray
    pose_iso: np.ndarray
    f: np.ndarray
    w: np.ndarray
    status: list
    solve_s: float
    periods: int
    limits: tuple


def _bound_params(params: MpcParams | None, **changes) -> MpcParams:
    p = MpcParams() if params is None else params
    full = {"gain_x": 1.0, "gain_y": 1.0, "gain_z": 1.0, "gain_rot": 1.0, "knee": 0.0,
            "gain_y_sustained": 0.0}  # fmt: skip
    return p.replace(
        **{"horizon": 2, "preview": 0.0, "lead": 0.0, "lead_x": 0.0, **full, **changes}
    )


def _axis_qp(law: ModelPredictiveCueing, k: int, d: np.ndarray, N: int):
    """The sparse QP of axis ``k`` over ``N`` periods with the vehicle input ``d`` (N, 2)."""
    from scipy import sparse

    p, ax, pr = law.params, law.axes[k], law._pred[k]
    n = ax.n
    ny = pr.CY.shape[0] // law.N  # the MPC's per-sample cost rows (horizon N_mpc)
    cy = pr.CY[:ny, :n]
    dy = pr.DY[:ny, 2:4]  # the sample's own input (horizon 2: shift [[0, 1], [0, 1]])
    sel = pr.S[: pr.rows, :n]
    A, B = ax.ad, ax.bd
    jref = ax.accel_max / p.period
    r = p.weight_jerk / jref**2
    nx = N * n
    # cost: x_k (k = 1..N) sees d_k (d is indexed 0..N, the vehicle at each sample)
    P = sparse.block_diag(
        [sparse.kron(sparse.eye(N), sparse.csc_matrix(2.0 * cy.T @ cy)), 2.0 * r * sparse.eye(N)],
        format="csc",
    )
    q = np.r_[(2.0 * (cy.T @ (dy @ d[1:].T))).T.ravel(), np.zeros(N)]
    # dynamics: x_{k+1} - A x_k - B_j j_k = B_d d_k
    Ax = sparse.kron(sparse.eye(N), sparse.eye(n)) - sparse.kron(sparse.eye(N, k=-1), A)
    Au = sparse.kron(sparse.eye(N), sparse.csc_matrix(B[:, 0:1]))
    Aeq = sparse.hstack([Ax, -Au])
    beq = (B[:, 1:3] @ d[:-1].T).T.ravel()
    # the vehicle-only (jerk-free) trajectory: the felt-rotation bounds
    free = np.zeros((N + 1, n))
    for i in range(N):
        free[i + 1] = A @ free[i] + B[:, 1:3] @ d[i]
    rows, cveh = pr.rows, None
    if pr.veh is not None:
        vrow = pr.veh[0][0, :n]
        vd = pr.veh[1][0, 2:4]
        cveh = free[1:] @ vrow + d[1:] @ vd
        wv = d[:, 1]
        cveh = cveh + ax.tau_n * np.gradient(wv)[1:] / p.period / ax.thr_w
    lo, hi = pr.bounds(ax, cveh, d[1:, 0], law._rotation_limit(ax.kind), N)
    Ain = sparse.hstack(
        [sparse.kron(sparse.eye(N), sparse.csc_matrix(sel)), sparse.csc_matrix((N * rows, N))]
    )
    A_all = sparse.vstack([Aeq, Ain], format="csc")
    # the rows given up in turn: the jolt limit's, then the felt rotation's too
    soft: list[np.ndarray] = []
    for cols in ((pr.jolt,), (pr.felt, pr.jolt)):
        mask = np.zeros((N, rows), bool)
        for c in cols:
            if c is not None:
                mask[:, c] = True
        soft.append(nx + mask.ravel().nonzero()[0])
    return (
        P,
        q,
        A_all,
        np.r_[beq, lo.ravel()],
        np.r_[beq, hi.ravel()],
        nx,
        soft,
    )


def _solve(P, q, A, lo, hi, soft_rows):
    import osqp
    from scipy import sparse

    P = sparse.triu(P, format="csc")

    def run(lo, hi):
        s = osqp.OSQP()
        s.setup(P, q, A, lo, hi, verbose=False, eps_abs=1e-5, eps_rel=1e-5, max_iter=20000,
                polishing=True)  # fmt: skip
        return s.solve(raise_error=False)

    res = run(lo, hi)
    status = str(res.info.status)
    lo, hi = lo.copy(), hi.copy()
    for rows, without in zip(soft_rows, WITHOUT, strict=True):
        if "infeasible" not in status or not rows.size:
            break
        lo[rows], hi[rows] = -np.inf, np.inf
        res = run(lo, hi)
        status = str(res.info.status) + without
    return res, status


def _evaluate(x3: np.ndarray, jerks: np.ndarray, period: float, t: np.ndarray) -> np.ndarray:
    """Position, rate, acceleration (3, len(t)) of the triple integrator with state ``x3``
    (N + 1, 3) at the period starts and the jerks (N,) held over each period."""
    k = np.minimum((t // period).astype(int), jerks.size - 1)
    r = t - k * period
    a0, a1, a2, j = x3[k, 0], x3[k, 1], x3[k, 2], jerks[k]
    return np.vstack(
        [
            a0 + a1 * r + 0.5 * a2 * r**2 + j * r**3 / 6.0,
            a1 + a2 * r + 0.5 * j * r**2,
            a2 + j * r,
        ]
    )


def cue_bound(f, w, dt: float, params: MpcParams | None = None, geometry=None) -> CueBound:
    """The bound (module docstring) of a vehicle input ``f``, ``w`` (n, 3, V frame, SI)
    sampled every ``dt`` from rest.

    ``params``: the law's :class:`MpcParams` (their box, limits and weights; the gains
    are set to 1, the preview to the whole drive); ``None``: the MPC's defaults.
    """
    f = np.asarray(f, float)
    w = np.asarray(w, float)
    if f.ndim != 2 or f.shape[1] != 3 or w.shape != f.shape:
        raise ValueError(f"f and w must both be (n, 3), got {f.shape} and {w.shape}")
    p = _bound_params(params)
    law = ModelPredictiveCueing(p, geometry=geometry)
    n = f.shape[0]
    t = dt * np.arange(n)
    period = p.period
    N = max(2, int(np.ceil(t[-1] / period)) + 1)
    idx = np.minimum(np.round(np.arange(N + 1) * period / dt).astype(int), n - 1)
    out = np.zeros((n, 3))  # ISO roll, ISO pitch, heave
    plans = {}
    status = []
    t0 = time.perf_counter()
    for k, ax in enumerate(law.axes):
        d = law._d(f[idx], w[idx], k).reshape(N + 1, 2)
        P, q, A, lo, hi, nx, soft = _axis_qp(law, k, d, N)
        res, st = _solve(P, q, A, lo, hi, soft)
        status.append(st)
        if res.x is None or not np.all(np.isfinite(res.x)):
            x = np.zeros(nx + N)
        else:
            x = np.asarray(res.x, float)
        xs = np.vstack([np.zeros(ax.n), x[:nx].reshape(N, ax.n)])
        plans[ax.kind] = _evaluate(xs[:, :3], x[nx:], period, t)
    solve_s = time.perf_counter() - t0
    hp, hr = p.head_height_pitch, p.head_height
    th, a_r, z = plans["pitch"], plans["roll"], plans["heave"]
    phi = -a_r[0]
    out[:, 0], out[:, 1], out[:, 2] = phi, th[0], z[0]
    head_f = np.column_stack(
        [
            hp * th[2] - GRAVITY * np.sin(th[0]),
            hr * a_r[2] - GRAVITY * np.sin(a_r[0]),
            GRAVITY * np.cos(th[0]) * np.cos(phi) + z[2],
        ]
    )
    head_w = np.column_stack([-a_r[1], th[1], np.zeros(n)])
    limits = (law.axes[1].amax, law.axes[0].amax, law.axes[2].amax)
    return CueBound(t=t, pose_iso=out, f=head_f, w=head_w, status=status, solve_s=solve_s,
                    periods=N, limits=limits)  # fmt: skip
