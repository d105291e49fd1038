"""Valve dither: a small square wave added to each valve's command.

A pneumatic cylinder's seals hold the piston until the net force passes their
breakaway force, then let go at the lower running force (Stribeck): a position
loop whose valve ramps the pressure while the leg sticks hunts in a stick-slip
cycle (``docs/paper-notes.md``, controllers for the heavy cabin). Dither, a
periodic command well above the loop's bandwidth and below the spool's, keeps
the chamber pressures swinging by a few tens of newtons around what the loop
asks, so that the seals break away at a smaller error and the loop sees
friction closer to its mean, running value (Armstrong-Hélouvry, Dupont &
Canudas de Wit, *Automatica* 30(7), 1994, section 6.1: dither as a friction
compensation). The motion it makes is the force ripple over the moving mass at
the dither frequency, microns here.

The signal is ``+A`` for the first half of each period and ``-A`` for the
second, the same on every leg; it is added to the joint controllers' output
before the valves' saturation, like the velocity feed-forward.
"""

from __future__ import annotations

import numpy as np


def dither_signal(n: int, dt: float, amplitude_v: float, period_s: float) -> np.ndarray:
    """The dither of ``n`` steps of ``dt`` s on the three valves, ``(n, 3)`` volts.

    Parameters
    ----------
    n : int
        Number of samples (steps).
    dt : float
        The step, s.
    amplitude_v : float
        Half the square wave's swing, V (``0``: zeros).
    period_s : float
        The square wave's period, s: an even number of steps, so that both
        halves last equally long.

    Raises
    ------
    ValueError
        A period that is not an even, positive number of steps.
    """
    steps = period_s / dt
    half = int(round(steps / 2.0))
    if half < 1 or abs(2 * half - steps) > 1e-9 * steps:
        raise ValueError(f"the dither period {period_s:g} s is not an even number of {dt:g} s")
    k = np.arange(n)
    wave = np.where((k // half) % 2 == 0, amplitude_v, -amplitude_v)
    return np.repeat(wave[:, None], 3, axis=1).astype(float)
