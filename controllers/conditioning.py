"""Conditioning of a vehicle's motion signals before a cueing law: bias out, vibration out.

A real feed is not a simulation's: an accelerometer reads a slowly drifting
bias (a vertical force averaging 9.6 m/s^2 instead of g), and the car's
engine, tyres and road add vibration far above anything a motion platform
of 1-2 Hz bandwidth can play. Fed to a cueing law as they are, the bias
reads as a sustained force (the platform tilts or sinks to cue it and drifts
there) and the vibration spends stroke and valve effort for nothing.

Per channel ``x`` (the three specific forces, the three angular rates), with
``x0`` its value at rest (``g`` on ``fz``, 0 elsewhere)::

    y = x0 + L(s) H(s) (x - x0)

    H(s) = tau s / (tau s + 1)                        slow bias removal, corner 1 / (2 pi tau)
    L(s) = wc^2 / (s^2 + sqrt(2) wc s + wc^2)          vibration filter, 2nd-order Butterworth

``tau`` (default :data:`BIAS_TAU_S`, 10 s: a corner of 0.016 Hz) removes a
constant bias to 1/e in ``tau`` and to 1 % in ``4.6 tau``; it also washes out
a force held longer than that (a very long banked curve), which a 3-DOF
platform cannot hold anyway (its tilt coordination is limited to a few
degrees). ``wc = 2 pi fc`` with ``fc`` default :data:`VIBRATION_HZ` (10 Hz:
-3 dB there, -19 dB at 30 Hz, unity up to 2 Hz within 0.1 %). Both are
discretised with Tustin at the cueing period (:class:`controllers.filters.DiscreteFilter`):
at 10 ms the 10 Hz corner sits at 9.7 Hz. Either stage is left out with
``tau = 0`` or ``fc = 0``.

The same conditioner runs sample by sample (:meth:`InputConditioner.step`,
a live session) or over a whole record (:meth:`InputConditioner.run`, an
offline file); both give the same numbers.
"""

from __future__ import annotations

import math

import numpy as np

from controllers.filters import DiscreteFilter
from controllers.frames import GRAVITY

#: Default time constant of the bias removal (s).
BIAS_TAU_S = 10.0
#: Default corner of the vibration filter (Hz).
VIBRATION_HZ = 10.0
_REST = (0.0, 0.0, GRAVITY, 0.0, 0.0, 0.0)


class InputConditioner:
    """Bias removal and vibration filtering of ``f`` (3,) and ``w`` (3,) every ``dt``.

    Parameters
    ----------
    dt : float
        The sampling period (s): the cueing law's.
    bias_tau_s : float
        Time constant of the bias removal (s); 0 leaves it out.
    vibration_hz : float
        Corner of the vibration low-pass (Hz), below the Nyquist frequency; 0 leaves it out.
    """

    def __init__(self, dt: float, bias_tau_s: float = BIAS_TAU_S,
                 vibration_hz: float = VIBRATION_HZ):  # fmt: skip
        if not (math.isfinite(bias_tau_s) and bias_tau_s >= 0):
            raise ValueError(f"bias_tau_s={bias_tau_s!r}; allowed: >= 0 s (0: off)")
        nyquist = 0.5 / dt
        if not (math.isfinite(vibration_hz) and 0 <= vibration_hz < nyquist):
            raise ValueError(
                f"vibration_hz={vibration_hz!r}; allowed: 0 (off) or below {nyquist:g} Hz"
            )
        self.dt, self.bias_tau_s, self.vibration_hz = dt, float(bias_tau_s), float(vibration_hz)
        self._stages = []
        for _ in range(6):
            chain = []
            if bias_tau_s > 0:
                chain.append(DiscreteFilter([bias_tau_s, 0.0], [bias_tau_s, 1.0], dt))
            if vibration_hz > 0:
                wc = 2.0 * math.pi * vibration_hz
                chain.append(DiscreteFilter([wc * wc], [1.0, math.sqrt(2.0) * wc, wc * wc], dt))
            self._stages.append(chain)

    def step(self, f, w) -> tuple[tuple, tuple]:
        """One sample: the conditioned ``(f, w)``."""
        out = []
        for x, x0, chain in zip((*f, *w), _REST, self._stages, strict=True):
            d = float(x) - x0
            for flt in chain:
                d = flt.step(d)
            out.append(x0 + d)
        return tuple(out[:3]), tuple(out[3:])

    def run(self, f: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A record ``f``, ``w`` (n, 3) sampled every ``dt``, from the current state."""
        x = np.column_stack([np.asarray(f, float), np.asarray(w, float)])
        out = np.empty_like(x)
        for j, (x0, chain) in enumerate(zip(_REST, self._stages, strict=True)):
            d = x[:, j] - x0
            for flt in chain:
                d = flt.run(d)
            out[:, j] = x0 + d
        return out[:, :3], out[:, 3:]
