"""Closed-loop frequency response of the task axes: measurement fit and linear prediction.

Two halves, numbers only (no MuJoCo):

* :func:`fit_sine` estimates the complex amplitude of a sinusoid in a
  record by linear least squares (offset, linear trend, cosine, sine), so
  that ``H = Y / R`` of an output ``y`` and the set-point ``r`` fitted over
  the same settled whole periods is the measured response at that frequency.
* :func:`predict` computes the response of the linearised loop with
  python-control: per leg the identified plant ``b / (s (s^2 + a1 s + a0))``
  (eq. 19) ZOH-discretised at 1 ms (``control.c2d``), the discrete joint
  controller of :mod:`controllers.joint`, closed with ``control.feedback``;
  the legs mapped to the task axes with the IK Jacobian at home
  (``y = J^-1 diag(G_i) J x``, which is where the cross-axis terms come
  from: leg 1 is slower than legs 2-3); the IMU's first-order filter and
  output hold on roll and pitch; and, for the task-space modes, the outer
  law at its period ``T`` around the inner loops lifted to ``T`` (exact
  sampled-data model, :func:`controllers.analysis.lifted.lift`).

The sampled-data loop and its fundamental
-----------------------------------------
With the outer law ``C(z)`` at ``T = n dt`` (``g T / (z - 1)`` for the I
law of eq. 22, ``g T (z + c) / (z - 1)`` for the PI law), ``P_T(z)`` the
inner loops lifted to ``T`` from the held command to the measured pose at
the sampling instants, and ``F(w)`` the fast (1 ms) chain from a task
command to the pose, a set-point ``r`` of complex amplitude ``R`` at ``w``
gives (fundamental component, exact for the linear model)::

    joint_only   y = F R
    I, PI        y = F H_n (I + C P_T)^-1 C R
    feedforward  y = F (R + H_n c),   c = (I + C P_T)^-1 C (M - F_fb) R
                 (lag "joints": c = (I + C (z^-1 - P_J))^-1 C (I - S) F R, with
                 P_J the lifted chain to (I - S) y and S the IMU filter)

where ``H_n(w) = (1/n) sum_{i<n} e^{-j w i dt}`` is the fundamental of the
outer loop's staircase (zero-order hold of ``n`` fast samples) and
``F_fb`` the fast chain to the measured pose that the outer loop samples,
``M`` the feed-forward scheme's reference model (identity without one).
The harmonics at ``k 2 pi / T +- w`` that the staircase also carries are
not in ``y``'s fundamental; the fit over whole periods sees them as a small
leakage.

Only numpy and python-control (imported on use).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .analysis.lifted import lift
from .design import JointDesign, Plant
from .joint import leg_state_space

#: Vehicle-input and head channels of the whole cueing chain (V frame, ISO 8855): specific
#: force x, y, z (m/s^2) and roll and pitch rates (rad/s).
CHAIN_CHANNELS = ("fx", "fy", "fz", "wx", "wy")

#: The twelve frequencies of the Objective Motion Cueing Test (ICAO 9625, 4th ed.,
#: Attachment 2): 0.1 to 15.85 rad/s, five per decade (10^(k/5), k = -5..6).
OMCT_RAD_S = tuple(10.0 ** (k / 5.0) for k in range(-5, 7))

#: Loop structures :func:`predict` knows.
RESPONSE_MODES = ("joint_only", "I", "PI", "feedforward")


def fit_sine(t, y, omega: float, trend: bool = True) -> complex | np.ndarray:
    """Complex amplitude ``Y`` of ``y(t) ~ c0 + c1 t + Re(Y e^{j omega t})`` (least squares).

    Parameters
    ----------
    t, y : array_like, (n,)
        Times (s) and samples; ``y`` may be (n, m): one amplitude per column.
    omega : float
        Angular frequency (rad/s).
    trend : bool
        Fit a linear trend too (a slow drift of the loop is not leaked into
        the sine); over whole periods it leaves an exact sinusoid unbiased.

    Returns
    -------
    complex or ndarray of complex
        ``Y = a - j b`` for ``y = a cos(w t) + b sin(w t) + ...``: the ratio of two
        such amplitudes is the frequency response between the two signals.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    t0 = t[0]
    cols = [np.ones_like(t)]
    if trend:
        cols.append(t - t0)
    cols += [np.cos(omega * t), np.sin(omega * t)]
    a = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return coef[-2] - 1j * coef[-1]


