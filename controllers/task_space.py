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
``T K K_I / (z (z - 1))``, eq. (24). The other discretisation of eq. (22)'s
integral, backward Euler ``T K_I z / (z - 1)`` (the newest error enters the
output at once), is the PI law below with ``c = 0``: :func:`outer_law` maps
the scenario's ``(type, integrator)`` onto ``(mode, c)``.

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

``lag="joints"`` measures the joint loops' lag instead of modelling it::

    e = y_d - y - J^-1 (q_d - q_meas)

``J`` the IK Jacobian at the commanded pose: ``J^-1 (q_d - q_meas)`` is what
the joint loops have not delivered yet, so during a transient ``e`` is only the
as-built error left (whatever the legs, the valves' flow limit or the
mechanism's coupling do), and at rest (``q_meas = q_d`` on average, type-2
joint loops) ``e = y_d - y``: no steady-state error. In the linear loop
``e = -c[k-1]``: ``z^2 - z + T K K_I``, stable for ``T K K_I < 1``.
``average=True`` takes the means of ``y_d, y, q_d, q_meas`` over the outer
period (the sensors' noise averaged over its samples instead of one sample).
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
from .kinematics import PoseKinematics, check_reachable, jacobian, reachable

__all__ = ["TaskSpaceController", "SamplingError", "MODES", "LAGS", "INTEGRATORS", "outer_law"]

#: Discretisations of eq. (22)'s integral for the I law (docs/paper-notes.md,
#: closed loop): "forward" ``T/(z - 1)`` as Fig. 7 prints it, "backward" ``T z/(z - 1)``.
INTEGRATORS = ("forward", "backward")


def outer_law(kind: str, integrator: str = "forward", pi_zero: float = 0.2) -> tuple[str, float]:
    """The outer law ``(mode, c)`` of a ``(type, integrator, pi_zero)`` setting.

    ``"I"`` with the ``"backward"`` integrator is ``x_c[k] = x_c[k-1] + T K_I e[k]``,
    ``q_d[k] = IK(x_c[k])``: the PI law ``T (z + c)/(z - 1)`` with ``c = 0``, so the
    controller, its analysis and its stability limits are those of ``("PI", 0.0)``.
    The PI law of section 4 already outputs the newest integration; ``integrator``
    does not change it.

    Raises
    ------
    ValueError
        ``kind`` not in ("I", "PI") or ``integrator`` not in :data:`INTEGRATORS`,
        naming the allowed values.
    """
    if kind not in ("I", "PI"):
        raise ValueError(f"outer law {kind!r}: allowed 'I', 'PI'")
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator {integrator!r}: allowed {', '.join(INTEGRATORS)}")
    if kind == "I" and integrator == "backward":
        return "PI", 0.0
    return kind, float(pi_zero)


MODES = ("I", "PI", "joint_only", "feedforward")

#: How ``mode="feedforward"`` removes the joint loops' lag from the error it integrates.
LAGS = ("model", "joints")


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
        (module docstring); 0: no model. Used with ``lag="model"``.
    lag : {"model", "joints"}
        ``mode="feedforward"``: how the joint loops' lag is taken out of the
        error the correction integrates: the reference model ``M`` (``"model"``)
        or the measured lag ``J^-1 (q_d - q_meas)`` (``"joints"``; module docstring).
    average : bool
        ``mode="feedforward"``: the correction uses the means of the signals over
        the outer period (every inner step passes them to
        :meth:`feedforward_floats`) instead of the samples at the outer step.
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
        lag: str = "model",
        average: bool = False,
    ):
        if mode not in MODES:
            raise ValueError(f"unknown mode {mode!r}; allowed: {list(MODES)}")
        if outer_law not in ("I", "PI"):
            raise ValueError(f"unknown outer_law {outer_law!r}; allowed: ['I', 'PI']")
        if lag not in LAGS:
            raise ValueError(f"unknown lag {lag!r}; allowed: {list(LAGS)}")
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
        self.lag = lag
        self.average = bool(average)
        # feedforward: sums over the current outer period of y_d, y_meas, q_d, q_meas
        # (12 floats) and their count, for average=True
        self._acc = [0.0] * 12
        self._n_acc = 0
        self._ref_cmd = self.geometry.home.tolist()
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
        self._acc = [0.0] * 12
        self._n_acc = 0
        self._ref_cmd = pose0.tolist()
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

    def update_floats(
        self, pose_ref: list, pose_meas: list, hold: bool = False, q_meas: list | None = None
    ) -> list:
        """:meth:`update` on lists of 3 floats; returns ``q_d`` as a new list.

        The co-simulation's path. Bit-identical to the array
        formulation ``e = y_d - y``, ``x_c + T K_I e``, ``IK(x_c)`` because each
        of those is one IEEE operation per axis, and the IK is
        :class:`~controllers.kinematics.PoseKinematics`. The IK of the new
        ``x_c`` is a by-product of its reachability test in :meth:`_integrate`
        and is kept for the next update (mode ``"I"`` outputs ``IK(x_c[k])``
        before integrating; mode ``"PI"`` right after), so an update costs
        one IK instead of three.

        ``hold`` and ``q_meas`` (the measured joints, needed with ``lag="joints"``)
        are used by ``mode="feedforward"`` only.
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
            if self.average or self.lag == "joints":
                e = self._ff_error(pose_meas, q_meas)
            elif self.model_tau > 0:
                m = self._model
                e = [m[0] - pose_meas[0], m[1] - pose_meas[1], m[2] - pose_meas[2]]
            self._correct(ref, e, hold)
            return self._ff_step(ref)
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

    def feedforward_floats(
        self, pose_ref: list, pose_meas: list | None = None, q_meas: list | None = None
    ) -> list:
        """``q_d = IK(y_d + c)`` of ``mode="feedforward"`` for this inner step (new list).

        ``pose_ref`` is the set-point of this step (checked or clamped as in
        :meth:`update_floats`). The I law's pending increment, integrated at
        the last outer step, is applied from the next outer step on. With
        ``average=True`` the measured pose (and joints, ``lag="joints"``) of
        this step are added to the outer period's means.
        """
        ref = self._setpoint(pose_ref)
        if self.average and pose_meas is not None:
            self._accumulate(pose_meas, q_meas)
        return self._ff_step(ref)

    def _accumulate(self, pose_meas: list, q_meas: list | None) -> None:
        """Add this step's measurements and the last step's command to the period's sums."""
        a, r, q = self._acc, self._ref_cmd, self._qd
        for i in range(3):
            a[i] += r[i]
            a[3 + i] += pose_meas[i]
        if q_meas is not None:
            for i in range(3):
                a[6 + i] += q[i]
                a[9 + i] += q_meas[i]
        self._n_acc += 1

    def _ff_error(self, pose_meas: list, q_meas: list | None) -> list:
        """The error the correction integrates at this outer step (module docstring).

        ``r - y`` with ``r`` the reference model's output (``lag="model"``) or the
        set-point (``lag="joints"``), minus ``J^-1 (q_d - q_meas)`` for
        ``lag="joints"``; over the outer period's means with ``average=True``,
        else at the last step's command and this step's measurements.
        """
        joints = self.lag == "joints"
        if joints and q_meas is None:
            raise ValueError("lag='joints' needs the measured joints q_meas")
        if self.average:
            self._accumulate(pose_meas, q_meas if joints else None)
            a, k = self._acc, 1.0 / self._n_acc
            r, y = [a[0] * k, a[1] * k, a[2] * k], [a[3] * k, a[4] * k, a[5] * k]
            qd, qm = [a[6] * k, a[7] * k, a[8] * k], [a[9] * k, a[10] * k, a[11] * k]
            self._acc, self._n_acc = [0.0] * 12, 0
        else:
            r, y, qd, qm = self._ref_cmd, pose_meas, self._qd, q_meas
        e = [r[0] - y[0], r[1] - y[1], r[2] - y[2]]
        if joints:  # the joint loops' lag, in task coordinates at the commanded pose
            lag = np.linalg.solve(
                jacobian(np.array(self._xc), self.geometry),
                np.array([qd[0] - qm[0], qd[1] - qm[1], qd[2] - qm[2]]),
            ).tolist()
            e = [e[0] - lag[0], e[1] - lag[1], e[2] - lag[2]]
        return e

    def _ff_step(self, ref: list) -> list:
        """This inner step's ``q_d = IK(ref + c)``, the reference model advanced."""
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
        # the reference this step's command stands for: the set-point (lag "joints")
        # or the reference model's output (lag "model")
        self._ref_cmd = ref if self.lag == "joints" else list(self._model)
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
