"""The outer loop with the inner loop as a delay (eqs. 21, 24-27): polynomials, the
stability limit (closed forms and any order), poles, steps and root loci.

See :mod:`controllers.analysis` for the model.
"""

from __future__ import annotations

import numpy as np


# --------------------------------------------------------------------------
# Outer loop with the inner loop as a delay (eqs. 21, 24-27)
# --------------------------------------------------------------------------
def schur_stable(coeffs, tol: float = 0.0) -> bool:
    """All roots of ``coeffs`` (highest power first) inside the unit circle, ``|z| < 1 - tol``.

    The poles of ``1 / P(z)``; a Jury (Schur-Cohn) table written out by hand
    gives the same verdict on every polynomial
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
    a = np.asarray(np.polymul([1.0, -1.0], np.r_[1.0, np.zeros(int(delay))]))
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

    cands: list[float] = []
    for z in (1.0, -1.0):
        bz = np.polyval(b, z)
        if bz != 0:
            cands.append(float(-np.polyval(a, z) / bz))
    w = np.linspace(1e-6, np.pi - 1e-6, 4001)
    im = gain(w).imag
    for i in np.nonzero(np.sign(im[:-1]) * np.sign(im[1:]) < 0)[0]:
        wi = brentq(lambda x: gain(x).imag, w[i], w[i + 1], xtol=1e-15)
        cands.append(gain(wi).real)
    cands = sorted(float(c) for c in cands if 0 < c < g_max and np.isfinite(c))
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