def hold_factor(omega, n: int, dt: float):
    """Fundamental of an ``n``-sample zero-order hold at ``dt``: ``(1/n) sum e^{-j w i dt}``."""
    omega = np.asarray(omega, dtype=float)
    i = np.arange(int(n))
    return np.exp(-1j * np.multiply.outer(omega, i * dt)).mean(axis=-1)


@dataclass
class LoopModel:
    """The linearised loop of one scenario (what :func:`predict` needs).

    Attributes
    ----------
    plants, designs : 3 Plant, 3 JointDesign
        Per leg: the identified plant (eq. 19) and the joint controller.
    jac : (3, 3) array
        IK Jacobian ``dq/dx`` at home (rows legs, columns roll, pitch, heave).
    mode : {"joint_only", "I", "PI", "feedforward"}
    gains : (3,) array
        ``K K_I`` per axis (1/s).
    period : float
        Outer period ``T`` (s), a multiple of ``dt``.
    dt : float
        Inner step (s).
    method : str
        Discretisation of the joint controllers (``tustin`` or ``zoh``).
    pi_zero : float
        ``c`` of the PI law.
    outer_law : {"I", "PI"}
        The correction law of ``mode="feedforward"``.
    imu_alpha : float
        IMU filter coefficient per step (``1 - exp(-2 pi f_c dt)``); 0: no filter.
    imu_every : int
        IMU output period in steps (its zero-order hold).
    velocity_ff : (3,) array
        Leg velocity feed-forward gains (V per m/s), 0: none.
    model_tau : float
        ``mode="feedforward"``: time constant (s) of the reference model ``M``
        the correction compares the pose with (0: none,
        :class:`controllers.task_space.TaskSpaceController`).
    lag : {"model", "joints"}
        ``mode="feedforward"``: the joint loops' lag taken out of the error by the
        reference model ``M`` or measured, ``J^-1 (q_d - q)``
        (:class:`controllers.task_space.TaskSpaceController`).
    average : bool
        ``mode="feedforward"``: the correction uses the means over the outer period.
    setpoint_filter : tuple (A, B, C, D) or list of 3 such, optional
        One leg's set-point filter at ``dt`` between ``q_d`` and the joint
        loop (Fig. 13's "Filter"), applied to every leg in every mode.
    """

    plants: Sequence[Plant]
    designs: Sequence[JointDesign]
    jac: np.ndarray
    mode: str = "I"
    gains: np.ndarray = field(default_factory=lambda: np.full(3, 3.0))
    period: float = 0.06
    dt: float = 0.001
    method: str = "tustin"
    pi_zero: float = 0.2
    outer_law: str = "I"
    imu_alpha: float = 0.0
    imu_every: int = 1
    velocity_ff: np.ndarray = field(default_factory=lambda: np.zeros(3))
    model_tau: float = 0.0
    setpoint_filter: tuple | list | None = None
    lag: str = "model"
    average: bool = False

    def __post_init__(self):
        if self.mode not in RESPONSE_MODES:
            raise ValueError(f"unknown mode {self.mode!r}; allowed: {list(RESPONSE_MODES)}")
        if self.outer_law not in ("I", "PI"):
            raise ValueError(f"unknown outer_law {self.outer_law!r}; allowed: ['I', 'PI']")
        if self.lag not in ("model", "joints"):
            raise ValueError(f"unknown lag {self.lag!r}; allowed: ['model', 'joints']")
        n = self.period / self.dt
        if not (math.isfinite(n) and n >= 1 and abs(n - round(n)) < 1e-9 * max(1.0, n)):
            raise ValueError(
                f"period {self.period!r} s is not a positive integer multiple of dt {self.dt} s"
            )
        self.gains = np.broadcast_to(np.asarray(self.gains, float), (3,)).copy()
        self.velocity_ff = np.broadcast_to(np.asarray(self.velocity_ff, float), (3,)).copy()
        self.jac = np.asarray(self.jac, float).reshape(3, 3)

    @property
    def ratio(self) -> int:
        return int(round(self.period / self.dt))


def _leg_loops(model: LoopModel):
    """Per leg, ``control`` systems at ``dt``: the (filtered) joint loop ``q_d -> q`` and
    the path ``u_ff -> q`` of a feed-forward voltage added to the controller's output."""
    import control as ct

    legs = []
    filters: tuple | list | None = model.setpoint_filter
    if filters is not None and not isinstance(filters, list):
        filters = [filters] * len(model.plants)  # one (A, B, C, D) for every leg
    for i, (plant, design) in enumerate(zip(model.plants, model.designs, strict=True)):
        # in state space before the ZOH: a discrete canonical form with poles near
        # z = 1 would be too ill-conditioned to lift to the outer period
        p = ct.c2d(ct.ss(ct.tf(plant.num, plant.den)), model.dt, "zoh")  # held valve command
        c = ct.ss(*leg_state_space(design, model.dt, model.method), model.dt)
        loop = ct.feedback(ct.series(c, p), 1)  # u = C (q_d - q) + u_ff
        if filters is not None:  # q_d -> filter -> q_ref of the joint loop
            loop = ct.series(ct.ss(*filters[i], model.dt), loop)
        dist = ct.feedback(p, c)
        legs.append((ct.ss(loop), ct.ss(dist)))
    return legs


