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
Call :meth:`TaskSpaceController.update` at the outer steps (it
integrates ``c``) and :meth:`TaskSpaceController.feedforward` every
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
from typing import Literal, get_args

import numpy as np

from . import step_functions as sf
from .dead_band import BandKind
from .errors import WorkspaceError
from .geometry import PlatformGeometry, nominal_geometry
from .kinematics import check_reachable

#: Discretisations of eq. (22)'s integral for the I law (docs/paper-notes.md,
#: closed loop): "forward" ``T/(z - 1)`` as Fig. 7 prints it, "backward" ``T z/(z - 1)``.
Integrator = Literal["forward", "backward"]
INTEGRATORS: tuple[Integrator, ...] = get_args(Integrator)


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
_MODE_CODES = dict(joint_only=sf.MODE_JOINT, I=sf.MODE_I, PI=sf.MODE_PI, feedforward=sf.MODE_FF)

#: How ``mode="feedforward"`` removes the joint loops' lag from the error it integrates.
Lag = Literal["model", "joints"]
LAGS: tuple[Lag, ...] = get_args(Lag)
#: What the I and PI laws integrate: the whole task error (the paper) or the error less
#: the joint loops' lag beyond their dead bands (``joint_lag``).
JointLag = Literal["none", "joints"]
JOINT_LAGS: tuple[JointLag, ...] = get_args(JointLag)
BAND_KINDS: tuple[BandKind, ...] = get_args(BandKind)


def _widths(value, name: str) -> np.ndarray:
    """``value`` as three finite widths >= 0 (one number for all three); else ValueError."""
    w = np.broadcast_to(np.asarray(value, dtype=float), (3,))
    if not (np.all(np.isfinite(w)) and np.all(w >= 0)):
        raise ValueError(f"{name} must be 1 or 3 finite widths >= 0, got {value!r}")
    return w


