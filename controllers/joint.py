"""Discrete joint controllers of the inner loops (1 ms), paper eqs. (28), (36)-(37).

Each leg runs the eq. (28) controller::

    C(s) = k_p (s + k_i)(s^2 + n1 s + n0) / (s (s^2 + c1 s + c0))

split into an explicit integrator and a biproper, stable remainder
(partial fractions)::

    C(s) = r0 / s + C_r(s),      r0 = k_p k_i n0 / c0

``C_r(s) = (k_p s^2 + m1 s + m0) / (s^2 + c1 s + c0)`` is realised in
controllable canonical form. Both parts are discretised with the same method
(``"tustin"``: bilinear, ``s = (2/T)(z - 1)/(z + 1)``; ``"zoh"``: exact
zero-order-hold equivalent). Both maps are linear in the system, so the
discretised sum equals the discretised controller. The integrator in discrete
form is ``x_I[k+1] = x_I[k] + r0 T e[k]`` with output ``x_I[k] + d_I e[k]``
(``d_I = r0 T / 2`` for Tustin, ``0`` for ZOH).

The valve command is ``v = u_offset + u`` (5 V = closed centre of the
MPYE-5 valve) saturated to ``[u_min, u_max]``. Anti-windup acts on the
integrator state only:

* ``"back_calculation"`` (default): ``x_I += (T / T_t)(v_sat - v)``, the
  tracking time ``T_t`` a parameter (default 0.05 s);
* ``"conditional"`` (conditional integration, or clamping): the integrator is
  held while the output is saturated and the error would drive it further
  into saturation;
* ``"none"``.

Back-calculation reads every sample's excess over a rail. When the command
carries more than its margin to the rails in fast parts (dither, the
quantised potentiometer times the controller's high-frequency gain
``k_p``), the excesses at the nearer rail outweigh those at the farther one
and the integrator is pulled towards the valve's centre, whatever the mean
error: the leg then moves far slower than designed. Conditional integration
only stops the integrator growing into a rail, so it has no such pull
(docs/paper-notes.md, joint anti-windup).

Per leg one step is ``[x[k+1]; u[k]] = [[A, B], [C, D]] [x[k]; e[k]]``
(``e = q_ref - q_meas``, m) plus the saturation and the anti-windup on the
integrator: :func:`controllers.step_functions.joint_step`,
the co-simulation's step (this class designs the matrices and runs the same
function for its :meth:`JointControllers.update`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Literal, get_args

import numpy as np

from .design import (
    ACTUATORS,
    DEFAULT_READING,
    VARIANTS,
    JointDesign,
    Plant,
    corrected_design,
    paper_plant,
    paper_scale,
    printed_design,
    redesigned_design,
)
from .step_functions import JC, JS, JX, joint_step

__all__ = [
    "JointControllers",
    "discretise",
    "expm",
    "split_integrator",
    "leg_state_space",
    "METHODS",
    "ANTI_WINDUP",
    "AntiWindup",
]

#: Discretisations of the joint controller.
Method = Literal["tustin", "zoh"]
METHODS: tuple[Method, ...] = get_args(Method)
#: Anti-windup of the joint integrators (class docstring).
AntiWindup = Literal["back_calculation", "conditional", "none"]
ANTI_WINDUP: tuple[AntiWindup, ...] = get_args(AntiWindup)
_NX = JX.LEN  # states per leg: two of C_r, one integrator (last)


def discretise(a, b, c, d, dt: float, method: str = "tustin"):
    """Discrete equivalent of a continuous state-space model.

    Parameters
    ----------
    a, b, c, d : array_like
        Continuous ``x' = a x + b u, y = c x + d u``.
    dt : float
        Sampling period (s).
    method : {"tustin", "zoh"}
        ``"tustin"``: ``Ad = (I - a T/2)^-1 (I + a T/2)``, ``Bd = (I - a T/2)^-1 b T``,
        ``Cd = c (I - a T/2)^-1``, ``Dd = d + c (I - a T/2)^-1 b T/2``.
        ``"zoh"``: ``[[Ad, Bd], [0, I]] = expm([[a, b], [0, 0]] T)``, ``Cd, Dd = c, d``.

    Notes
    -----
    Kept by hand, equal to python-control's :func:`control.c2d` to 1e-12 of each
    matrix (``tests/test_joint_control.py``): c2d (scipy's ``solve`` for the
    inverse) moves the 1 ms coefficients by 5e-14 relative, enough to move the
    shipped runs past the reference's 10 um in ``q1_m`` (step_roll, track_sines),
    and would add python-control's 1-2 s import to every run. The ZOH's
    exponential is :func:`expm` (the pre-run check discretises the plants with it
    before every run; ``scipy.linalg`` would add 0.2 s of imports).
    """
    a, b, c, d = (np.atleast_2d(np.asarray(m, dtype=float)) for m in (a, b, c, d))
    n = a.shape[0]
    if method == "tustin":
        eye = np.eye(n)
        inv = np.linalg.inv(eye - a * dt / 2.0)
        return inv @ (eye + a * dt / 2.0), inv @ b * dt, c @ inv, d + c @ inv @ b * dt / 2.0
    if method == "zoh":
        m = b.shape[1]
        big = np.zeros((n + m, n + m))
        big[:n, :n], big[:n, n:] = a, b
        e = expm(big * dt)
        return e[:n, :n], e[:n, n:], c.copy(), d.copy()
    raise ValueError(f"unknown discretisation method {method!r}; allowed: {list(METHODS)}")


def expm(m) -> np.ndarray:
    """``exp(m)`` of a small square matrix (a few states): scaling and squaring.

    ``m`` is scaled by ``2^-s`` to an infinity norm of at most 1/2, its Taylor
    polynomial to degree 14 is summed by Horner's rule,
    ``I + a (I + a/2 (I + ... (I + a/14)))``, and the result squared ``s`` times.
    The truncation, ``0.5^15 / 15! e^0.5 ~ 4e-17`` relative, is below float
    rounding. On the ZOH discretisations here (1-10 ms, norms up to about 15) it
    equals ``scipy.linalg.expm`` (Pade 13) to 1e-15 of the largest entry
    (``tests/test_joint_control.py``) without scipy's import; on a matrix of larger
    norm its squarings, more than scipy's, lose more of the last digits.
    """
    m = np.atleast_2d(np.asarray(m, dtype=float))
    norm = float(np.abs(m).sum(axis=1).max()) if m.size else 0.0
    s = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    a = m / 2.0**s
    eye = np.eye(m.shape[0])
    e = eye + a / 14.0
    for k in range(13, 0, -1):
        e = eye + (a @ e) / k
    for _ in range(s):
        e = e @ e
    return e


def split_integrator(design: JointDesign):
    """Partial fractions ``C(s) = r0 / s + (k_p s^2 + m1 s + m0) / (s^2 + c1 s + c0)``.

    Returns ``(r0, (kp, m1, m0))``.
    """
    r0 = design.kp * design.ki * design.n0 / design.c0
    num = design.num  # degree 3
    rest = np.polysub(num, r0 * np.array([1.0, design.c1, design.c0]))
    # rest(0) == 0 by construction: divide by s
    kp, m1, m0 = rest[0], rest[1], rest[2]
    return float(r0), (float(kp), float(m1), float(m0))


def leg_state_space(design: JointDesign, dt: float, method: str = "tustin"):
    """Discrete ``(A, B, C, D)`` of one leg's controller, states ``[x_r1, x_r2, x_I]``."""
    r0, (kp, m1, m0) = split_integrator(design)
    c1, c0 = design.c1, design.c0
    # C_r = kp + ((m1 - kp c1) s + (m0 - kp c0)) / (s^2 + c1 s + c0), controllable form
    ar = np.array([[0.0, 1.0], [-c0, -c1]])
    br = np.array([[0.0], [1.0]])
    cr = np.array([[m0 - kp * c0, m1 - kp * c1]])
    dr = np.array([[kp]])
    ad, bd, cd, dd = discretise(ar, br, cr, dr, dt, method)
    a = np.zeros((_NX, _NX))
    a[:2, :2] = ad
    a[2, 2] = 1.0
    b = np.vstack([bd, [[r0 * dt]]])
    c = np.hstack([cd, [[1.0]]])
    d = dd + (r0 * dt / 2.0 if method == "tustin" else 0.0)
    return a, b, c, d


