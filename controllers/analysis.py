"""Stability and response analysis of the joint and task-space loops (paper section 4).

Outer loop, per task axis (eqs. 21-27): the integrated pose is
``x_c[k+1] = x_c[k] + T K_I e[k]`` (Fig. 7's ``T K_I / (z - 1)``, forward
Euler), the inner loop is ``d`` samples of delay (eq. 21: ``d = 1``), the
sensor a gain ``K``. With ``g = K K_I`` the loop gain is::

    L(z) = g T N(z) / ((z - 1) z^d),   N = 1 (I, eq. 22),  N = z + c (PI, c = 0.2)

and the characteristic polynomial ``P(z) = (z - 1) z^d + g T N(z)`` is linear
in ``g``: ``P = A + g B``. For ``d = 1`` (eq. 24) it is second order and the
Jury conditions ``|a0| < 1``, ``P(1) > 0``, ``P(-1) > 0`` give closed forms:

* I:  ``z^2 - z + g T``:  ``g T < 1``,  so ``g < 1/T = 16.67`` for T = 60 ms;
* PI: ``z^2 + (g T - 1) z + c g T``: ``g < min(1/(c T), 2/((1 - c) T))``
  = ``min(83.3, 41.7) = 41.7``.

For any order :func:`stability_limit` finds the first gain at which a root
reaches the unit circle (``z = 1``, ``z = -1`` or a complex pair: zero of the
imaginary part of ``-A/B`` on the circle, refined with ``brentq``) and checks
it with the poles (:func:`schur_stable`) just above.

The "real inner loop" replaces the delay by the discretised joint controller
and the identified plant (ZOH at 1 ms), lifted to the outer period
(``Phi = A_cl^n``, ``Gamma = sum A_cl^i B_cl``), mapped to the task space
with the IK Jacobian at home.

Imports numpy and scipy; python-control (``control``) on use, for the root
loci and step information (``analyze``). The pieces every run's preflight
uses stay numpy (the discretisation, the realisation, the stability
limit): each says why and is tested against python-control.
"""

from __future__ import annotations

import numpy as np

from .design import (
    ACTUATORS,
    DEFAULT_READING,
    JointDesign,
    Plant,
    closed_loop_poles,
    closed_loop_tf,
    damping,
    design_for,
    paper_plant,
)
from .joint import discretise, leg_state_space

__all__ = [
    "schur_stable",
    "outer_polynomials",
    "closed_form_limit",
    "stability_limit",
    "outer_poles",
    "outer_step",
    "root_locus",
    "tf_step",
    "step_metrics",
    "inner_summary",
    "inner_discrete_loop",
    "lift",
    "with_setpoint_filter",
    "lifted_inner",
    "outer_closed_loop",
    "spectral_radius",
    "real_inner_closed_loop",
    "real_inner_limit",
    "real_inner_step",
]


# --------------------------------------------------------------------------
# Outer loop with the inner loop as a delay (eqs. 21, 24-27)
# --------------------------------------------------------------------------
def schur_stable(coeffs, tol: float = 0.0) -> bool:
    """All roots of ``coeffs`` (highest power first) inside the unit circle, ``|z| < 1 - tol``.

    The poles of ``1 / P(z)``; they replace the hand-written Jury (Schur-Cohn)
    table of the first version (issue 14): same verdict on every polynomial
    whose largest root is not within 1e-9 of the circle
    (``tests/test_analysis.py``).
    """
    a = np.trim_zeros(np.asarray(coeffs, dtype=float), "f")
    if a.size == 0:
        raise ValueError("schur_stable: zero polynomial")
    if a.size == 1:
        return True
    return bool(np.max(np.abs(np.roots(a))) < 1.0 - tol)