class SamplingError(ValueError):
    """A sampling period that is not an integer multiple of the inner step."""


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
        :meth:`feedforward`) instead of the samples at the outer step.
    margin : float
        Stroke margin (m) kept by the integrated pose and by clamping.
    dead_band : float or (3,) array_like
        Width per axis (rad, rad, m) of the dead band on the task error the
        law integrates (:func:`controllers.dead_band.dead_band`): within it the
        integrated pose holds. Default 0 (none).
    band_kind : {"subtract", "gap"}
        Outside the band the law integrates ``e -+ w`` (``"subtract"``,
        :func:`~controllers.dead_band.dead_band`) or the whole ``e`` (``"gap"``,
        :func:`~controllers.dead_band.gap`).
    band_release : float
        ``>= 1``: once the error is within the band, the law holds until it
        leaves ``band_release`` times the band (1: no hold beyond the band).
    joint_lag : {"none", "joints"}
        Modes I and PI: ``"none"`` (the paper) integrates the whole task error
        ``y_d - y``; ``"joints"`` integrates it less the joint loops' lag
        ``J(x_c)^-1 db(q_d - q_meas)``, what the legs are still delivering (``db``
        the joint dead band ``joint_band``). While the legs travel the law then
        drives ``x_c`` towards ``y_d`` at its own rate instead of winding up
        on their lag; at rest ``q_d - q_meas`` is within the bands and the law
        removes the whole error. :meth:`update` needs ``q_meas``.
    joint_band : float or (3,) array_like
        Each leg's dead band (m) left out of the lag (``joint_lag="joints"``):
        the joint loops' own (``controller.inner.dead_band_mm``).

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
        dead_band=0.0,
        band_kind: str = "subtract",
        band_release: float = 1.0,
        joint_lag: str = "none",
        joint_band=0.0,
    ):
        if mode not in MODES:
            raise ValueError(f"unknown mode {mode!r}; allowed: {list(MODES)}")
        if outer_law not in ("I", "PI"):
            raise ValueError(f"unknown outer_law {outer_law!r}; allowed: ['I', 'PI']")
        if lag not in LAGS:
            raise ValueError(f"unknown lag {lag!r}; allowed: {list(LAGS)}")
        if band_kind not in BAND_KINDS:
            raise ValueError(f"unknown band_kind {band_kind!r}; allowed: {list(BAND_KINDS)}")
        if not (math.isfinite(band_release) and band_release >= 1.0):
            raise ValueError(f"band_release must be finite and >= 1, got {band_release!r}")
        if joint_lag not in JOINT_LAGS:
            raise ValueError(f"unknown joint_lag {joint_lag!r}; allowed: {list(JOINT_LAGS)}")
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
        # the per-step functions' arrays (controllers.step_functions): the geometry,
        # the constants and the state of the outer loop
        self.step_geometry = sf.geometry_constants(self.geometry)
        db = _widths(dead_band, "dead_band")
        self.dead_band = db.copy()
        jb = _widths(joint_band, "joint_band")
        self.joint_lag = joint_lag
        self.step_constants = sf.TC.pack(
            mode=_MODE_CODES[mode], law=2.0 if outer_law == "PI" else 1.0, clamp=self.clamp,
            lagj=lag == "joints", avg=self.average, tau=self.model_tau, beta=self._beta,
            piz=self.pi_zero, tg=self.period * self.gains, margin=self.margin,
            home=self.geometry.home, db=db, dbgap=band_kind == "gap", dbrel=band_release,
            jlag=joint_lag == "joints", jband=jb,
        )  # fmt: skip
        self.step_state = np.zeros(sf.TS.LEN)
        self.reset()  # raises if home is not reachable

    # ------------------------------------------------------------------
    @property
    def pose_command(self) -> np.ndarray:
        """The integrated pose ``x_c`` (roll rad, pitch rad, h m) whose IK is ``q_d`` (copy)."""
        return self.step_state[sf.TS.xc : sf.TS.xc + 3].copy()

    @property
    def correction(self) -> np.ndarray:
        """The integrated pose correction ``c`` of ``mode="feedforward"`` (copy)."""
        return self.step_state[sf.TS.corr : sf.TS.corr + 3].copy()

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
        ts = self.step_state
        ts[:] = 0.0
        ts[sf.TS.xc : sf.TS.xc + 3] = pose0
        ts[sf.TS.qd : sf.TS.qd + 3] = q
        ts[sf.TS.model : sf.TS.model + 3] = pose0
        ts[sf.TS.refcmd : sf.TS.refcmd + 3] = pose0
        return q

    def update(self, pose_ref, pose_meas, hold: bool = False, q_meas=None) -> np.ndarray:
        """One outer step: set-point and measured pose -> joint reference ``q_d`` (3,), m.

        ``pose_ref``, ``pose_meas``: (roll rad, pitch rad, heave m). ``hold`` is used by
        ``mode="feedforward"`` only; ``q_meas`` (the measured joints) by its
        ``lag="joints"`` and by ``joint_lag="joints"``. The arithmetic is
        :func:`controllers.step_functions.outer_update`, the co-simulation's step.
        """
        ts, tc, g = self.step_state, self.step_constants, self.step_geometry
        if self.mode == "feedforward" and self.lag == "joints" and q_meas is None:
            raise ValueError("lag='joints' needs the measured joints q_meas")
        if self.mode in ("I", "PI") and self.joint_lag == "joints" and q_meas is None:
            raise ValueError("joint_lag='joints' needs the measured joints q_meas")
        qm = (0.0, 0.0, 0.0) if q_meas is None else q_meas
        args = (*_floats(pose_ref, pose_meas, qm), bool(hold), ts, tc, g)
        err = sf.outer_update(*args)
        raise_step_error(err, pose_ref, pose_meas, self.geometry, self.margin)
        return ts[sf.TS.qd : sf.TS.qd + 3].copy()

    def feedforward(self, pose_ref, pose_meas=None, q_meas=None) -> np.ndarray:
        """``q_d = IK(y_d + c)`` of ``mode="feedforward"`` for this inner step (new array).

        ``pose_ref`` is the set-point of this step (checked or clamped as in
        :meth:`update`). The I law's pending increment, integrated at
        the last outer step, is applied from the next outer step on. With
        ``average=True`` the measured pose (and joints) of this step are added
        to the outer period's means. The arithmetic is
        :func:`controllers.step_functions.ff_inner`.
        """
        acc = 0 if pose_meas is None else (1 if q_meas is None else 2)
        y = (0.0, 0.0, 0.0) if pose_meas is None else pose_meas
        qm = (0.0, 0.0, 0.0) if q_meas is None else q_meas
        ts, tc, g = self.step_state, self.step_constants, self.step_geometry
        args = (*_floats(pose_ref, y, qm), acc, ts, tc, g)
        err = sf.ff_inner(*args)
        raise_step_error(err, pose_ref, pose_meas, self.geometry, self.margin)
        return ts[sf.TS.qd : sf.TS.qd + 3].copy()


def raise_step_error(err: int, pose_ref, pose_meas, geometry, margin: float = 0.0) -> None:
    """The exception of an outer-loop error code (:mod:`controllers.step_functions`).

    Returns for 0 (none) and for codes that are not the outer loop's.

    Raises
    ------
    WorkspaceError
        The set-point is not finite or unreachable (naming the limit), or the
        guide circle misses the commanded pose.
    ValueError
        The measured pose is not finite.
    """
    if not err:
        return
    if err == sf.ERR_SETPOINT_NONFINITE:
        raise WorkspaceError(f"set-point not finite: {np.array(pose_ref, dtype=float)}")
    if err == sf.ERR_SETPOINT_UNREACHABLE:
        check_reachable(np.asarray(pose_ref, dtype=float), geometry, margin)  # names the limit
        raise WorkspaceError("set-point unreachable: outside the guide arc or stroke limits")
    if err == sf.ERR_MEAS_NONFINITE:
        raise ValueError(f"measured pose not finite: {np.array(pose_meas, dtype=float)}")
    if err == sf.ERR_GUIDE:
        raise WorkspaceError(
            f"pose unreachable: the guide arc (radius {geometry.guide_radius:.4f} m) does not "
            "reach that height; allowed heave keeps |z_B1 - z_c| <= r"
        )


def _floats(*triples) -> list[float]:
    """(3,) poses or joint vectors as Python floats (the per-step functions' scalar arguments)."""
    return [float(v) for t in triples for v in np.broadcast_to(np.asarray(t, float), (3,))]
