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

``mode="feedforward"`` (beyond the paper: section 6's "feed-forward control"
and "following trajectory"): the set-point goes straight through the IK to
the joint loops every inner step, and the outer law, at its own period from
the measured pose, integrates only a correction ``c`` of the pose::

    q_d[m] = IK(y_d[m] + c[k]),   m in [k n, (k + 1) n)
    c[k+1] = c[k] + T K_I (y_d[k] - y[k])                  (outer_law "I")
    c[k]   = c[k-1] + T K_I (e[k] + c_PI e[k-1])           (outer_law "PI")

so the steady-state task error is removed as by the paper's scheme (the
integrator), while the set-point reaches the legs with the bandwidth of the
joint loops instead of the outer loop's.

The error the correction integrates is taken against a reference model of
what the joint loops deliver, ``e = M y_d - y`` with ``M`` a first-order lag
of time constant ``model_tau`` (0: ``e = y_d - y``): without it the
integrator also integrates the joint loops' lag during every transient and
gives it back as overshoot (``K K_I`` times the lag's area). ``M(1) = 1``, so
the steady state is still ``y = y_d``. ``hold=True`` at an outer step (the
co-simulation passes "a valve was at its rail during the last period") skips
that step's integration: the correction's anti-windup against the valves'
saturation, which the linear model does not describe. The loop seen by ``c`` is the one
the I/PI law closes (same characteristic polynomial, same stability limits,
:mod:`controllers.analysis`); the feed-forward path is outside it.
Call :meth:`TaskSpaceController.update_floats` at the outer steps (it
integrates ``c``) and :meth:`TaskSpaceController.feedforward_floats` every
inner step. ``docs/feedforward.md`` has the block diagram.

Workspace: a set-point outside the reachable workspace raises
:class:`~controllers.errors.WorkspaceError` naming the limit, or, with
``clamp=True``, is pulled back along the segment from the home pose to the
farthest reachable point. The integrated pose never leaves the workspace:
an integration step that would is shortened to the farthest reachable point
on it (conditional integration, the outer loop's anti-windup).
"""

from __future__ import annotations

import math

import numpy as np

from .errors import WorkspaceError
from .geometry import PlatformGeometry, nominal_geometry
from .kinematics import PoseKinematics, check_reachable, reachable

__all__ = ["TaskSpaceController", "SamplingError", "MODES"]

MODES = ("I", "PI", "joint_only", "feedforward")


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
    mode : {"I", "PI", "joint_only", "feedforward"}
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
    outer_law : {"I", "PI"}
        The law of the correction in ``mode="feedforward"`` (default "I").
    model_tau : float
        ``mode="feedforward"``: time constant (s) of the reference model ``M``
        (module docstring); 0: no model.
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
        outer_law: str = "I",
        model_tau: float = 0.0,
        margin: float = 0.0,
    ):
        if mode not in MODES:
            raise ValueError(f"unknown mode {mode!r}; allowed: {list(MODES)}")
        if outer_law not in ("I", "PI"):
            raise ValueError(f"unknown outer_law {outer_law!r}; allowed: ['I', 'PI']")
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
        self.outer_law = outer_law
        if not (math.isfinite(model_tau) and model_tau >= 0):
            raise ValueError(f"model_tau must be finite and >= 0 s, got {model_tau!r}")
        self.model_tau = float(model_tau)
        # ZOH-exact first-order lag at the inner step: m[k+1] = m[k] + beta (y_d[k] - m[k])
        self._beta = -math.expm1(-self.inner_dt / model_tau) if model_tau > 0 else 1.0
        self.margin = float(margin)
        # The state is kept in Python floats: one pose per update is too small
        # for numpy (see update_floats); every operation below is the same
        # IEEE operation, element by element, as the array expressions it mirrors.
        self._kin = PoseKinematics(self.geometry)  # single-pose IK, bit-identical
        self._tg = (self.period * self.gains).tolist()  # T K K_I per axis
        self._xc = self.geometry.home.tolist()
        self._e_prev = [0.0, 0.0, 0.0]
        self._last_ref = None
        self._qd = check_reachable(self._xc, self.geometry).tolist()  # raises if home is not
        self._q_xc = None  # IK(x_c) when already known (computed by _integrate), else None
        self._corr = [0.0, 0.0, 0.0]  # feedforward: the integrated pose correction c
        self._pending = None  # feedforward, I law: c[k+1], applied at the next outer step
        self._model = list(self._xc)  # feedforward: the reference model's output M y_d

    # ------------------------------------------------------------------
    @property
    def pose_command(self) -> np.ndarray:
        """The integrated pose ``x_c`` (roll rad, pitch rad, h m) whose IK is ``q_d`` (copy)."""
        return np.array(self._xc)

    @property
    def correction(self) -> np.ndarray:
        """The integrated pose correction ``c`` of ``mode="feedforward"`` (copy)."""
        return np.array(self._corr)

    @property
    def q_desired(self) -> np.ndarray:
        """The last joint reference (m, copy)."""
        return np.array(self._qd)

    def is_due(self, inner_step: int) -> bool:
        """True on the inner steps at which the outer loop runs (every ``ratio`` steps)."""
        return inner_step % self.ratio == 0

    def reset(self, pose0=None) -> np.ndarray:
        """Start the integrator at ``pose0`` (default home); returns ``IK(pose0)``.

        Raises :class:`WorkspaceError` if ``pose0`` is unreachable.
        """
        pose0 = self.geometry.home if pose0 is None else pose0
        pose0 = np.asarray(pose0, dtype=float).reshape(3)
        q = check_reachable(pose0, self.geometry, self.margin)
        self._qd = q.tolist()
        self._xc = pose0.tolist()
        self._q_xc = None
        self._e_prev = [0.0, 0.0, 0.0]
        self._corr = [0.0, 0.0, 0.0]
        self._pending = None
        self._model = pose0.tolist()
        return q

    def _setpoint(self, ref: list) -> list:
        last = self._last_ref
        if last is not None and ref == last[0]:  # == per item: NaN never equal, -0.0 == 0.0
            return last[1]  # same set-point as last time: already checked
        ref = list(ref)  # a copy: the cache must not see the caller's later changes
        out = self._check_setpoint(ref)
        self._last_ref = (ref, out)
        return out

    def _check_setpoint(self, ref: list) -> list:
        if not all(map(math.isfinite, ref)):
            raise WorkspaceError(f"set-point not finite: {np.array(ref)}")
        if self._kin.solve(ref, self.margin)[1]:  # reachable(ref, geometry, margin)
            return ref
        ref = np.array(ref)
        if not self.clamp:
            check_reachable(ref, self.geometry, self.margin)  # raises, naming the limit
            raise WorkspaceError(  # the guide arc (check_reachable covers strokes)
                "set-point unreachable: outside the guide arc or stroke limits"
            )
        home = np.asarray(self.geometry.home, dtype=float)
        s = _segment_limit(home, ref, self.geometry, self.margin)
        return (home + s * (ref - home)).tolist()

    def update(self, pose_ref, pose_meas) -> np.ndarray:
        """One outer step: set-point and measured pose -> joint reference ``q_d`` (3,), m.

        Parameters
        ----------
        pose_ref, pose_meas : array_like, (3,)
            (roll rad, pitch rad, heave m).
        """
        return np.array(self.update_floats(_floats3(pose_ref), _floats3(pose_meas)))

    def update_floats(self, pose_ref: list, pose_meas: list, hold: bool = False) -> list:
        """:meth:`update` on lists of 3 floats; returns ``q_d`` as a new list.

        The co-simulation's path (issue 7). Bit-identical to the array
        formulation ``e = y_d - y``, ``x_c + T K_I e``, ``IK(x_c)`` because each
        of those is one IEEE operation per axis, and the IK is
        :class:`~controllers.kinematics.PoseKinematics`. The IK of the new
        ``x_c`` is a by-product of its reachability test in :meth:`_integrate`
        and is kept for the next update (mode ``"I"`` outputs ``IK(x_c[k])``
        before integrating; mode ``"PI"`` right after), so an update costs
        one IK instead of three.
        """
        ref = self._setpoint(pose_ref)
        if self.mode == "joint_only":
            self._xc = list(ref)
            self._q_xc = None
            self._qd = self._kin.solve(ref, arc_check=False)[0]  # IK(check=False)
            return list(self._qd)
        if not all(map(math.isfinite, pose_meas)):
            raise ValueError(f"measured pose not finite: {np.array(pose_meas)}")
        e = [ref[0] - pose_meas[0], ref[1] - pose_meas[1], ref[2] - pose_meas[2]]
        tg = self._tg
        if self.mode == "feedforward":
            if self.model_tau > 0:
                m = self._model
                e = [m[0] - pose_meas[0], m[1] - pose_meas[1], m[2] - pose_meas[2]]
            self._correct(ref, e, hold)
            return self.feedforward_floats(ref)
        if self.mode == "I":
            # eq. (22) / Fig. 7: output x_c[k], then integrate e[k]
            self._qd = self._ik_xc()
            self._integrate([tg[0] * e[0], tg[1] * e[1], tg[2] * e[2]])
        else:
            # section 4 PI: x_c[k] = x_c[k-1] + T K_I (e[k] + c e[k-1])
            c, ep = self.pi_zero, self._e_prev
            self._integrate([tg[i] * (e[i] + c * ep[i]) for i in range(3)])
            self._e_prev = e
            self._qd = self._ik_xc()
        return list(self._qd)

    def _correct(self, ref: list, e: list, hold: bool = False) -> None:
        """One outer step of the feed-forward scheme's correction ``c`` (module docstring).

        The I law applies ``c[k]`` over the coming period and integrates
        ``e[k]`` for the next one; the PI law integrates first. An increment
        that would take ``y_d + c`` out of the workspace is not taken
        (conditional integration: the correction's anti-windup).
        """
        if self._pending is not None:  # I law: c[k] = c[k-1] + T K_I e[k-1]
            self._corr, self._pending = self._pending, None
        if hold:
            return
        tg, c = self._tg, self._corr
        if self.outer_law == "PI":
            ep, z = self._e_prev, self.pi_zero
            step = [tg[i] * (e[i] + z * ep[i]) for i in range(3)]
            self._e_prev = e
        else:
            step = [tg[0] * e[0], tg[1] * e[1], tg[2] * e[2]]
        new = [c[0] + step[0], c[1] + step[1], c[2] + step[2]]
        if self._kin.solve([ref[0] + new[0], ref[1] + new[1], ref[2] + new[2]], self.margin)[1]:
            if self.outer_law == "PI":
                self._corr = new
            else:
                self._pending = new

    def feedforward_floats(self, pose_ref: list) -> list:
        """``q_d = IK(y_d + c)`` of ``mode="feedforward"`` for this inner step (new list).

        ``pose_ref`` is the set-point of this step (checked or clamped as in
        :meth:`update_floats`). The I law's pending increment, integrated at
        the last outer step, is applied from the next outer step on.
        """
        ref = self._setpoint(pose_ref)
        c, m, b = self._corr, self._model, self._beta
        if b < 1.0:  # the reference model sees this step's set-point
            self._model = [m[0] + b * (ref[0] - m[0]), m[1] + b * (ref[1] - m[1]),
                           m[2] + b * (ref[2] - m[2])]  # fmt: skip
        pose = [ref[0] + c[0], ref[1] + c[1], ref[2] + c[2]]
        q, ok = self._kin.solve(pose, self.margin)
        if not ok:  # the correction pushes past the workspace: the set-point alone
            q = self._kin.solve(ref, arc_check=False)[0]
            pose = list(ref)
        self._xc = pose
        self._qd = q
        return list(q)

    def _ik_xc(self) -> list:
        """``inverse_kinematics(x_c, check=False)``, reusing the one :meth:`_integrate` found."""
        q = self._q_xc
        if q is None:
            q = self._kin.solve(self._xc, arc_check=False)[0]
        return q

    def _integrate(self, step: list) -> None:
        xc = self._xc
        new = [xc[0] + step[0], xc[1] + step[1], xc[2] + step[2]]
        q, ok = self._kin.solve(new, self.margin)  # reachable(new) and IK(new)
        if ok:
            self._xc, self._q_xc = new, q
            return
        s = float(_segment_limit(np.array(xc), np.array(new), self.geometry, self.margin))
        self._xc = [xc[0] + s * step[0], xc[1] + s * step[1], xc[2] + s * step[2]]
        self._q_xc = None


def _floats3(x) -> list:
    """A (3,) pose as a list of 3 Python floats."""
    return np.asarray(x, dtype=float).reshape(3).tolist()