def _imu_filter(model: LoopModel):
    """The IMU's output filter ``s[k] = s[k-1] + alpha (y[k] - s[k-1])`` (``control`` ss)."""
    import control as ct

    a = model.imu_alpha
    if a > 0:  # state space: a series with a tf would turn the leg into a tf
        return ct.ss(ct.tf([a, 0.0], [1.0, -(1.0 - a)], model.dt))
    return ct.ss(ct.tf([1.0], [1.0], model.dt))


def _eval(sys, z) -> complex:
    """A SISO ``control`` system's value at ``z`` (``C (zI - A)^-1 B + D``), as python-control
    evaluates it less its failed slycot import per call (a quarter of ``analyze``)."""
    if not hasattr(sys, "A"):
        return complex(np.asarray(sys(z, squeeze=False)).reshape(-1)[0])
    a, b, c, d = (np.asarray(m) for m in (sys.A, sys.B, sys.C, sys.D))
    n = a.shape[0]
    if n == 0:
        return complex(d[0, 0])
    if n == 1:
        with np.errstate(divide="ignore", invalid="ignore"):
            value = complex(c[0, 0] / (z - a[0, 0]) * b[0, 0] + d[0, 0])
        return complex(np.inf, np.nan) if np.isnan(value) else value
    try:
        x = np.linalg.solve(z * np.eye(n) - a, b)
    except np.linalg.LinAlgError:  # z on a pole
        return complex(np.inf, np.nan)
    return complex((c @ x + d)[0, 0])


def _lifted(sys, n: int, period: float):
    """SISO ``sys`` (discrete, D = 0) lifted to ``n`` steps with the input held (exact
    at the slow instants), as a ``control`` system at ``period``."""
    import control as ct

    sys = ct.ss(sys)
    a, b, c = np.asarray(sys.A), np.asarray(sys.B), np.asarray(sys.C)
    if np.any(np.asarray(sys.D)):
        raise ValueError("the lifted chain must be strictly proper (D = 0)")
    phi, gam = lift(a, b, n)
    return ct.ss(phi, gam, c, np.zeros((1, 1)), period)


