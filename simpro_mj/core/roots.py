"""A bracketed scalar root by Brent's method, without importing ``scipy.optimize``.

Every run solves the valves' static equilibrium before it starts (a few hundred
scalar roots, :meth:`simpro_mj.plant.pneumatics.nonlinear.NonlinearActuators.equilibrium`),
and importing ``scipy.optimize`` for them costs about half a second of CPU per
process (``python -X importtime``: it loads ``scipy.sparse``, ``scipy.special``
and the linear-programming solvers too). :func:`brentq` takes the same steps as
``scipy.optimize.brentq`` (Brent 1973, *Algorithms for Minimization without
Derivatives*, ch. 4, in the form of SciPy's C solver): inverse quadratic
extrapolation or secant interpolation while the step shrinks fast enough,
bisection otherwise, stopping when half the bracket is below
``(xtol + rtol |x|) / 2``. In IEEE double arithmetic, with the operations in
the same order, it returns the same bits as SciPy's (tests/test_roots.py checks
that against SciPy on the equilibrium's own functions and on others).
"""

from __future__ import annotations

import math
from collections.abc import Callable

#: the smallest relative tolerance accepted (four units in the last place)
RTOL_MIN = 4 * 2.220446049250313e-16


def brentq(
    f: Callable[..., float],
    a: float,
    b: float,
    args: tuple = (),
    xtol: float = 2e-12,
    rtol: float = RTOL_MIN,
    maxiter: int = 100,
) -> float:
    """A root of ``f(x, *args)`` in the bracket ``[a, b]``.

    Parameters
    ----------
    f : callable(float, *args) -> float
        Continuous on ``[a, b]``, with ``f(a)`` and ``f(b)`` of opposite signs.
    a, b : float
        The bracket's ends.
    args : tuple
        Further arguments of ``f``.
    xtol, rtol : float
        The root is returned when it is known within ``xtol + rtol |x|``
        (``xtol > 0``, ``rtol >= 4 eps``).
    maxiter : int
        The most iterations (each one evaluation of ``f``).

    Returns
    -------
    float
        The root.

    Raises
    ------
    ValueError
        A tolerance out of range, ``f(a)`` and ``f(b)`` of the same sign, or
        ``f`` not a number.
    RuntimeError
        No convergence within ``maxiter`` iterations.
    """
    if not xtol > 0:
        raise ValueError(f"xtol must be > 0, got {xtol}")
    if not rtol >= RTOL_MIN:
        raise ValueError(f"rtol must be >= {RTOL_MIN}, got {rtol}")

    def value(x: float) -> float:
        y = float(f(x, *args))
        if math.isnan(y):
            raise ValueError(f"the function value at x={x} is NaN; no root can be bracketed")
        return y

    # x: the best estimate; xp, fp: the previous one; xb, fb: the bracket's other
    # end (f(x) and f(xb) of opposite signs); d: the last step, e: the one before
    x, xp = float(b), float(a)
    fp, fx = value(xp), value(x)
    if fp * fx > 0:
        raise ValueError("f(a) and f(b) must have different signs")
    if fp == 0:
        return xp
    if fx == 0:
        return x
    xb = fb = d = e = 0.0
    for _ in range(maxiter):
        if fp * fx < 0:  # the root lies between the last two: restart the bracket
            xb, fb = xp, fp
            e = d = x - xp
        if abs(fb) < abs(fx):  # keep the smaller |f| as the estimate
            xp, x, xb = x, xb, x
            fp, fx, fb = fx, fb, fx
        tol = (xtol + rtol * abs(x)) / 2
        half = (xb - x) / 2
        if fx == 0 or abs(half) < tol:
            return x
        if abs(e) > tol and abs(fx) < abs(fp):
            if xp == xb:  # two points: the secant
                trial = -fx * (x - xp) / (fx - fp)
            else:  # three: inverse quadratic extrapolation
                slope_p = (fp - fx) / (xp - x)
                slope_b = (fb - fx) / (xb - x)
                trial = -fx * (fb * slope_b - fp * slope_p) / (slope_b * slope_p * (fb - fp))
            if 2 * abs(trial) < min(abs(e), 3 * abs(half) - tol):
                e, d = d, trial  # accepted: it shrinks faster than bisection
            else:
                e = d = half
        else:
            e = d = half
        xp, fp = x, fx
        x += d if abs(d) > tol else (tol if half > 0 else -tol)
        fx = value(x)
    raise RuntimeError(f"brentq: no convergence after {maxiter} iterations, value is {x}")
