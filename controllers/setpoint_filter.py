"""The set-point filter of Fig. 13, between the task-space loop and the joint loops.

The outer loop (eq. 22) updates the joint set-points q_d every T = 60 ms, so
the joint loops see a staircase. The joint controller of eqs. (36)-(37) is
biproper: its high-frequency gain is k_p (5.3 kV/m for actuator 1 under the
volts reading), so each 60 ms step of q_d reaches the valve at once — a 5 mm
step of leg 1 (the first outer update of a 3 deg pitch step at K K_I = 3) asks
for 26 V, five times the valve's half range. Fig. 13 draws a "Filter" on this
path; the paper does not print it. Kinds (:data:`KINDS`):

* ``"none"``: q_ref = q_d (the staircase);
* ``"first_order"``: ``1 / (tau s + 1)`` (``tau`` = ``time``), discretised
  exactly (ZOH) at the joint rate; the kick of a step falls to
  ``k_p Delta q dt / tau``;
* ``"ramp"`` (default, ``time`` = T): the mean of q_d over the last ``time``
  (a moving average of ``n = time / dt`` samples). With ``time`` = T the
  staircase becomes the linear interpolation between outer samples: no step
  at all, linear phase, a delay of T/2 on average;
* ``"zero_cancel"``: ``k_i / (s + k_i)`` with eq. (36)-(37)'s ``k_i = 3.03``:
  the reading of Fig. 13's filter as the classic prefilter that cancels the
  closed-loop zero ``(s + k_i)`` of eq. (29) (a 19 % overshoot of the joint
  loop alone). It leaves the joint loop with its poles only (dominant pair
  near -6.7 rad/s), which is slow for the outer loop: kept for comparison.

Which one by default, and why, is in ``docs/paper-notes.md`` (set-point
filter); :func:`filter_state_space` gives the discrete filter for the
analysis (:mod:`controllers.analysis`).

Only numpy (and scipy for the ZOH) are imported here.
"""

from __future__ import annotations

import math
from typing import Literal, get_args

import numpy as np

from .step_functions import FC, FS, filter_step

Kind = Literal["none", "first_order", "ramp", "zero_cancel"]
KINDS: tuple[Kind, ...] = get_args(Kind)
#: k_i of eqs. (36)-(37) (rad/s): the zero of eq. (29) that "zero_cancel" cancels.
PAPER_KI = 3.03


def leg_times(time) -> list[float]:
    """``time`` (s) as one value per leg: a number is every leg's, or 3 numbers.

    Raises
    ------
    ValueError
        Not one or three positive finite numbers.
    """
    times = [time] * 3 if np.ndim(time) == 0 else list(time)
    if len(times) != 3 or not all(math.isfinite(float(t)) and float(t) > 0 for t in times):
        raise ValueError(f"time must be 1 or 3 positive numbers of seconds, got {time!r}")
    return [float(t) for t in times]


def _first_order(tau: float, dt: float) -> tuple[float, float]:
    """Exact ZOH of ``1 / (tau s + 1)``: ``y+ = a y + (1 - a) u``."""
    a = math.exp(-dt / tau)
    return a, 1.0 - a


def filter_state_space(kind: str, dt: float, time: float):
    """Discrete ``(A, B, C, D)`` of one leg's filter at ``dt`` (for the analysis);
    the same arithmetic as :class:`SetpointFilter` (tested)."""
    if kind == "none":
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.ones((1, 1))
    if kind in ("first_order", "zero_cancel"):
        tau = time if kind == "first_order" else 1.0 / PAPER_KI
        pole, gain = _first_order(tau, dt)
        # y[k] is the output used at step k: y[k] = a y[k-1] + b u[k] -> state y[k-1]
        return np.array([[pole]]), np.array([[gain]]), np.array([[pole]]), np.array([[gain]])
    if kind == "ramp":
        n = max(1, int(round(time / dt)))
        if n == 1:
            return filter_state_space("none", dt, time)
        # state: the last n - 1 inputs (shift register), y = (u + sum(state)) / n
        a = np.eye(n - 1, k=-1)
        b = np.zeros((n - 1, 1))
        b[0, 0] = 1.0
        c = np.full((1, n - 1), 1.0 / n)
        return a, b, c, np.array([[1.0 / n]])
    raise ValueError(f"unknown set-point filter {kind!r}; allowed: {list(KINDS)}")


class SetpointFilter:
    """Three legs' set-point filter, one update per joint-loop step.

    Parameters
    ----------
    kind : {"none", "first_order", "ramp", "zero_cancel"}
    dt : float
        Joint-loop period (s).
    time : float or sequence of 3 floats
        Length of the ``"ramp"`` average, or ``tau`` of ``"first_order"`` (s);
        one value for all legs or one per leg (:func:`leg_times`).
    """

    def __init__(self, kind: str = "ramp", *, dt: float, time):
        if kind not in KINDS:
            raise ValueError(f"unknown set-point filter {kind!r}; allowed: {list(KINDS)}")
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        times = leg_times(time)
        self.kind = kind
        self.dt = float(dt)
        self.n = [max(1, int(round(t / dt))) for t in times]
        self._ab = [_first_order(t if kind == "first_order" else 1.0 / PAPER_KI, dt) for t in times]
        # the per-step function's arrays (controllers.step_functions.filter_step): the
        # constants, the state (y, running sums, ring heads) and the ramp's ring
        code = {"none": 0.0, "first_order": 1.0, "zero_cancel": 1.0, "ramp": 2.0}[kind]
        a, b = np.transpose(self._ab)
        self.step_constants = FC.pack(kind=code, n=self.n, a=a, b=b)
        self.step_state = np.zeros(FS.LEN)
        self.ring = np.zeros((3, max(self.n)))
        self._ready = False

    def reset(self, q) -> None:
        """At rest at ``q`` (3 floats): the filter's output and memory are ``q``."""
        q = [float(x) for x in q]
        fs = self.step_state
        fs[FS.y : FS.y + 3] = q
        fs[FS.sum : FS.sum + 3] = [x * n for x, n in zip(q, self.n, strict=True)]
        fs[FS.head : FS.head + 3] = 0.0
        for i, n in enumerate(self.n):
            self.ring[i, :n] = q[i]
        self._ready = True

    def update(self, q_d) -> list:
        """One joint-loop step: the set-points q_d (3 floats) -> filtered q_ref.

        The arithmetic is :func:`controllers.step_functions.filter_step`.
        """
        if not self._ready:
            self.reset(q_d)
        q0, q1, q2 = (float(v) for v in q_d[:3])
        out = np.zeros(3)
        ring = self.ring.reshape(-1)  # a view: the function takes it flat
        filter_step(self.step_constants, q0, q1, q2, self.step_state, ring, out)
        return out.tolist()
