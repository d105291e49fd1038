"""Kinematic task-space control, the outer loop (paper eqs. 21-27, Fig. 7, section 5.2.3).

The measured pose ``y = (roll, pitch, h)`` (IMU + encoder, SI, sensor gain
``K = 1``) is compared with the set-point ``y_d``; the law integrates the
task error into a commanded pose ``x_c`` whose inverse kinematics (nominal
model) is the joint reference ``q_d`` of the inner loops. ``gains`` are the
products ``K K_I`` per axis (the paper's ``K_theta K_I1 = K_phi K_I2 =
K_h K_I3 = 3``).

``mode="I"`` (eq. 22; Fig. 7 ``T K_I / (z - 1)``, forward Euler)::

    q_d[k] = IK(x_c[k]);   x_c[k+1] = x_c[k] + T K_I (y_d[k] - y[k])

so with the inner loop as one sample of delay (eq. 21) the loop is
``T K K_I / (z (z - 1))``, eq. (24).

``mode="PI"`` (section 4, ``C = T (z + 0.2)/(z - 1)``; the printed 0.06 is T)::

    x_c[k] = x_c[k-1] + T K_I (e[k] + c e[k-1]);   q_d[k] = IK(x_c[k]),  c = 0.2

``mode="joint_only"``: ``q_d = IK(y_d)``, no task feedback (Fig. 15a).

Workspace: a set-point outside the reachable workspace raises
:class:`~controllers.errors.WorkspaceError` naming the limit, or, with
``clamp=True``, is pulled back along the segment from the home pose to the
farthest reachable point. The integrated pose never leaves the workspace:
an integration step that would is shortened to the farthest reachable point
on it (conditional integration, the outer loop's anti-windup).
"""

from __future__ import annotations

import numpy as np

from .errors import WorkspaceError
from .geometry import PlatformGeometry, nominal_geometry
from .kinematics import check_reachable, inverse_kinematics, reachable

__all__ = ["TaskSpaceController", "SamplingError", "MODES"]

MODES = ("I", "PI", "joint_only")


class SamplingError(ValueError):
    """A sampling period that is not an integer multiple of the inner step."""


def _segment_limit(start, stop, geometry, margin, n: int = 33, rounds: int = 2) -> float:
    """Largest ``s`` in [0, 1] with ``start + s' (stop - start)`` reachable for all s' <= s.

    Vectorised search: ``n`` points per round, ``rounds`` rounds (resolution
    ``1 / (n - 1)^rounds``). ``start`` must be reachable.
    """
    lo, hi = 0.0, 1.0
    d = stop - start
    for _ in range(rounds):
        s = np.linspace(lo, hi, n)
        ok = reachable(start + s[:, None] * d, geometry, margin)
        if ok.all():
            return hi
        first_bad = int(np.argmin(ok))
        if first_bad == 0:
            return lo
        lo, hi = s[first_bad - 1], s[first_bad]
    return float(lo)


