"""The outer loop around the real inner loops: the discretised joint controllers and the
identified plants (ZOH at 1 ms), behind Fig. 13's set-point filter, lifted to the outer
period (``Phi = A_cl^n``, ``Gamma = sum A_cl^i B_cl``) and mapped to the task space with
the IK Jacobian at home; its stability limit and step.
"""

from __future__ import annotations

import numpy as np

from controllers.analysis.inner import companion
from controllers.design import (
    ACTUATORS,
    DEFAULT_READING,
    JointDesign,
    Plant,
    design_for,
    paper_plant,
)
from controllers.joint import discretise, leg_state_space
from controllers.setpoint_filter import filter_state_space, leg_times


def inner_discrete_loop(
    design: JointDesign, plant: Plant, dt: float = 1e-3, method: str = "tustin"
):
    """Linear closed joint loop at ``dt``: ``(A, B, C)`` from q_ref to q (no saturation).

    Plant ZOH-discretised (exact for the held valve command), controller by
    ``method`` (see :func:`controllers.joint.leg_state_space`).
    """
    ap, bp, cp, dp = companion(plant.num, plant.den)
    apd, bpd, cpd, _ = discretise(ap, bp, cp, dp, dt, "zoh")
    ac, bc, cc, dc = leg_state_space(design, dt, method)
    npl, nc = apd.shape[0], ac.shape[0]
    a = np.zeros((npl + nc, npl + nc))
    a[:npl, :npl] = apd - bpd @ dc @ cpd
    a[:npl, npl:] = bpd @ cc
    a[npl:, :npl] = -bc @ cpd
    a[npl:, npl:] = ac
    b = np.vstack([bpd @ dc, bc])
    c = np.hstack([cpd, np.zeros((1, nc))])
    return a, b, c


def with_setpoint_filter(leg, filt):
    """A fast-rate joint loop ``(A, B, C)`` behind the set-point filter ``(Af, Bf, Cf, Df)``
    of Fig. 13 (:func:`controllers.setpoint_filter.filter_state_space`): states
    ``[filter; loop]``, input the outer loop's q_d, output q."""
    a, b, c = (np.atleast_2d(np.asarray(m, float)) for m in leg)
    af, bf, cf, df = (np.atleast_2d(np.asarray(m, float)) for m in filt)
    nf, n = af.shape[0], a.shape[0]
    if nf == 0:
        return a, b * df[0, 0], c
    a2 = np.zeros((nf + n, nf + n))
    a2[:nf, :nf] = af
    a2[nf:, :nf] = b @ cf
    a2[nf:, nf:] = a
    return a2, np.vstack([bf, b @ df]), np.hstack([np.zeros((c.shape[0], nf)), c])


def lift(a, b, n: int):
    """State transition over ``n`` fast samples with the input held: ``(A^n, sum A^i B)``.

    Both come from one power of the augmented matrix ``[[A, B], [0, I]]^n =
    [[A^n, sum_{i<n} A^i B], [0, I]]``, by repeated squaring: O(log n)
    products, so a 10 s outer period costs what 60 ms does.
    """
    a = np.atleast_2d(np.asarray(a, float))
    shape = np.shape(b)
    b2 = np.asarray(b, float).reshape(a.shape[0], -1)
    nx, nu = b2.shape
    aug = np.zeros((nx + nu, nx + nu))
    aug[:nx, :nx], aug[:nx, nx:], aug[nx:, nx:] = a, b2, np.eye(nu)
    p = np.linalg.matrix_power(aug, int(n))
    return p[:nx, :nx], p[:nx, nx:].reshape(shape)


def _blockdiag(mats):
    r = sum(m.shape[0] for m in mats)
    c = sum(m.shape[1] for m in mats)
    out = np.zeros((r, c))
    i = j = 0
    for m in mats:
        out[i : i + m.shape[0], j : j + m.shape[1]] = m
        i += m.shape[0]
        j += m.shape[1]
    return out


