"""Brent's method without scipy.optimize: SciPy's steps, SciPy's bits.

:func:`simpro_mj.core.roots.brentq` replaces ``scipy.optimize.brentq`` in the valves'
static equilibrium (solved before every run) so that a run need not import
``scipy.optimize``. Both do IEEE double arithmetic in the same order, so on the same
function and bracket they return the same float, bit for bit: checked on the
equilibrium's own functions (its whole solve, all three legs, holding forces from
the cylinder's pull to its push) and on functions that exercise the secant, the
inverse quadratic and the bisection steps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import optimize

from simpro_mj.core.roots import RTOL_MIN, brentq
from simpro_mj.plant.pneumatics.nonlinear import NonlinearActuators

CASES = [
    (lambda x: x**3 - 2 * x - 5, 2.0, 3.0),  # Newton's cubic: quadratic steps
    (lambda x: math.cos(x) - x, 0.0, 1.0),
    (lambda x: math.exp(x) - 1e6, 0.0, 30.0),  # flat then steep
    (lambda x: (x - 0.3) ** 9, -1.0, 2.0),  # a root of order 9: slow, bisections
    (lambda x: math.atan(50 * (x - 0.7)), -3.0, 1.0),
    (lambda x: x - 1e-300, -1.0, 1.0),
    (lambda x: 1.0 if x > 0.123 else -1.0, 0.0, 1.0),  # a jump: bisection to the tolerance
]


@pytest.mark.parametrize("k", range(len(CASES)))
@pytest.mark.parametrize("xtol, rtol", [(2e-12, RTOL_MIN), (1e-7, 1e-14), (1e-3, 1e-3)])
def test_the_same_root_as_scipy_bit_for_bit(k, xtol, rtol):
    f, a, b = CASES[k]
    ours = brentq(f, a, b, xtol=xtol, rtol=rtol, maxiter=500)
    assert ours == optimize.brentq(f, a, b, xtol=xtol, rtol=rtol, maxiter=500)


@pytest.mark.parametrize("k", range(len(CASES)))
def test_the_bracket_reversed_gives_scipys_root_too(k):
    f, a, b = CASES[k]
    assert brentq(f, b, a, maxiter=500) == optimize.brentq(f, b, a, maxiter=500)


def test_the_valves_equilibrium_is_scipys_bit_for_bit(monkeypatch):
    """The whole static solve, nested roots included, with each solver in turn."""
    import simpro_mj.plant.pneumatics.nonlinear as nonlinear

    act = NonlinearActuators()
    P = act.params
    reach = P.p_supply * P.area_cap  # beyond every leg's range: the saturated spool too
    forces = [np.zeros(3), np.array([-0.3, 0.1, 0.6]) * reach, np.array([-2.0, 0.02, 2.0]) * reach]
    for force in forces:
        ours = act.equilibrium(force)
        monkeypatch.setattr(nonlinear, "brentq", optimize.brentq)
        theirs = act.equilibrium(force)
        monkeypatch.undo()
        for x, y in zip(ours, theirs, strict=True):
            assert x.tobytes() == y.tobytes()


def test_an_end_that_is_a_root_is_returned():
    assert brentq(lambda x: x - 1.0, 1.0, 4.0) == 1.0
    assert brentq(lambda x: x - 4.0, 1.0, 4.0) == 4.0


def test_bad_brackets_and_tolerances_are_refused():
    with pytest.raises(ValueError, match="different signs"):
        brentq(lambda x: x * x + 1, -1.0, 1.0)
    with pytest.raises(ValueError, match="xtol"):
        brentq(lambda x: x, -1.0, 1.0, xtol=0.0)
    with pytest.raises(ValueError, match="rtol"):
        brentq(lambda x: x, -1.0, 1.0, rtol=1e-17)
    with pytest.raises(ValueError, match="NaN"):
        brentq(lambda x: math.nan if x > 0.5 else x - 0.7, 0.0, 1.0)
    with pytest.raises(RuntimeError, match="no convergence after 3 iterations"):
        brentq(lambda x: (x - 0.3) ** 9, -1.0, 2.0, maxiter=3)
