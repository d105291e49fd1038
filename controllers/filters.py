"""Discrete SISO filters designed in continuous time (motion cueing, perception).

A filter is given as a continuous transfer function ``num(s) / den(s)``
(coefficients in descending powers of s, as in ``scipy.signal``) and
discretised with :func:`scipy.signal.cont2discrete` (Tustin by default: it
maps the stable left half-plane into the unit disc, keeps the DC gain exactly
and needs no pre-warping at the cut-offs used here, all below 1 % of the
Nyquist frequency of a 10 ms period). The difference equation is
``scipy.signal.lfilter``'s direct form II transposed, run either sample by
sample (:meth:`DiscreteFilter.step`, what a rig's control computer does) or
over an array (:meth:`DiscreteFilter.run`); both give the same numbers.
"""

from __future__ import annotations

import math

import numpy as np


def _signal():
    """scipy.signal on first use: its 0.6-1.6 s import would otherwise delay every
    command's one-line refusal (a scenario's validation imports the washout)."""
    from scipy import signal

    return signal


class FilterError(ValueError):
    """A filter specification that cannot be discretised (non-finite, improper, bad period)."""


class DiscreteFilter:
    """A continuous SISO transfer function, discretised, with its state.

    Parameters
    ----------
    num, den : sequence of float
        Continuous transfer function ``num(s) / den(s)``, descending powers of s.
        Must be proper (``len(num) <= len(den)``) with ``den[0] != 0``.
    dt : float
        Sampling period (s), > 0.
    method : str
        :func:`scipy.signal.cont2discrete` method, default ``"bilinear"`` (Tustin).

    Attributes
    ----------
    b, a : ndarray
        Discrete numerator and denominator (``a[0] == 1``).
    """

    def __init__(self, num, den, dt: float, *, method: str = "bilinear"):
        num = np.atleast_1d(np.asarray(num, dtype=float))
        den = np.atleast_1d(np.asarray(den, dtype=float))
        if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
            raise FilterError(f"filter coefficients must be finite, got {num} / {den}")
        if den[0] == 0 or num.size > den.size:
            raise FilterError(f"filter {num} / {den} is improper or has den[0] = 0")
        if not (math.isfinite(dt) and dt > 0):
            raise FilterError(f"filter period must be > 0 s, got {dt!r}")
        b, a, _ = _signal().cont2discrete((num, den), dt, method=method)
        b = np.ravel(b)
        a = np.ravel(a)
        n = max(a.size, b.size)
        b = np.concatenate([np.zeros(n - b.size), b])  # pad to the order of a
        self.b = b / a[0]
        self.a = a / a[0]
        self.dt = float(dt)
        self.num, self.den = num, den
        self._bl = self.b.tolist()
        self._al = self.a.tolist()
        self._z = [0.0] * (n - 1)

    @property
    def dc_gain(self) -> float:
        """Gain at s = 0 (``num[-1] / den[-1]``; inf for a pole at the origin)."""
        return float(self.num[-1] / self.den[-1]) if self.den[-1] != 0 else math.inf

    def reset(self, u0: float = 0.0) -> None:
        """Set the state to the steady state under the constant input ``u0``.

        ``u0 = 0`` is rest. A non-zero ``u0`` needs a finite DC gain (no
        integrator): the state is :func:`scipy.signal.lfilter_zi` scaled by ``u0``.
        """
        if u0 == 0.0 or len(self._z) == 0:
            self._z = [0.0] * len(self._z)
            return
        self._z = (_signal().lfilter_zi(self.b, self.a) * float(u0)).tolist()

    def step(self, u: float) -> float:
        """Advance one sample with input ``u``; returns the output (direct form II transposed)."""
        b, a, z = self._bl, self._al, self._z
        y = b[0] * u + (z[0] if z else 0.0)
        n = len(z)
        for i in range(n):
            nxt = z[i + 1] if i + 1 < n else 0.0
            z[i] = b[i + 1] * u + nxt - a[i + 1] * y
        return y

    def run(self, u) -> np.ndarray:
        """Filter an array (n,) from the current state; the state moves to its end."""
        u = np.asarray(u, dtype=float)
        if not self._z:
            return self.b[0] * u
        y, zf = _signal().lfilter(self.b, self.a, u, zi=np.asarray(self._z))
        self._z = zf.tolist()
        return y