def _legs(
    variant, dt, method, actuators, legs=None, spec=None, reading=DEFAULT_READING,
    setpoint_filter=None,
):  # fmt: skip
    """The joint loops on eqs. (34)-(35) in SI under ``reading`` (or ``legs`` as given),
    behind the set-point filter ``(kind, time_s)`` of Fig. 13 when one is given."""
    if legs is not None:
        return [tuple(np.atleast_2d(np.asarray(m, float)) for m in leg) for leg in legs]
    spec = dict(spec or {}) if variant == "redesigned" else {}
    filt = [None] * 3
    if setpoint_filter is not None:  # (kind, time or 3 times), one filter per leg
        filt = [
            filter_state_space(setpoint_filter[0], dt, t) for t in leg_times(setpoint_filter[1])
        ]
    out = []
    for act in actuators:
        plant = paper_plant(act, reading)
        des = design_for(act, variant, plant=plant, reading=reading, **spec)
        leg = inner_discrete_loop(des, plant, dt, method)
        f = filt[ACTUATORS.index(act)]
        out.append(leg if f is None else with_setpoint_filter(leg, f))
    return out


def lifted_inner(
    period: float,
    variant: str = "corrected",
    dt: float = 1e-3,
    method: str = "tustin",
    actuators=ACTUATORS,
    legs=None,
    spec=None,
    setpoint_filter=None,
):
    """Inner loops lifted to the outer period: block-diagonal ``(Phi, Gamma, C_q)``.

    ``legs`` (list of fast-rate ``(A, B, C)``) replaces the joint loops, e.g.
    ``[(0, 1, 1)]`` is exactly the one-sample delay of eq. (21).
    ``setpoint_filter`` ``(kind, time_s)``: Fig. 13's filter in front of each loop
    (:mod:`controllers.setpoint_filter`).
    """
    n = int(round(period / dt))
    fast = _legs(variant, dt, method, actuators, legs, spec, setpoint_filter=setpoint_filter)
    lifted = [lift(a, b, n) for a, b, _ in fast]
    return (
        _blockdiag([p for p, _ in lifted]),
        _blockdiag([g for _, g in lifted]),
        _blockdiag([c for _, _, c in fast]),
    )


def reduced(lifted):
    """The lifted inner loops with their dead-beat states folded into the held input.

    A state whose row of ``Phi`` is zero (the shift register of a ``"ramp"`` set-point
    filter no longer than the outer period: ``A_f^n = 0``) is at every outer instant
    ``x_R[k] = Gamma_R u[k-1]``: a function of the previous held input. Replacing
    those states by ``p[k] = u[k-1]``::

        x_N[k+1] = Phi_NN x_N[k] + Phi_NR Gamma_R p[k] + Gamma_N u[k]
        p[k+1]   = u[k]
        y[k]     = C_N x_N[k] + C_R Gamma_R p[k]

    gives a loop whose closed loop under any outer law has the full one's nonzero
    eigenvalues (the map ``(x_N, p) -> (x_N, Gamma_R p)`` intertwines the two; only
    eigenvalues 0 are dropped), so the spectral radius and the stability limit are
    the same with a state of 3 legs x (plant + controller) + 3 instead of about
    130 (the shipped ramps of 60/30/30 ms). ``lifted`` comes back as it is when no
    such state exists.
    """
    phi, gam, cq = lifted
    dead = ~np.any(phi != 0.0, axis=1)
    nu = gam.shape[1]
    if dead.sum() <= nu:
        return lifted
    keep = ~dead
    gr = gam[dead]
    n = int(keep.sum())
    phi2 = np.zeros((n + nu, n + nu))
    phi2[:n, :n] = phi[np.ix_(keep, keep)]
    phi2[:n, n:] = phi[np.ix_(keep, dead)] @ gr
    gam2 = np.vstack([gam[keep], np.eye(nu)])
    cq2 = np.hstack([cq[:, keep], cq[:, dead] @ gr])
    return phi2, gam2, cq2