def predict(model: LoopModel, omega) -> dict:
    """Predicted closed-loop response of the task axes at ``omega`` (rad/s).

    Per leg the systems are built, closed and lifted with python-control
    (SISO, well conditioned); the legs are mixed with the Jacobian per
    frequency: the IMU filter ``f`` acts on roll and pitch after ``J^-1``,
    so ``y_fb = E J^-1 diag(f G_i) J x + (I - E) J^-1 diag(G_i) J x`` with
    ``E = diag(1, 1, 0)``, and the same for the lifted ``P_T``.

    Returns
    -------
    dict
        ``true`` and ``measured``: complex arrays (len(omega), 3, 3),
        ``[k, out, in]`` the response of output axis ``out`` to a set-point on
        axis ``in`` (SI per SI: rad/rad, m/rad, rad/m, m/m). The velocity
        feed-forward is a leg voltage ``kv (q_ff[k] - q_ff[k-1]) / dt`` with
        ``q_ff = J r`` the feed-forward part of the joint reference.
    """
    import control as ct

    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    n, dt, T = model.ratio, model.dt, model.period
    jac = model.jac
    jinv = np.linalg.inv(jac)
    eye = np.eye(3)
    e_imu = np.diag([1.0, 1.0, 0.0])
    legs = _leg_loops(model)
    imu = _imu_filter(model)
    filters: tuple | list | None = model.setpoint_filter
    if filters is not None and not isinstance(filters, list):
        filters = [filters] * 3
    sf_sys = None if filters is None else [ct.ss(*f, dt) for f in filters]

    def f_sf(z):
        if sf_sys is None:
            return np.ones(3)
        return np.array([_eval(f, z) for f in sf_sys])

    slow = None
    if model.mode != "joint_only":
        slow = [
            (_lifted(g, n, T), _lifted(ct.series(g, imu), n, T))
            if model.imu_alpha > 0
            else (_lifted(g, n, T),) * 2
            for g, _ in legs
        ]
    law = model.outer_law if model.mode == "feedforward" else model.mode
    hold_imu = hold_factor(omega, model.imu_every, dt)
    out_true = np.empty((omega.size, 3, 3), complex)
    out_meas = np.empty((omega.size, 3, 3), complex)
    for k, w in enumerate(omega):
        zf = np.exp(1j * w * dt)
        g = np.array([_eval(leg, zf) for leg, _ in legs])
        d = np.array([_eval(dist, zf) for _, dist in legs])
        f_imu = _eval(imu, zf)
        sens = np.diag([f_imu, f_imu, 1.0])
        # fast chain from a task command x and the leg voltages u_ff to the pose
        f_x = jinv @ np.diag(g) @ jac
        f_u = jinv @ np.diag(d)
        # leg velocity feed-forward from the 1 ms set-point: u_ff = kv F_sf (1 - z^-1)/dt J r
        # (F_sf the legs' set-point filters, as on q_d)
        vff = np.diag(model.velocity_ff * f_sf(zf)) @ jac * ((1.0 - 1.0 / zf) / dt)
        direct = f_x + f_u @ vff
        if model.mode == "joint_only":
            h = direct
        else:
            assert slow is not None  # built above for every mode but joint_only
            zs = np.exp(1j * w * T)
            pg = np.array([_eval(lg, zs) for lg, _ in slow])
            pf = np.array([_eval(lf, zs) for _, lf in slow])
            p_t = e_imu @ jinv @ np.diag(pf) @ jac + (eye - e_imu) @ jinv @ np.diag(pg) @ jac
            c = np.diag(model.gains) * T / (zs - 1.0)
            if law == "PI":
                c = c * (zs + model.pi_zero)
            hn = hold_factor(w, n, dt)
            if model.mode == "feedforward":
                # average: the period's mean of a fast signal, sampled (its fundamental;
                # for the lifted terms an approximation, exact for slow signals)
                avg = hn if model.average else 1.0
                if model.lag == "joints":
                    # e = y_d - y_fb - J^-1 (q_d - q) = -c (last period) + (I - S) y:
                    # the set-point cancels, the IMU filter's lag remains
                    p_j = e_imu @ jinv @ np.diag(pg - pf) @ jac
                    plant_c = eye / zs - avg * p_j
                    drive = avg * (eye - sens) @ direct
                else:
                    # the error is M y_d - y_fb, M = beta / (z - (1 - beta)) at dt
                    ref_model = 1.0
                    if model.model_tau > 0:
                        beta = -math.expm1(-dt / model.model_tau)
                        ref_model = beta / (zf - (1.0 - beta))
                    plant_c = avg * p_t
                    drive = avg * (ref_model * eye - sens @ direct)
                corr = np.linalg.solve(eye + c @ plant_c, c @ drive)
                h = direct + f_x @ (hn * corr)
            else:
                h = f_x @ (hn * np.linalg.solve(eye + c @ p_t, c))
        out_true[k] = h
        out_meas[k] = np.diag([hold_imu[k], hold_imu[k], 1.0]) @ sens @ h
    return {"omega_rad_s": omega, "true": out_true, "measured": out_meas}


# ------------------------------------------------ the whole cueing chain


def head_response(omega, jac=None, g: float = 9.80665) -> np.ndarray:
    """Rigid cabin: head specific force and angular velocity per cabin pose, small angles.

    A cabin at ISO roll ``phi``, pitch ``theta`` and heave ``z`` (from home) whose head
    moves by ``x_head = J (phi, theta, z)`` (ISO axes, m per rad or m; the mechanism's
    kinematics linearised at home) feels::

        f = (-g theta, g phi, 0) + J (phi, theta, z)'',  w = (phi', theta')

    (gravity seen through the tilt, :func:`controllers.frames.static_specific_force`,
    plus the head's acceleration; ``' = j w``). ``J = None``: the head at a point that
    only heaves, ``J = diag(0, 0, 1)``.

    Returns
    -------
    ndarray, complex, (len(omega), 5, 3)
        :data:`CHAIN_CHANNELS` per (roll, pitch, heave).
    """
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    jac = np.diag([0.0, 0.0, 1.0]) if jac is None else np.asarray(jac, float).reshape(3, 3)
    s = 1j * omega
    m = np.zeros((omega.size, 5, 3), complex)
    m[:, :3, :] = (s * s)[:, None, None] * jac
    m[:, 0, 1] += -g
    m[:, 1, 0] += g
    m[:, 3, 0] = s
    m[:, 4, 1] = s
    return m


