"""Eq. (19)'s output-error fit with the filter's own sensitivities, compiled.

The experiment's fit (:func:`simpro_mj.identification.identify.fit_eq19`) minimises
:math:`\\sum_k (\\hat v_k(θ) - v_k)^2` over :math:`θ = (b, a_1, a_0, d)` with
``scipy.optimize.least_squares``' trust region on a Jacobian of forward differences:
about 60 simulations of the 20 s record and a singular-value decomposition of the
20,000 x 4 Jacobian per iteration, 0.08-0.11 s of CPU a leg. The same minimum is
reached here by Levenberg-Marquardt on the normal equations with the exact
Jacobian: the ZOH filter of :func:`~simpro_mj.identification.identify.zoh_velocity_filter`,
:math:`\\hat v_k = n_1 x_{k-1} + n_2 x_{k-2} - d_1 \\hat v_{k-1} - d_2 \\hat v_{k-2}`,
:math:`x = u - d`, differentiated through its recursion (forward sensitivities:
:math:`∂\\hat v/∂θ_j` obeys the same recursion driven by
:math:`∂n/∂θ_j\\, x - ∂d/∂θ_j\\, \\hat v`; the coefficients' derivatives by central
differences of the filter's closed form), the residual, :math:`J^T J` (4 x 4) and
:math:`J^T r` accumulated in one compiled pass over the record. An iteration costs
one pass instead of five simulations and an SVD. It stops as the trust region does,
when a step lowers the cost by less than :data:`FTOL` (1e-8) of it: the same minimum
within the flatness of its valley. On the reduced experiment's records of ``paper``,
``heavy_cabin`` and the 450/750 N cabin (nine legs) b, a1, a0 land within 3e-4 of
the trust region's but on that cabin's legs 2 and 3 (fit 5 %, the flattest valley
seen): 0.9 %, where the experiment's seeds spread them by 30 %. The pass, the
filter's coefficients and their matrix exponential are compiled (the last two from
:mod:`~simpro_mj.identification.identify`'s own source): CPU for those nine legs
0.30 s against the trust region's 1.76 s (one loaded machine, the same process).
"""

from __future__ import annotations

import math
import threading
import types as pytypes

import numpy as np

from simpro_mj.identification import identify
from simpro_mj.identification.identify import Fit, _arx_guess, zoh_velocity_filter

__all__ = ["FTOL", "coefficients", "fit_sensitivity", "normal_equations"]

#: A step that lowers the cost by less than this share of it ends the fit (the trust
#: region's ``ftol``).
FTOL = 1e-8
#: The damping's factors after a step that lowers the cost, and after one that does not.
LAM_DOWN, LAM_UP = 1.0 / 3.0, 4.0
#: Most iterations.
MAX_ITER = 200
#: Relative step of the central differences of the filter's coefficients.
COEF_STEP = 1e-6


def normal_equations(num, den, dnum, dden, x, v, skip, out_jtj, out_jtr):
    """One pass over the record: the cost ``r^T r / 2`` (returned), ``J^T J`` and
    ``J^T r`` (into the 4 x 4 and 4 arrays) of the filter ``(num, den)`` on input ``x``
    against ``v``, ``dnum``/``dden`` (3, 3) the coefficients' derivatives in b, a1, a0;
    the fourth parameter the offset d (input ``x - d``: its sensitivity is the filter
    of -1). Samples before ``skip`` are simulated, not counted."""
    n1, n2 = num[1], num[2]
    d1, d2 = den[1], den[2]
    y1 = y2 = 0.0
    s1 = np.zeros(4)
    s2 = np.zeros(4)
    s = np.zeros(4)
    for i in range(4):
        out_jtr[i] = 0.0
        for j in range(4):
            out_jtj[i, j] = 0.0
    cost = 0.0
    x1 = x2 = 0.0
    for k in range(x.shape[0]):
        y = n1 * x1 + n2 * x2 - d1 * y1 - d2 * y2
        for j in range(3):
            s[j] = (dnum[j, 1] * x1 + dnum[j, 2] * x2 - dden[j, 1] * y1 - dden[j, 2] * y2
                    - d1 * s1[j] - d2 * s2[j])  # fmt: skip
        # d: the input x - d, so its sensitivity is the filter of -1 from the record's start
        s[3] = -n1 * (1.0 if k >= 1 else 0.0) - n2 * (1.0 if k >= 2 else 0.0)
        s[3] += -d1 * s1[3] - d2 * s2[3]
        if k >= skip:
            r = y - v[k]
            cost += r * r
            for i in range(4):
                out_jtr[i] += s[i] * r
                for j in range(i + 1):
                    out_jtj[i, j] += s[i] * s[j]
        for j in range(4):
            s2[j] = s1[j]
            s1[j] = s[j]
        y2, y1 = y1, y
        x2, x1 = x1, x[k]
    for i in range(4):
        for j in range(i + 1, 4):
            out_jtj[i, j] = out_jtj[j, i]
    return 0.5 * cost