def outer_closed_loop(mode: str, gain, period: float, lifted, jac=None, pi_zero: float = 0.2):
    """Slow-rate closed loop ``(F, G, H)``: outer law around lifted inner loops.

    State ``[xi; x_c]`` (I) or ``[xi; x_c[k-1]; e[k-1]]`` (PI), ``xi`` the
    inner states at the outer sampling instants. ``jac`` (m x m) maps task to
    joint deviations (``q_d = J x_c``, ``y = J^-1 q``); default identity
    (per-leg analysis). ``gain`` is a scalar or one per axis.
    """
    phi, gam, cq = lifted
    m = cq.shape[0]
    jac = np.eye(m) if jac is None else np.asarray(jac, float)
    hy = np.linalg.inv(jac) @ cq  # y = hy xi,  e = r - hy xi
    g = np.diag(np.broadcast_to(np.asarray(gain, float), (m,))) * period
    nx = phi.shape[0]
    eye, zero = np.eye(m), np.zeros((m, m))
    if mode == "I":
        # q_d[k] = J x_c[k];  xi+ = phi xi + gam J x_c;  x_c+ = x_c + g (r - hy xi)
        f = np.block([[phi, gam @ jac], [-g @ hy, eye]])
        gr = np.vstack([np.zeros((nx, m)), g])
        h = np.hstack([hy, zero])
    elif mode == "PI":
        # x_c[k] = x_c[k-1] + g (e[k] + c e[k-1]);  xi+ = phi xi + gam J x_c[k]
        c = pi_zero
        gj = gam @ jac
        f = np.block(
            [
                [phi - gj @ g @ hy, gj, c * gj @ g],
                [-g @ hy, eye, c * g],
                [-hy, zero, zero],
            ]
        )
        gr = np.vstack([gj @ g, g, eye])
        h = np.hstack([hy, zero, zero])
    else:
        raise ValueError(f"mode must be 'I' or 'PI', got {mode!r}")
    return f, gr, h


def closed_loops(mode: str, gains, period: float, lifted, jac=None, pi_zero: float = 0.2):
    """:func:`outer_closed_loop`'s ``F`` at each common gain of ``gains``, stacked
    ``(len(gains), n, n)``, element for element the same numbers.

    ``F`` is the gain-free loop plus the gain's blocks, each built as
    :func:`outer_closed_loop` rounds it: a product by the diagonal ``g = K K_I T``
    is each gain times the other factor rounded once (``-g H_y``; the PI law's
    ``c (Gamma J) g`` and ``c g``), and the PI law's ``(Gamma J g) H_y`` is the same
    matrix product, one gain's at a time in one stacked ``matmul``.
    """
    gains = np.asarray(gains, float)
    if mode not in ("I", "PI"):
        raise ValueError(f"mode must be 'I' or 'PI', got {mode!r}")
    phi, gam, cq = lifted
    m, nx = cq.shape[0], phi.shape[0]
    jac = np.eye(m) if jac is None else np.asarray(jac, float)
    hy = np.linalg.inv(jac) @ cq
    gp = (gains * period)[:, None, None]
    f = np.repeat(
        outer_closed_loop(mode, 0.0, period, lifted, jac, pi_zero)[0][None], gains.size, 0
    )
    f[:, nx : nx + m, :nx] = -(gp * hy)
    if mode == "PI":
        gj = gam @ jac
        f[:, :nx, :nx] = phi - np.matmul(gj * gp, hy)
        f[:, :nx, nx + m :] = (pi_zero * gj) * gp
        f[:, nx : nx + m, nx + m :] = (pi_zero * gp) * np.eye(m)
    return f


#: Gains of the stability scan whose closed loops are solved in one call.
_SCAN_BLOCK = 40


def spectral_radius(f) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(f))))