class JointControllers:
    """The three discrete joint controllers (eq. 28), vectorised over the legs.

    Parameters
    ----------
    variant : {"corrected", "printed", "redesigned"}
        ``"printed"``: eqs. (36)-(37) verbatim (numerator ``s^2 + 7.726 s + a0``).
        ``"corrected"``: the numerator quadratic equals the plant's
        (27.72 for actuator 1, 7.276 for 2-3) so it cancels the plant poles.
        ``"redesigned"``: pole placement for ``zeta = 0.7, wn = 10 rad/s``
        (:func:`controllers.design.redesigned_design`; ``spec`` overrides).
    dt : float
        Sampling period, s (paper: 1 ms).
    method : {"tustin", "zoh"}
        Discretisation of the continuous controller.
    u_offset, u_min, u_max : float
        Valve command ``v = u_offset + u``, saturated to ``[u_min, u_max]`` V.
    anti_windup : {"back_calculation", "conditional", "none"}
    tracking_time : float
        Back-calculation time constant ``T_t`` (s).
    spec : mapping, optional
        ``zeta, wn, p1, p2`` for ``variant="redesigned"``.
    designs : sequence of 3 JointDesign, optional
        Explicit controllers per leg (overrides ``variant``).
    plants : sequence of 3 Plant, optional
        Plants (SI, m per V) used by the ``corrected``/``redesigned`` designs
        (default eqs. 34-35 in SI under ``reading``).
    reading : {"volts", "metres"}
        Units of eqs. (34)-(37) (:data:`controllers.design.READINGS`): Y in
        potentiometer volts (20 V/m, default) or in metres. Sets the SI gain of
        the ``printed`` controllers and the default design plants.
    dead_band : float or (3,) array_like
        Width (m) of the dead band of each leg's integrator
        (:func:`controllers.dead_band.dead_band`): the integrator takes
        ``e -+ w`` outside the band and holds inside it, while the rest of the
        controller sees the whole error. Default 0 (none).
    dead_band_release : float
        Once a leg's error has entered its band, the band holds its integrator
        until the error leaves ``dead_band_release`` bands (a hysteresis; >= 1,
        default 1: none).
    """

    def __init__(
        self,
        variant: str = "corrected",
        *,
        dt: float = 0.001,
        method: str = "tustin",
        u_offset: float = 5.0,
        u_min: float = 0.0,
        u_max: float = 10.0,
        anti_windup: str = "back_calculation",
        tracking_time: float = 0.05,
        spec: Mapping | None = None,
        designs=None,
        plants=None,
        reading: str = DEFAULT_READING,
        dead_band=0.0,
        dead_band_release: float = 1.0,
    ):
        paper_scale(reading)  # raises DesignError (a ValueError) naming the readings
        if variant not in VARIANTS:
            raise ValueError(f"unknown variant {variant!r}; allowed: {list(VARIANTS)}")
        if method not in METHODS:
            raise ValueError(f"unknown method {method!r}; allowed: {list(METHODS)}")
        if anti_windup not in ANTI_WINDUP:
            raise ValueError(f"unknown anti_windup {anti_windup!r}; allowed: {list(ANTI_WINDUP)}")
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        if not (np.isfinite(tracking_time) and tracking_time > 0):
            raise ValueError(f"tracking_time must be > 0 s, got {tracking_time!r}")
        if not (u_min < u_max):
            raise ValueError(f"need u_min < u_max, got {u_min} and {u_max}")
        if not (np.isfinite(dead_band_release) and dead_band_release >= 1.0):
            raise ValueError(f"dead_band_release must be >= 1, got {dead_band_release!r}")
        if spec is not None and variant != "redesigned":
            raise ValueError("spec is only used with variant='redesigned'")
        spec = dict(spec or {})
        unknown = set(spec) - {"zeta", "wn", "p1", "p2"}
        if unknown:
            raise ValueError(f"unknown spec keys {sorted(unknown)}; allowed: zeta, wn, p1, p2")
        self.variant = variant
        self.dt = float(dt)
        self.method = method
        self.u_offset, self.u_min, self.u_max = float(u_offset), float(u_min), float(u_max)
        self.anti_windup = anti_windup
        self.tracking_time = float(tracking_time)
        self.reading = reading
        db = np.broadcast_to(np.asarray(dead_band, dtype=float), (3,))
        if not (np.all(np.isfinite(db)) and np.all(db >= 0)):
            raise ValueError(f"dead_band must be 1 or 3 finite widths >= 0 m, got {dead_band!r}")
        if plants is None:
            plants = [paper_plant(a, reading) for a in ACTUATORS]
        plants = list(plants)
        if len(plants) != 3 or not all(isinstance(p, Plant) for p in plants):
            raise ValueError("plants must be a sequence of 3 Plant")
        if designs is None:
            designs = []
            for act, plant in zip(ACTUATORS, plants, strict=True):
                if variant == "printed":
                    designs.append(printed_design(act, reading))
                elif variant == "corrected":
                    designs.append(corrected_design(act, plant))
                else:
                    designs.append(redesigned_design(act, plant=plant, **spec))
        designs = list(designs)
        if len(designs) != 3 or not all(isinstance(d, JointDesign) for d in designs):
            raise ValueError("designs must be a sequence of 3 JointDesign")
        self.designs = tuple(designs)
        self.plants = tuple(plants)

        r0 = np.array([split_integrator(des)[0] for des in self.designs])
        self._int_gain = r0 * self.dt  # increment of x_I per unit error
        # the per-step function's constants (controllers.step_functions.joint_step): the
        # limits, the integrators' gains and dead bands, per leg [[A, B], [C, D]]
        blocks = []
        for des in self.designs:
            a, b, c, d = leg_state_space(des, self.dt, method)
            blocks.append(np.block([[a, b], [c, d]]))
        aw = ANTI_WINDUP.index(anti_windup)
        self.step_constants = JC.pack(
            off=u_offset, lo=u_min, hi=u_max, kind=aw, aw=self.dt / self.tracking_time,
            gain=self._int_gain, band=db, rel=dead_band_release, m=blocks,
        )  # fmt: skip
        self._x = np.zeros(JS.LEN)

    @property
    def integrator(self) -> np.ndarray:
        """The integrator state of each leg, volts (copy)."""
        return self._x[JS.x + JX.i : JS.x + 3 * JX.LEN : JX.LEN].copy()

    def reset(self) -> None:
        """Zero every state: the next command is ``u_offset`` for zero error."""
        self._x[:] = 0.0

    def update(self, q_ref, q_meas, u_ff=None) -> np.ndarray:
        """One 1 ms step: joint references and measurements (m, (3,)) -> valve volts (3,).

        ``u_ff`` ((3,) V, optional) is added to the controllers' outputs before
        the saturation (the leg velocity feed-forward,
        :mod:`controllers.velocity_feedforward`); the anti-windup sees the total.
        Returns a new array in ``[u_min, u_max]`` V. The arithmetic is
        :func:`controllers.step_functions.joint_step`, the co-simulation's step.
        """
        e = np.broadcast_to(np.asarray(q_ref, float) - np.asarray(q_meas, float), (3,))
        f = np.broadcast_to(np.asarray(0.0 if u_ff is None else u_ff, float), (3,))
        v = np.zeros(3)
        (e0, e1, e2), (f0, f1, f2) = e.tolist(), f.tolist()
        joint_step(self._x, self.step_constants, e0, e1, e2, f0, f1, f2, v)
        return v