class TaskSpaceController:
    """Outer task-space loop.

    Parameters
    ----------
    mode : {"I", "PI", "joint_only"}
    gains : float or (3,) array_like
        ``K K_I`` per axis (roll, pitch, heave), 1/s. Default 3 (section 5.2.3).
    period : float
        Outer sampling period T (s), default 0.06; an integer multiple of ``inner_dt``.
    geometry : PlatformGeometry, optional
        Nominal model used by the IK (default :func:`nominal_geometry`).
    clamp : bool
        Clamp unreachable set-points instead of raising.
    inner_dt : float
        Inner-loop step (s), default 0.001.
    pi_zero : float
        ``c`` of the PI law ``T (z + c)/(z - 1)``, default 0.2.
    margin : float
        Stroke margin (m) kept by the integrated pose and by clamping.

    Raises
    ------
    SamplingError
        ``period`` not a positive integer multiple of ``inner_dt``.
    ValueError
        Unknown mode, negative or non-finite gains.
    """

    def __init__(
        self,
        mode: str = "I",
        gains=(3.0, 3.0, 3.0),
        period: float = 0.06,
        geometry: PlatformGeometry | None = None,
        clamp: bool = False,
        *,
        inner_dt: float = 0.001,
        pi_zero: float = 0.2,
        margin: float = 0.0,
    ):
        if mode not in MODES:
            raise ValueError(f"unknown mode {mode!r}; allowed: {list(MODES)}")
        if not (np.isfinite(inner_dt) and inner_dt > 0):
            raise SamplingError(f"inner_dt must be > 0 s, got {inner_dt!r}")
        ratio = period / inner_dt
        n = int(round(ratio))
        if not np.isfinite(ratio) or n < 1 or abs(ratio - n) > 1e-9 * max(1.0, ratio):
            raise SamplingError(
                f"outer period {period!r} s is not a positive integer multiple of the "
                f"inner step {inner_dt} s"
            )
        g = np.broadcast_to(np.asarray(gains, dtype=float), (3,)).copy()
        if not np.all(np.isfinite(g)) or np.any(g < 0):
            raise ValueError(f"gains must be finite and >= 0, got {gains!r}")
        if not (0 <= margin < 0.25):
            raise ValueError(f"margin must be in [0, 0.25) m, got {margin!r}")
        self.mode = mode
        self.gains = g
        self.period = float(period)
        self.inner_dt = float(inner_dt)
        self.ratio = n
        self.geometry = nominal_geometry() if geometry is None else geometry
        self.clamp = bool(clamp)
        self.pi_zero = float(pi_zero)
        self.margin = float(margin)
        self._tg = self.period * self.gains  # T K K_I per axis
        self._xc = np.array(self.geometry.home, dtype=float)
        self._e_prev = np.zeros(3)
        self._last_ref = None
        self._qd = inverse_kinematics(self._xc, self.geometry)

    # ------------------------------------------------------------------
    @property
    def pose_command(self) -> np.ndarray:
        """The integrated pose ``x_c`` (roll rad, pitch rad, h m) whose IK is ``q_d`` (copy)."""
        return self._xc.copy()

    @property
    def q_desired(self) -> np.ndarray:
        """The last joint reference (m, copy)."""
        return self._qd.copy()

    def is_due(self, inner_step: int) -> bool:
        """True on the inner steps at which the outer loop runs (every ``ratio`` steps)."""
        return inner_step % self.ratio == 0

    def reset(self, pose0=None) -> np.ndarray:
        """Start the integrator at ``pose0`` (default home); returns ``IK(pose0)``.

        Raises :class:`WorkspaceError` if ``pose0`` is unreachable.
        """
        pose0 = self.geometry.home if pose0 is None else pose0
        pose0 = np.asarray(pose0, dtype=float).reshape(3)
        self._qd = check_reachable(pose0, self.geometry, self.margin)
        self._xc = pose0.copy()
        self._e_prev[:] = 0.0
        return self._qd.copy()

    def _setpoint(self, pose_ref) -> np.ndarray:
        ref = np.asarray(pose_ref, dtype=float).reshape(3)
        if self._last_ref is not None and np.array_equal(ref, self._last_ref[0]):
            return self._last_ref[1]  # same set-point as last time: already checked
        out = self._check_setpoint(ref)
        self._last_ref = (ref.copy(), out)
        return out

    def _check_setpoint(self, ref) -> np.ndarray:
        if not np.all(np.isfinite(ref)):
            raise WorkspaceError(f"set-point not finite: {ref}")
        if reachable(ref, self.geometry, self.margin):
            return ref
        if not self.clamp:
            check_reachable(ref, self.geometry, self.margin)  # raises, naming the limit
            raise WorkspaceError(  # the guide arc (check_reachable covers strokes)
                "set-point unreachable: outside the guide arc or stroke limits"
            )
        home = np.asarray(self.geometry.home, dtype=float)
        s = _segment_limit(home, ref, self.geometry, self.margin)
        return home + s * (ref - home)

    def update(self, pose_ref, pose_meas) -> np.ndarray:
        """One outer step: set-point and measured pose -> joint reference ``q_d`` (3,), m.

        Parameters
        ----------
        pose_ref, pose_meas : array_like, (3,)
            (roll rad, pitch rad, heave m).
        """
        ref = self._setpoint(pose_ref)
        if self.mode == "joint_only":
            self._xc = ref.copy()
            self._qd = inverse_kinematics(ref, self.geometry, check=False)
            return self._qd.copy()
        meas = np.asarray(pose_meas, dtype=float).reshape(3)
        if not np.all(np.isfinite(meas)):
            raise ValueError(f"measured pose not finite: {meas}")
        e = ref - meas
        if self.mode == "I":
            # eq. (22) / Fig. 7: output x_c[k], then integrate e[k]
            self._qd = inverse_kinematics(self._xc, self.geometry, check=False)
            self._integrate(self._tg * e)
        else:
            # section 4 PI: x_c[k] = x_c[k-1] + T K_I (e[k] + c e[k-1])
            self._integrate(self._tg * (e + self.pi_zero * self._e_prev))
            self._e_prev = e
            self._qd = inverse_kinematics(self._xc, self.geometry, check=False)
        return self._qd.copy()

    def _integrate(self, step) -> None:
        new = self._xc + step
        if reachable(new, self.geometry, self.margin):
            self._xc = new
            return
        s = _segment_limit(self._xc, new, self.geometry, self.margin)
        self._xc = self._xc + s * step