def coefficients(theta, dt, step):
    """The filter of ``theta`` (b, a1, a0) and its coefficients' derivatives in each
    (3, 3 each; central differences of relative ``step``)."""
    num, den = zoh_velocity_filter(theta[0], theta[1], theta[2], dt)
    dnum, dden = np.zeros((3, 3)), np.zeros((3, 3))
    for j in range(3):
        h = step * max(abs(theta[j]), 1e-3)
        up, dn = theta.copy(), theta.copy()
        up[j] += h
        dn[j] -= h
        nu, du = zoh_velocity_filter(up[0], up[1], up[2], dt)
        nd, dd = zoh_velocity_filter(dn[0], dn[1], dn[2], dt)
        for i in range(3):
            dnum[j, i] = (nu[i] - nd[i]) / (2 * h)
            dden[j, i] = (du[i] - dd[i]) / (2 * h)
    return num, den, dnum, dden


_compiled = None
_lock = threading.Lock()


def _functions():
    """``(coefficients, normal_equations)``: compiled (numba, cached beside the step's;
    the filter's closed form and its matrix exponential compiled from
    :mod:`simpro_mj.identification.identify`'s own source), or interpreted without numba."""
    global _compiled
    from simpro_mj.plant.kernels import kernel_choice

    if kernel_choice() != "numba":
        return coefficients, normal_equations
    with _lock:
        if _compiled is None:
            from simpro_mj.sim.numba_cache import jit
            from simpro_mj.sim.step import compiled

            folder = compiled().cache_folder + "-fit"
            expm = jit(folder)(_clone(identify._expm3, {}))
            zoh = jit(folder)(_clone(zoh_velocity_filter, {"_expm3": expm}))
            coef = jit(folder)(_clone(coefficients, {"zoh_velocity_filter": zoh}))
            _compiled = (coef, jit(folder)(normal_equations))
        return _compiled


def _clone(f, bound: dict):
    """``f`` with the names in ``bound`` bound to other (compiled) functions."""
    glob = dict(f.__globals__)
    glob.update(bound)
    clone = pytypes.FunctionType(f.__code__, glob, f.__name__, f.__defaults__)
    clone.__qualname__, clone.__module__ = f.__qualname__, f.__module__
    return clone


def fit_sensitivity(u, qdot, dt: float, skip: int = 0) -> Fit:
    """Eq. (19) fitted to a record as :func:`~simpro_mj.identification.identify.fit_eq19`
    fits it (the same residual, start, bounds and fit %), by Levenberg-Marquardt on the
    exact Jacobian (module docstring)."""
    u = np.asarray(u, float) - 5.0
    v = np.ascontiguousarray(qdot, float)
    b0, a10, a00, d0 = _arx_guess(u, v, dt)
    if not (b0 > 0 and a10 > 0 and a00 > 0 and np.isfinite(b0 + a10 + a00)):
        b0, a10, a00, d0 = 100.0, 10.0, 300.0, float(np.mean(u))
    lo = np.array([1e-6, 0.0, 1e-6, -5.0])
    hi = np.array([np.inf, np.inf, np.inf, 5.0])
    th = np.clip(np.array([b0, a10, a00, d0]), lo, hi)
    coef, step_pass = _functions()
    jtj, jtr = np.zeros((4, 4)), np.zeros(4)

    def at(t):
        num, den, dnum, dden = coef(t[:3].copy(), dt, COEF_STEP)
        x = np.ascontiguousarray(u - t[3])
        return step_pass(num, den, dnum, dden, x, v, skip, jtj, jtr)

    cost = at(th)
    a, g = jtj.copy(), jtr.copy()
    lam = 1e-3
    for _ in range(MAX_ITER):
        damp = np.diag(np.maximum(np.diag(a), 1e-300))
        improved = False
        while lam < 1e16:
            try:
                step = np.linalg.solve(a + lam * damp, -g)
            except np.linalg.LinAlgError:
                lam *= LAM_UP
                continue
            tn = np.clip(th + step, lo, hi)
            cn = at(tn)
            if math.isfinite(cn) and cn < cost:
                lam = max(lam * LAM_DOWN, 1e-12)
                improved = True
                break
            lam *= LAM_UP
        if not improved:
            break
        done = cost - cn <= FTOL * cn
        th, cost, a, g = tn, cn, jtj.copy(), jtr.copy()
        if done:
            break
    b, a1, a0, d = th
    vv = v[skip:] - v[skip:].mean()
    fit = 100.0 * (1.0 - math.sqrt(2.0 * cost) / max(float(np.linalg.norm(vv)), 1e-300))
    return Fit(float(b), float(a1), float(a0), float(d), float(fit))