def chain_response(washout, omega, *, dt: float = 0.001, pose=None, head_jac=None):
    """Vehicle input -> head, :data:`CHAIN_CHANNELS` x :data:`CHAIN_CHANNELS`, at ``omega``.

    ``washout`` (:meth:`controllers.washout.ClassicalWashout.linear_response`) sampled
    every ``period`` and held on the ``dt`` grid (:func:`hold_factor`), then the
    platform ``pose`` (complex (len(omega), 3, 3), ISO roll, pitch, heave per set-point;
    ``None``: the pose is the set-point) and the rigid cabin :func:`head_response`
    with the head's kinematic Jacobian ``head_jac``. With ``pose=None`` and
    ``head_jac=None`` this is the washout alone on an ideal platform, the reference
    against which the platform's share is read.

    Returns
    -------
    ndarray, complex, (len(omega), 5, 5)
        ``[k, out, in]``: head channel ``out`` per vehicle channel ``in`` (SI per SI).
    """
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    every = washout.params.period / dt
    if abs(every - round(every)) > 1e-9 * every:
        raise ValueError(f"washout period {washout.params.period} s is not a multiple of {dt} s")
    w = washout.linear_response(omega) * hold_factor(omega, int(round(every)), dt)[:, None, None]
    if pose is not None:
        w = np.asarray(pose) @ w
    return head_response(omega, head_jac) @ w


# ---------------------------------------------------------------- summaries


def _db(h) -> np.ndarray:
    return 20.0 * np.log10(np.maximum(np.abs(h), 1e-300))


def bandwidth_3db(freq_hz, h) -> float | None:
    """First frequency at which ``|h|`` falls 3 dB below its value at the lowest frequency.

    Linear interpolation of the gain (dB) in log frequency between the two
    points that bracket the crossing; ``None`` if it never falls within the
    data (the bandwidth is above the highest frequency).
    """
    f = np.asarray(freq_hz, float)
    g = _db(np.asarray(h))
    ref = g[0] if abs(g[0]) < 1.0 else 0.0  # a low-frequency gain of 1 is the reference
    below = np.nonzero(g < ref - 3.0)[0]
    if not below.size:
        return None
    i = int(below[0])
    if i == 0:
        return float(f[0])
    x0, x1 = math.log(f[i - 1]), math.log(f[i])
    g0, g1 = g[i - 1] - ref + 3.0, g[i] - ref + 3.0
    return float(math.exp(x0 + (x1 - x0) * g0 / (g0 - g1)))


def unwrapped_phase_deg(h) -> np.ndarray:
    """Phase (deg) of a response ordered by frequency, unwrapped, starting in (-180, 180]."""
    return np.degrees(np.unwrap(np.angle(np.asarray(h))))


def phase_at(freq_hz, h, f_hz: float, phase_deg=None) -> float | None:
    """Unwrapped phase (deg) at ``f_hz``, interpolated in log frequency; None outside the data.

    ``phase_deg``: the phase already unwrapped (default: :func:`unwrapped_phase_deg`).
    """
    f = np.asarray(freq_hz, float)
    if not (f[0] * (1 - 1e-12) <= f_hz <= f[-1] * (1 + 1e-12)):
        return None
    ph = unwrapped_phase_deg(h) if phase_deg is None else np.asarray(phase_deg, float)
    return float(np.interp(math.log(f_hz), np.log(f), ph))


def equivalent_delay(freq_hz, h, f_max_hz: float | None = None, phase_deg=None) -> float | None:
    """Equivalent time delay (s): least-squares slope ``tau`` of ``phase = -w tau``.

    Over the frequencies up to ``f_max_hz`` (default: the -3 dB bandwidth, or
    all of them), through the origin: ``tau = -sum(phi w) / sum(w^2)``. A
    pure delay gives its value exactly; a first-order lag ``1/(tau s + 1)``
    gives ``tau`` at frequencies well below ``1/tau``. ``phase_deg`` as in :func:`phase_at`.
    """
    f = np.asarray(freq_hz, float)
    ph = np.radians(unwrapped_phase_deg(h) if phase_deg is None else np.asarray(phase_deg, float))
    if f_max_hz is None:
        f_max_hz = bandwidth_3db(f, h) or f[-1]
    keep = f <= f_max_hz * (1 + 1e-12)
    if keep.sum() < 1:
        return None
    w = 2 * np.pi * f[keep]
    return float(-np.sum(ph[keep] * w) / np.sum(w * w))
