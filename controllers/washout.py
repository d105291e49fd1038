"""Classical washout motion cueing for the roll-pitch-heave platform.

The classical algorithm of Conrad & Schmidt (1970) and Reid & Nahon (1985,
UTIAS Report 296, "Flight simulation motion-base drive algorithms: Part 1"),
cut down to the three degrees of freedom SIMPRO has. Input: the vehicle's
specific force ``f`` and angular velocity ``w`` at the driver's head, vehicle
frame V (ISO 8855, :mod:`controllers.frames`). Output: the platform pose
set-point ``(roll, pitch, h)`` in the base frame B, inside the workspace.

Channels (all in V, ISO angles; every number a field of :class:`WashoutParams`)
-------------------------------------------------------------------------------
Heave (translational channel, z)::

    z(s) = k_z (f_z - g) * s / ((s^2 + 2 zeta_h w_h s + w_h^2)(s + w_hb))

the third-order high-pass ``s^2/(s^2 + 2 zeta w s + w^2) * s/(s + w_b)`` of
Reid & Nahon times the double integration ``1/s^2``, written as one stable
transfer function (no free integrator drifts): a step in ``f_z`` moves the
platform up and back to neutral.

Tilt coordination (surge and sway, which SIMPRO cannot translate)::

    pitch_t = asin(-k_x LP(f_x) / g),   roll_t = asin(k_y LP(f_y) / g)
    LP(s) = w_t^2 / (s^2 + 2 zeta_t w_t s + w_t^2)

then limited to ``tilt_limit`` and by a second-order rate limit: the tilt rate
to ``tilt_rate_limit`` (near the canals' roll/pitch thresholds of 3.0/3.6
deg/s, so the rotation that produces the cue is hardly perceived; Groen & Bles
2004, Reid & Nahon 1985) and the tilt acceleration to ``tilt_accel_limit``
(commercial cueing's tilt-acceleration limit: the rate ramps instead of
jumping), approaching the target no faster than it can stop at it
(``rate <= sqrt(2 accel |target - tilt|)``). At rest on a platform tilted by
``pitch_t`` the head feels ``f_x = -g sin(pitch_t) = k_x f_x,vehicle``: a
sustained acceleration ``a`` settles at ``asin(k a / g)``.

Head offset: the head is ``head_height`` (0.75 m) above the roll axis and
``head_height_pitch`` (1.21 m, measured) above the pitch motion's, so an
angular acceleration ``a''`` away from neutral throws it along the cue's axis
the wrong way, ``f = h a'' - g a`` (ISO pitch ``a``; roll alike): a pure tilt
first pushes the driver against the cue it builds. The outward tilt
acceleration is therefore also limited to ``(jolt_limit + g |a|) / h``, each axis
with its ``h``, so the
head's wrong-way specific force stays below ``jolt_limit`` (the otoliths'
0.17 m/s^2 threshold by default): the onset starts gently and speeds up as the
tilt's own cue grows.

Rotation (roll and pitch rates)::

    angle_r(s) = k_w w(s) / s * HP(s),  HP = s/(s + w_r) (order 1) or
                 s^2/(s^2 + 2 zeta_r w_r s + w_r^2) (order 2)

The sum ``tilt + angle_r`` and the heave, mapped to B, are saturated smoothly
into :func:`controllers.workspace.inscribed_box` by
:func:`controllers.workspace.soft_limit` (identity up to ``knee`` of the
half-range, then a tanh approach that never reaches the boundary).

Discrete time: every filter is designed in continuous time and discretised
by Tustin at ``period`` (:class:`controllers.filters.DiscreteFilter`); the
rate limit acts per period. The default period, 10 ms, is six times faster
than the outer loop's 60 ms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .filters import DiscreteFilter
from .frames import GRAVITY
from .geometry import HEAD_HEIGHT_PITCH, HEAD_HEIGHT_ROLL, PlatformGeometry, nominal_geometry
from .law_params import LawParams, ranged
from .workspace import inscribed_box, soft_limit


class WashoutParamError(ValueError):
    """A washout parameter out of its allowed range; the message names the field."""


@dataclass(frozen=True)
class WashoutParams(LawParams):
    """Parameters of :class:`ClassicalWashout`, SI (rad, s, m, rad/s).

    Defaults and where they come from (docs/paper-notes.md, "Motion cueing"):

    Attributes
    ----------
    period : float
        Cueing sample period (s), 0.01; an integer multiple of the 1 ms physics step,
        faster than the 60 ms outer loop.
    gain_x, gain_y : float
        Scale of the longitudinal / lateral specific force, 0.5: half scale, the
        middle of the 0.3-0.7 range of classical tuning (Reid & Nahon 1985 scale
        the inputs before the filters); our choice, swept by ``cue_sweep.yaml``.
    gain_z : float
        Scale of the vertical specific force, 0.5 (same reasoning).
    gain_rot : float
        Scale of the roll and pitch rates, 1.0 (a car's body roll and pitch are
        small: played at full scale).
    tilt_omega, tilt_zeta : float
        Tilt low-pass ``w_t`` (rad/s) and damping: 5 rad/s, 1 (critically damped
        second order as in Reid & Nahon 1985). Above the bandwidth the 3 deg/s
        rate limit allows, so the limiter, not the filter, shapes the onset.
    tilt_rate_limit : float
        3 deg/s (rad/s): the tilt rate kept near the canals' threshold (Groen &
        Bles 2004 measured 3 deg/s as the tilt-coordination limit).
    tilt_accel_limit : float
        Tilt acceleration limit (rad/s^2), the second-order rate limit.
    head_height, head_height_pitch : float
        The head above the roll axis (m), 0.75 (the MJCF ``head`` site), and above
        the pitch motion's axis, 1.21 (measured): :data:`controllers.geometry.HEAD_HEIGHT_ROLL`
        and ``HEAD_HEIGHT_PITCH``, as the MPC law's; 0 turns the axis' jolt limit off.
    jolt_limit : float
        Largest wrong-way specific force (m/s^2) the outward tilt acceleration may
        throw the head with, 0.17 (the x/y otolith threshold).
    tilt_limit : float
        10 deg (rad): largest tilt, inside the workspace box (about 9-12 deg,
        :func:`controllers.workspace.inscribed_box`), so it acts before the soft limit.
    heave_omega, heave_zeta, heave_omega_b : float
        Heave high-pass ``w_h`` = 2.5 rad/s, ``zeta_h`` = 1, ``w_hb`` = 0.5 rad/s
        (third order, Reid & Nahon 1985's structure). A 1 m/s^2 step then peaks at
        about ``k_z / w_h^2`` = 80 mm before returning; our choice for +-52 mm.
    rot_order : int
        Order of the rotational high-pass, 1 (Reid & Nahon 1985) or 2.
    rot_omega, rot_zeta : float
        Its break frequency, 0.5 rad/s (passes a car's roll at 0.1-1 Hz), and the
        damping used when ``rot_order`` is 2 (1.0).
    heave_fraction : float
        Share of the single-axis heave range given to heave, 0.25 (+-52 mm); the
        rest of the workspace goes to the angles (:func:`inscribed_box`).
    stroke_margin : float
        Stroke margin (m) the box keeps from the end stops, 0.01.
    knee : float
        :func:`soft_limit` knee, 0.8 of the half-range.
    """

    _LABEL = "washout"
    _ERROR = WashoutParamError

    period: float = ranged(0.01, lambda v: 0 < v <= 0.1, "> 0 and <= 0.1 s")
    gain_x: float = ranged(0.5, lambda v: 0 <= v <= 2, "0..2")
    gain_y: float = ranged(0.5, lambda v: 0 <= v <= 2, "0..2")
    gain_z: float = ranged(0.5, lambda v: 0 <= v <= 2, "0..2")
    gain_rot: float = ranged(1.0, lambda v: 0 <= v <= 2, "0..2")
    tilt_omega: float = ranged(5.0, lambda v: v > 0, "> 0 rad/s")
    tilt_zeta: float = ranged(1.0, lambda v: v > 0, "> 0")
    tilt_rate_limit: float = ranged(math.radians(3.0), lambda v: v > 0, "> 0 rad/s")
    tilt_limit: float = ranged(
        math.radians(10.0), lambda v: 0 < v < math.pi / 2, "in (0, pi/2) rad"
    )
    tilt_accel_limit: float = ranged(math.radians(30.0), lambda v: v > 0, "> 0 rad/s^2")
    head_height: float = ranged(HEAD_HEIGHT_ROLL, lambda v: 0 <= v <= 2, "0..2 m")
    head_height_pitch: float = ranged(HEAD_HEIGHT_PITCH, lambda v: 0 <= v <= 2, "0..2 m")
    jolt_limit: float = ranged(0.17, lambda v: v > 0, "> 0 m/s^2")
    heave_omega: float = ranged(2.5, lambda v: v > 0, "> 0 rad/s")
    heave_zeta: float = ranged(1.0, lambda v: v > 0, "> 0")
    heave_omega_b: float = ranged(0.5, lambda v: v > 0, "> 0 rad/s")
    rot_order: int = ranged(1, lambda v: v in (1, 2), "1 or 2")
    rot_omega: float = ranged(0.5, lambda v: v > 0, "> 0 rad/s")
    rot_zeta: float = ranged(1.0, lambda v: v > 0, "> 0")
    heave_fraction: float = ranged(0.25, lambda v: 0 < v <= 1, "in (0, 1]")
    stroke_margin: float = ranged(0.01, lambda v: 0 <= v < 0.2, "0..0.2 m")
    knee: float = ranged(0.8, lambda v: 0 <= v <= 1, "0..1")


@dataclass
class WashoutResult:
    """Output of :meth:`ClassicalWashout.run`, one row per cueing period.

    ``pose`` is the base-frame set-point (roll, pitch, h), SI; ``tilt`` the
    tilt-coordination angles and ``rot`` the rotational-channel angles, both
    (roll, pitch) in ISO angles; ``heave`` the heave from home before the
    workspace limit; ``rate_limited`` where the tilt rate limit acted;
    ``softened`` where the soft limit changed an axis by more than 1e-9.
    """

    t: np.ndarray
    pose: np.ndarray
    tilt: np.ndarray
    rot: np.ndarray
    heave: np.ndarray
    rate_limited: np.ndarray
    softened: np.ndarray


class ClassicalWashout:
    """Classical washout, one sample per :attr:`WashoutParams.period`.

    Parameters
    ----------
    params : WashoutParams, optional
        Defaults :class:`WashoutParams` ().
    geometry : PlatformGeometry, optional
        For the workspace box (default :func:`nominal_geometry`).
    **overrides
        Field values replacing those of ``params`` (unknown names raise
        :class:`WashoutParamError` listing the valid ones).
    """

    def __init__(
        self,
        params: WashoutParams | None = None,
        geometry: PlatformGeometry | None = None,
        **overrides,
    ):
        p = WashoutParams() if params is None else params
        if overrides:
            p = p.replace(**overrides)
        self.params = p
        self.geometry = nominal_geometry() if geometry is None else geometry
        self.box = inscribed_box(self.geometry, p.heave_fraction, p.stroke_margin)
        dt = p.period
        wh, zh, wb = p.heave_omega, p.heave_zeta, p.heave_omega_b
        # z / (f_z - g) = k_z s / ((s^2 + 2 zeta w s + w^2)(s + w_b)): HP3 * 1/s^2
        den_h = np.polymul([1.0, 2.0 * zh * wh, wh * wh], [1.0, wb])
        self._heave = DiscreteFilter([p.gain_z, 0.0], den_h, dt)
        wt, zt = p.tilt_omega, p.tilt_zeta
        lp = ([wt * wt], [1.0, 2.0 * zt * wt, wt * wt])
        self._lp = [DiscreteFilter(*lp, dt), DiscreteFilter(*lp, dt)]  # x, y
        wr = p.rot_omega
        if p.rot_order == 1:  # (1/s) * s/(s + w_r)
            rot = ([p.gain_rot], [1.0, wr])
        else:  # (1/s) * s^2/(s^2 + 2 zeta w s + w^2)
            rot = ([p.gain_rot, 0.0], [1.0, 2.0 * p.rot_zeta * wr, wr * wr])
        self._rot = [DiscreteFilter(*rot, dt), DiscreteFilter(*rot, dt)]  # roll, pitch
        self._home = [float(v) for v in self.geometry.home]
        self._lims = [
            (float(self.box[k][0]), float(self.box[k][1])) for k in ("roll", "pitch", "heave")
        ]
        self.reset()

    def reset(self) -> None:
        """Back to rest: filters at zero, tilt zero."""
        for f in (self._heave, *self._lp, *self._rot):
            f.reset()
        self._tilt = [0.0, 0.0]  # ISO roll, pitch
        self._rate = [0.0, 0.0]  # their rates
        self._target = [0.0, 0.0]  # the last tilt targets
        self._started = False
        self.last_rate_limited = False
        self.last_softened = False
        self.last_parts = (0.0, 0.0, 0.0, 0.0, 0.0)

    def _tilt_target(self, fx_lp: float, fy_lp: float) -> tuple[float, float]:
        p = self.params
        lim = p.tilt_limit
        sx = max(-1.0, min(1.0, -p.gain_x * fx_lp / GRAVITY))
        sy = max(-1.0, min(1.0, p.gain_y * fy_lp / GRAVITY))
        roll = max(-lim, min(lim, math.asin(sy)))
        pitch = max(-lim, min(lim, math.asin(sx)))
        return roll, pitch

    def _limited_step(self, k: int, target: float) -> bool:
        """Move tilt ``k`` one period toward ``target`` under the second-order rate
        limit and the head's jolt limit; True where a limit acted.

        The tilt follows the target's own rate, plus a closing rate on the error
        no faster than the acceleration limit can stop (``sqrt(2 accel |e|)``): a
        slowly moving target is followed without lag, a step is approached without
        overshoot."""
        p = self.params
        dt = p.period
        x, v = self._tilt[k], self._rate[k]
        v_t = (target - self._target[k]) / dt if self._started else 0.0
        self._target[k] = target
        e = target - x
        close = math.sqrt(2.0 * p.tilt_accel_limit * abs(e))
        want = v_t + max(-close, min(close, e / dt - v_t))
        tol = 1e-12
        limited = abs(want) > p.tilt_rate_limit + tol
        want = max(-p.tilt_rate_limit, min(p.tilt_rate_limit, want))
        acc = (want - v) / dt
        amax = p.tilt_accel_limit
        h = p.head_height_pitch if k == 1 else p.head_height
        if h > 0 and acc * x >= 0:
            # outward: the head is thrown against the cue by h a''
            amax = min(amax, (p.jolt_limit + GRAVITY * abs(x)) / h)
        if abs(acc) > amax + tol:
            acc = math.copysign(amax, acc)
            limited = True
        v += acc * dt
        self._rate[k] = v
        self._tilt[k] = x + v * dt
        return limited

    def step(self, f, w) -> np.ndarray:
        """One cueing period: head specific force ``f`` and angular velocity ``w``
        (3,) in V -> platform set-point (roll, pitch, h) in B (3,)."""
        fx, fy, fz = (float(v) for v in f)
        wx, wy = float(w[0]), float(w[1])
        if not all(map(math.isfinite, (fx, fy, fz, wx, wy))):
            raise ValueError(f"vehicle input not finite: f={f!r}, w={w!r}")
        z = self._heave.step(fz - GRAVITY)
        target = self._tilt_target(self._lp[0].step(fx), self._lp[1].step(fy))
        limited = False
        for k in range(2):
            limited |= self._limited_step(k, target[k])
        self._started = True
        rr = self._rot[0].step(wx)
        rp = self._rot[1].step(wy)
        self.last_rate_limited = limited
        self.last_parts = (self._tilt[0], self._tilt[1], rr, rp, z)
        # V -> B (controllers.frames.pose_iso_to_base, on floats): angles flip sign
        raw = (-(self._tilt[0] + rr), -(self._tilt[1] + rp), self._home[2] + z)
        out = [
            soft_limit(raw[k], self._home[k], *self._lims[k], self.params.knee) for k in range(3)
        ]
        self.last_softened = any(abs(o - r) > 1e-9 for o, r in zip(out, raw, strict=True))
        return np.array(out)

    def linear_response(self, omega) -> np.ndarray:
        """Small-signal response of the set-point to the vehicle input, per frequency.

        The discrete filters as they run (Tustin at ``period``), evaluated on the unit
        circle ``z = e^{j w period}`` (:func:`scipy.signal.freqz`), with ``asin`` and the
        frames linearised about rest and the rate, angle and workspace limits inactive
        (their small-signal range: check :attr:`WashoutResult.rate_limited` and
        ``softened``)::

            roll  =  k_y LP(z) f_y / g + ROT(z) w_x
            pitch = -k_x LP(z) f_x / g + ROT(z) w_y
            heave =  HEAVE(z) f_z

        Parameters
        ----------
        omega : array_like, (n,)
            Angular frequencies (rad/s), below the Nyquist frequency ``pi / period``.

        Returns
        -------
        ndarray, complex, (n, 3, 5)
            Output (ISO roll, ISO pitch in rad, heave from home in m) per input
            (``f_x, f_y, f_z`` in m/s^2, ``w_x, w_y`` in rad/s), sample by sample
            at the cueing period (no hold: see :func:`controllers.frequency.hold_factor`).
        """
        from scipy.signal import freqz

        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        p = self.params
        wd = omega * p.period
        if np.any(wd >= math.pi) or np.any(omega <= 0):
            raise ValueError(f"frequencies must be in (0, pi/period) rad/s, got {omega}")

        def h(filt: DiscreteFilter) -> np.ndarray:
            return freqz(filt.b, filt.a, worN=wd)[1]

        lp, rot, heave = h(self._lp[0]), h(self._rot[0]), h(self._heave)
        out = np.zeros((omega.size, 3, 5), complex)
        out[:, 0, 1] = p.gain_y * lp / GRAVITY
        out[:, 0, 3] = rot
        out[:, 1, 0] = -p.gain_x * lp / GRAVITY
        out[:, 1, 4] = rot
        out[:, 2, 2] = heave
        return out

    def run(self, f, w, t0: float = 0.0) -> WashoutResult:
        """Run from the current state over inputs sampled at the cueing period.

        ``f``, ``w``: (n, 3) in V. Returns a :class:`WashoutResult` of n rows.
        """
        f = np.asarray(f, dtype=float)
        w = np.asarray(w, dtype=float)
        if f.ndim != 2 or f.shape[1] != 3 or w.shape != f.shape:
            raise ValueError(f"f and w must both be (n, 3), got {f.shape} and {w.shape}")
        n = f.shape[0]
        pose = np.empty((n, 3))
        parts = np.empty((n, 5))
        lim = np.zeros(n, bool)
        soft = np.zeros(n, bool)
        for i in range(n):
            pose[i] = self.step(f[i], w[i])
            parts[i] = self.last_parts
            lim[i] = self.last_rate_limited
            soft[i] = self.last_softened
        return WashoutResult(
            t=t0 + self.params.period * np.arange(n),
            pose=pose,
            tilt=parts[:, 0:2],
            rot=parts[:, 2:4],
            heave=parts[:, 4],
            rate_limited=lim,
            softened=soft,
        )