def real_inner_limit(
    mode: str,
    period: float,
    g_max: float = 200.0,
    variant: str = "corrected",
    dt: float = 1e-3,
    method: str = "tustin",
    jac=None,
    actuators=ACTUATORS,
    pi_zero: float = 0.2,
    legs=None,
    spec=None,
    setpoint_filter=None,
) -> float:
    """Largest common ``K K_I`` with the real-inner-loop closed loop stable (rho(F) < 1).

    Scans ``g`` on a log grid from 1e-3 to ``g_max``, then refines the first
    crossing of ``rho = 1`` with ``brentq`` (``inf`` if none).
    """
    from scipy.optimize import brentq

    # the same spectral radius on a state a sixth the size (reduced): ~200 eigenvalue problems
    lifted = reduced(
        lifted_inner(period, variant, dt, method, actuators, legs, spec, setpoint_filter)
    )

    def rho(g):
        return spectral_radius(outer_closed_loop(mode, g, period, lifted, jac, pi_zero)[0])

    grid = np.geomspace(1e-3, g_max, 200)
    # up to the first unstable gain only: the grid beyond it cannot move the crossing. A
    # block of gains at a time, their eigenvalue problems in one call: the same numbers
    # as one gain at a time (closed_loops), for about half the CPU
    i = None
    for start in range(0, grid.size, _SCAN_BLOCK):
        f = closed_loops(mode, grid[start : start + _SCAN_BLOCK], period, lifted, jac, pi_zero)
        unstable = np.flatnonzero(np.max(np.abs(np.linalg.eigvals(f)), axis=-1) >= 1.0)
        if unstable.size:
            i = start + int(unstable[0])
            break
    if i is None:
        return float("inf")
    if i == 0:
        return 0.0
    return float(brentq(lambda g: rho(g) - 1.0, grid[i - 1], grid[i], xtol=1e-10))


def real_inner_step(
    mode: str,
    gain,
    period: float,
    t_end: float,
    variant: str = "corrected",
    dt: float = 1e-3,
    method: str = "tustin",
    jac=None,
    actuators=ACTUATORS,
    pi_zero: float = 0.2,
    axis: int = 0,
    legs=None,
    spec=None,
    model_tau: float = 0.0,
    lag: str = "model",
    setpoint_filter=None,
):
    """Task-axis unit-step response at the fast rate with the real inner loops.

    ``mode`` ``"I"``, ``"PI"`` or ``"feedforward"`` (the set-point through the
    Jacobian every fast step plus the I correction of ``M r - y``, ``M`` a
    first-order lag of ``model_tau`` s, or with ``lag="joints"`` of
    ``r - y - J^-1 (q_d - q)``, as
    :class:`controllers.task_space.TaskSpaceController`). Returns ``(t, y)``
    with ``y`` (len(t), m) the task deviations (linear model: no as-built
    error, so with ``lag="joints"`` the correction stays at zero and the step is
    the joint loops').
    """
    n = int(round(period / dt))
    legs = _legs(variant, dt, method, actuators, legs, spec, setpoint_filter=setpoint_filter)
    a = _blockdiag([x[0] for x in legs])
    b = _blockdiag([x[1] for x in legs])
    cq = _blockdiag([x[2] for x in legs])
    m = cq.shape[0]
    jac = np.eye(m) if jac is None else np.asarray(jac, float)
    jinv = np.linalg.inv(jac)
    g = np.broadcast_to(np.asarray(gain, float), (m,)) * period
    r = np.zeros(m)
    r[axis] = 1.0
    steps = int(round(t_end / dt))
    t = np.arange(steps) * dt
    y = np.zeros((steps, m))
    xi = np.zeros(a.shape[0])
    xc = np.zeros(m)
    e_prev = np.zeros(m)
    qd = np.zeros(m)
    beta = -np.expm1(-dt / model_tau) if model_tau > 0 else 1.0
    ref_model = np.zeros(m)  # M r, at rest before the step
    corr = np.zeros(m)
    for k in range(steps):
        yk = jinv @ (cq @ xi)
        y[k] = yk
        if mode == "feedforward":
            if k % n == 0:
                applied = corr.copy()  # c[k], then integrate e[k] for the next period
                if lag == "joints":  # y = J^-1 q in the linear model
                    corr = corr + g * (r - yk - jinv @ (qd - jac @ yk))
                else:
                    corr = corr + g * ((ref_model if model_tau > 0 else r) - yk)
            qd = jac @ (r + applied)
            ref_model = ref_model + beta * (r - ref_model)
        elif k % n == 0:
            e = r - yk
            if mode == "I":
                qd = jac @ xc
                xc = xc + g * e
            else:
                xc = xc + g * (e + pi_zero * e_prev)
                e_prev = e
                qd = jac @ xc
        xi = a @ xi + b @ qd
    return t, y