def outer_polynomials(
    mode: str, period: float, delay: int = 1, pi_zero: float = 0.2
) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` with characteristic polynomial ``A(z) + g B(z)``, ``g = K K_I``.

    ``A = (z - 1) z^delay``; ``B = T`` (I) or ``T (z + pi_zero)`` (PI).
    """
    if mode not in ("I", "PI"):
        raise ValueError(f"mode must be 'I' or 'PI', got {mode!r}")
    if delay < 1 or int(delay) != delay:
        raise ValueError(f"delay must be a positive integer number of samples, got {delay}")
    a = np.polymul([1.0, -1.0], np.r_[1.0, np.zeros(int(delay))])
    b = np.array([period]) if mode == "I" else period * np.array([1.0, pi_zero])
    return a, np.r_[np.zeros(a.size - b.size), b]


def closed_form_limit(mode: str, period: float, delay: int = 1, pi_zero: float = 0.2) -> float:
    """Largest stable ``K K_I`` from the Jury conditions worked by hand.

    ``delay = 1``: I ``1/T``; PI ``min(1/(c T), 2/((1 - c) T))`` (``|c| < 1``).
    ``delay = 2``, I: ``z^3 - z^2 + gT``: Jury's ``1 - (gT)^2 > gT`` gives
    ``g T < (sqrt(5) - 1)/2``.
    """
    if delay == 1 and mode == "I":
        return 1.0 / period
    if delay == 1 and mode == "PI":
        c = pi_zero
        lims = [2.0 / ((1.0 - c) * period)] if c < 1 else []
        if c > 0:
            lims.append(1.0 / (c * period))
        return min(lims) if lims else np.inf
    if delay == 2 and mode == "I":
        return (np.sqrt(5.0) - 1.0) / 2.0 / period
    raise NotImplementedError("closed form only for delay 1 (I, PI) and delay 2 (I)")


def _spectral_radius_poly(a, b, g) -> float:
    return float(np.max(np.abs(np.roots(np.polyadd(a, g * b)))))


def stability_limit(a, b, g_max: float = 1e4) -> float:
    """Largest ``g > 0`` such that ``A + g' B`` is Schur for every ``0 < g' < g``.

    Candidates are the gains at which a root lies on the unit circle:
    ``g = -A(1)/B(1)``, ``g = -A(-1)/B(-1)``, and ``g = -A(e^jw)/B(e^jw)`` where
    that is real (zeros of its imaginary part, refined by ``brentq``). The
    smallest positive candidate at which the closed loop is unstable just above
    is returned (``inf`` if none below ``g_max``).

    Kept by hand: python-control 0.10's ``stability_margins`` of ``B / A``
    reports a spurious crossing at ``w = 0`` (``gm ~ 1e-15``, the integrator
    at ``z = 1``) and misses the one at ``w = pi`` (PI, ``d = 1``: ``inf``
    instead of 41.7), measured in ``tests/test_analysis.py``.
    """
    from scipy.optimize import brentq

    a = np.asarray(a, float)
    b = np.asarray(b, float)

    def gain(w):
        z = np.exp(1j * w)
        return -np.polyval(a, z) / np.polyval(b, z)

    cands = []
    for z in (1.0, -1.0):
        bz = np.polyval(b, z)
        if bz != 0:
            cands.append(-np.polyval(a, z) / bz)
    w = np.linspace(1e-6, np.pi - 1e-6, 4001)
    im = gain(w).imag
    for i in np.nonzero(np.sign(im[:-1]) * np.sign(im[1:]) < 0)[0]:
        wi = brentq(lambda x: gain(x).imag, w[i], w[i + 1], xtol=1e-15)
        cands.append(gain(wi).real)
    cands = sorted(c for c in cands if 0 < c < g_max and np.isfinite(c))
    for g in cands:
        eps = 1e-9 * max(g, 1.0)
        if not schur_stable(np.polyadd(a, (g + eps) * b)):
            return float(g)
    return float("inf")


def outer_poles(mode: str, gain: float, period: float, delay: int = 1, pi_zero: float = 0.2):
    """Closed-loop z-plane poles of one task axis."""
    a, b = outer_polynomials(mode, period, delay, pi_zero)
    return np.roots(np.polyadd(a, gain * b))


def outer_step(
    mode: str, gain: float, period: float, n: int, delay: int = 1, pi_zero: float = 0.2
) -> np.ndarray:
    """Unit-step response y[0..n-1] of one task axis (delay model), by the difference equation.

    Same recursion as the implementation: the I law outputs ``x_c[k]`` then
    integrates ``e[k]``; the PI law integrates ``e[k] + c e[k-1]`` first.
    """
    y = np.zeros(n)
    qd = np.zeros(n)
    xc, e_prev = 0.0, 0.0
    for k in range(n):
        y[k] = qd[k - delay] if k >= delay else 0.0
        e = 1.0 - y[k]
        if mode == "I":
            qd[k] = xc
            xc += period * gain * e
        else:
            xc += period * gain * (e + pi_zero * e_prev)
            e_prev = e
            qd[k] = xc
    return y


def root_locus(a, b, gains) -> np.ndarray:
    """Roots (len(gains), order) of ``A + g B`` for each gain.

    :func:`control.root_locus_map` of the loop ``B / A`` (discrete); its
    branches are ordered for continuity from one gain to the next.
    """
    import control  # imported on use: ``import controllers`` stays light

    loop = control.tf(np.asarray(b, float), np.asarray(a, float), True)
    return np.asarray(control.root_locus_map(loop, np.asarray(gains, float)).loci)


# --------------------------------------------------------------------------
# Inner loops
# --------------------------------------------------------------------------
def _companion(num, den):
    """Controllable canonical ``(A, B, C, D)`` of ``num / den``.

    Kept by hand (it runs in every run's preflight, which python-control's
    1-2 s import would slow): equal to :func:`control.tf2ss` exactly
    (``tests/test_analysis.py``).
    """
    num = np.atleast_1d(np.asarray(num, float))
    den = np.asarray(den, float)
    num, den = num / den[0], den / den[0]
    n = den.size - 1
    num = np.r_[np.zeros(n + 1 - num.size), num]
    d = num[0]
    nn = num[1:] - d * den[1:]
    a = np.zeros((n, n))
    a[0, :] = -den[1:]
    a[1:, :-1] = np.eye(n - 1)
    b = np.zeros((n, 1))
    b[0, 0] = 1.0
    return a, b, nn[None, :], np.array([[d]])


def tf_step(num, den, t) -> np.ndarray:
    """Samples of the continuous unit-step response on a uniform grid t.

    python-control's :func:`control.step_response`, which integrates the
    state-space realisation exactly between samples (zero-order hold of the
    step), so the samples carry no discretisation error. The step is applied
    at ``t[0]`` with the system at rest.
    """
    import control  # imported on use: ``import controllers`` stays light

    t = np.asarray(t, float)
    res = control.step_response(control.tf(num, den), T=t)
    return np.asarray(res.outputs, float).reshape(-1)


def step_metrics(t, y, final: float | None = None, settle: float = 0.02) -> dict:
    """Rise time 10-90 %, settling time (band ``settle``), overshoot (%) of a step.

    :func:`control.step_info` on the samples with ``final`` as the steady
    state (default the last sample). A response that never reaches 90 % of it
    has no rise time, overshoot or settling (NaN, 0, NaN: ``step_info`` would
    raise); a zero final value is refused (``step_info`` divides by it).
    """
    import control  # imported on use: ``import controllers`` stays light

    t = np.asarray(t, float)
    y = np.asarray(y, float)
    yf = float(y[-1]) if final is None else float(final)
    if yf == 0.0:
        raise ValueError("step_metrics: the final value is 0; allowed: a step to a non-zero value")
    nan = float("nan")
    if not np.any(np.sign(yf) * (y - 0.9 * yf) >= 0):
        return {"final": yf, "rise_time_s": nan, "overshoot_pct": 0.0, "settling_time_s": nan}
    info = control.step_info(
        y, T=t, yfinal=yf, SettlingTimeThreshold=settle, RiseTimeLimits=(0.1, 0.9)
    )
    return {
        "final": yf,
        "rise_time_s": float(info["RiseTime"]),
        "overshoot_pct": float(info["Overshoot"]),
        "settling_time_s": float(info["SettlingTime"]),
    }


def inner_summary(
    actuator: str,
    variant: str,
    t_end: float = 3.0,
    dt: float = 1e-3,
    spec=None,
    reading: str = DEFAULT_READING,
) -> dict:
    """Closed-loop poles, damping and step metrics of one continuous joint loop.

    The plant is eq. (34)/(35) and the controller eq. (36)/(37) in SI under
    ``reading`` (:data:`controllers.design.READINGS`); the closed loop does
    not depend on the reading (``k_p b`` does not), the printed ``k_p`` does.
    """
    plant = paper_plant(actuator, reading)
    spec = dict(spec or {}) if variant == "redesigned" else {}
    des = design_for(actuator, variant, plant=plant, reading=reading, **spec)
    poles = closed_loop_poles(des, plant)
    wn, zeta = damping(poles)
    num, den = closed_loop_tf(des, plant)
    t = np.arange(0.0, t_end + dt / 2, dt)
    y = tf_step(num, den, t)
    return {
        "controller": des.as_dict(),
        "closed_loop_poles": poles,
        "wn_rad_s": wn,
        "zeta": zeta,
        "step": step_metrics(t, y, final=1.0),
        "t": t,
        "y": y,
    }


def inner_discrete_loop(
    design: JointDesign, plant: Plant, dt: float = 1e-3, method: str = "tustin"
):
    """Linear closed joint loop at ``dt``: ``(A, B, C)`` from q_ref to q (no saturation).

    Plant ZOH-discretised (exact for the held valve command), controller by
    ``method`` (see :func:`controllers.joint.leg_state_space`).
    """
    ap, bp, cp, dp = _companion(plant.num, plant.den)
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
        from .setpoint_filter import filter_state_space, leg_times

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


def real_inner_closed_loop(
    mode: str,
    gain,
    period: float,
    variant: str = "corrected",
    dt: float = 1e-3,
    method: str = "tustin",
    jac=None,
    actuators=ACTUATORS,
    pi_zero: float = 0.2,
    legs=None,
    spec=None,
    setpoint_filter=None,
):
    """:func:`outer_closed_loop` around :func:`lifted_inner` (see both)."""
    lifted = lifted_inner(period, variant, dt, method, actuators, legs, spec, setpoint_filter)
    return outer_closed_loop(mode, gain, period, lifted, jac, pi_zero)


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

    lifted = lifted_inner(period, variant, dt, method, actuators, legs, spec, setpoint_filter)

    def rho(g):
        return spectral_radius(outer_closed_loop(mode, g, period, lifted, jac, pi_zero)[0])

    grid = np.geomspace(1e-3, g_max, 200)
    vals = np.array([rho(g) for g in grid]) - 1.0
    if vals[0] >= 0:
        return 0.0
    bad = np.nonzero(vals >= 0)[0]
    if not bad.size:
        return float("inf")
    i = bad[0]
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
