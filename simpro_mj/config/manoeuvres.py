"""Vehicle manoeuvres for the cueing chain, from commonroad-vehicle-models.

The vehicle is the CommonRoad multi-body model (Althoff & Würsching,
"CommonRoad: Vehicle Models", 2020; ``vehiclemodels.vehicle_dynamics_mb``:
sprung mass with roll and pitch, unsprung masses, Pacejka tyres) with one of
its published parameter sets (:data:`VEHICLES`). It is an optional extra:
``pip install "simpro-sim[vehicle]"``. The shipped scenarios read telemetry
files made with it (``scenarios/telemetry/``), so running them does
not need it; ``simpro-sim manoeuvre`` makes more.

Tyres (:data:`TYRE_OFFSETS`)
    CommonRoad's lateral magic formula (``vehiclemodels.utils.tire_model``)
    adds the tyre's offsets ``p_hy1`` (0.0027 rad) and ``p_vy1`` (0.037 F_z)
    with the sign of the camber, ``sign(gamma) (p_hy1 + p_hy3 |gamma|)``: a
    relay of about 0.1 F_z per tyre that flips whenever a wheel's camber
    crosses zero, as it does at every small roll of a car driven straight.
    In the model that relay is a roll limit cycle (0.46 deg peak to peak, 1.6 Hz,
    1.05 m/s^2 of sway at the head peak to peak, driven straight at 60 km/h; gone,
    1e-9 deg, without the offsets). A tyre's force is continuous in camber, so
    the default ``tyre_offsets: none`` sets ``p_hy1 = p_vy1 = 0`` on this run's
    parameter set (the camber terms stay, now ``p_hy3 gamma``, ``p_vy3 gamma F_z``);
    ``commonroad`` keeps the published relay. Pacejka's MF 5.2 reading (the
    offsets without the sign, ``p_hy1 + p_hy3 gamma``) holds still too (roll 2e-9 deg
    peak to peak) with the car crabbing 0.07 m sideways in 4 s; it needs the
    library's function replaced, so it is not offered (docs/paper-notes.md).

A driver model closes the loop: speed held by a proportional acceleration
command, the path followed by pure pursuit (look-ahead ``0.5 s`` of travel
plus 5 m) with a first-order steering servo (20 1/s) under the model's own
steering-rate limit.

Manoeuvres (:data:`MANOEUVRES`)
    ``braking``: constant speed, then a ramp (0.4 s) to a constant
    deceleration (default 5 m/s^2, firm braking), eased off in proportion to
    the speed below 3 m/s (a comfort stop); at 0.2 m/s the vehicle is taken
    as stopped (the model turns stiff as its wheels stop) and rests.
    ``lane_change``: ISO 3888-1 double lane change: 15 m entry lane, 30 m
    offset, 25 m offset lane, 25 m back, 30 m exit; the lateral offset of the
    lane centres is ``1.1 w / 2 + 0.125 + 1 + (w + 1) / 2`` (3.32 m for the
    1.61 m BMW 320i); centre line joined by cosine half-waves.
    ``slalom``: cones every 18 m, the path a sine of amplitude 1 m through them.
    ``braking_turn``: a left turn of constant curvature (:data:`TURN_LATERAL_MPS2`
    at the entry speed, steered by the kinematic angle ``atan(L k)`` through the
    servo) from ``lead_s`` for :data:`TURN_S`, braking at ``deceleration_mps2`` (ramps
    of 0.4 s) from :data:`BRAKE_AFTER_S` into the turn for :data:`BRAKE_S`, then
    rolling on at the speed reached, straight.
    ``bump``: a cosine road bump (default 60 mm high, 0.5 m long) crossed by
    both axles. The multi-body model has no road input, so this one uses a
    half-car (bounce and pitch of the sprung mass, one unsprung mass per axle)
    built from the same parameter set (masses, pitch inertia, axle distances,
    suspension and tyre rates), simulated by ``scipy.signal.lsim``.

Output: :class:`~simpro_mj.config.telemetry.Telemetry` at the driver's head, vehicle
frame V (ISO 8855). The model's states are in a yaw-aligned frame with x
forward and y left (its lateral velocity is ISO's: negative sideslip in a
fast left turn); its roll and pitch angles have the opposite sign to ISO's
(a left turn rolls the body outwards, right side down, and the model's roll
angle is then negative; braking dives the nose and its pitch is negative),
so ``roll_iso = -x7``, ``pitch_iso = -x9`` (pinned by tests). The head is
``HEAD_OFFSET`` from the sprung mass' centre of gravity; its specific force
is ``R^T (a_cg + (0, 0, g)) + dw x r + w x (w x r)``.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass

import numpy as np

from simpro_mj.config.telemetry import Telemetry
from simpro_mj.core.errors import UserInputError

MANOEUVRES = ("braking", "lane_change", "slalom", "bump", "braking_turn")
#: ``braking_turn``: the turn starts at ``lead_s`` and lasts TURN_S; the braking starts
#: BRAKE_AFTER_S into the turn and lasts BRAKE_S; the turn's curvature gives
#: TURN_LATERAL_MPS2 at the entry speed (a brisk country-road bend).
TURN_S, BRAKE_AFTER_S, BRAKE_S, TURN_LATERAL_MPS2 = 3.0, 1.5, 2.0, 3.0
#: ``ManoeuvreSpec.tyre_offsets``: ``none`` (the lateral offsets p_hy1, p_vy1 at 0:
#: the force continuous in camber) or ``commonroad`` (the published sign(camber) relay).
TYRE_OFFSETS = ("none", "commonroad")
#: CommonRoad parameter sets (``vehiclemodels.parameters_vehicleN``); 4 is a trailer truck.
VEHICLES = {"ford_escort": 1, "bmw_320i": 2, "vw_vanagon": 3}
#: Driver's head from the sprung mass' centre of gravity, V frame (m): 0.3 m behind
#: it, 0.35 m to the left (left-hand drive), 0.65 m above (head ~1.2 m above the road
#: with the centre of gravity at ~0.55 m). Assumption.
HEAD_OFFSET = (-0.3, 0.35, 0.65)
GRAVITY_MB = 9.81  # the model's own g (vehicle_dynamics_mb)
#: Straight driving before a manoeuvre's time 0, to let the suspension settle (s).
SETTLE_S = 3.0


class ManoeuvreError(UserInputError):
    """A manoeuvre that cannot be generated (unknown name, range, missing extra)."""


@dataclass(frozen=True)
class ManoeuvreSpec:
    """What to generate. ``speed_kmh`` is the entry speed; ``duration_s`` None = automatic."""

    manoeuvre: str
    speed_kmh: float
    vehicle: str = "bmw_320i"
    deceleration_mps2: float = 5.0
    bump_height_m: float = 0.06
    bump_length_m: float = 0.5
    lead_s: float = 1.0
    duration_s: float | None = None
    rate_hz: float = 200.0
    tyre_offsets: str = "none"

    def check(self) -> None:
        choices = {"manoeuvre": MANOEUVRES, "tyre_offsets": TYRE_OFFSETS, "vehicle": VEHICLES}
        for key, allowed in choices.items():
            if (value := getattr(self, key)) not in allowed:
                allowed = sorted(allowed) if isinstance(allowed, dict) else list(allowed)
                raise ManoeuvreError(f"invalid value at {key}: {value!r}; allowed: {allowed}")
        rng = {
            "speed_kmh": (10.0, 180.0),
            "deceleration_mps2": (0.5, 10.0),
            "bump_height_m": (0.0, 0.2),
            "bump_length_m": (0.1, 10.0),
            "lead_s": (0.0, 10.0),
            "rate_hz": (20.0, 1000.0),
        }
        for k, (lo, hi) in rng.items():
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and lo <= v <= hi):
                raise ManoeuvreError(f"invalid value at {k}: {v!r}; allowed: {lo}..{hi}")
        if self.duration_s is not None and not (1.0 <= self.duration_s <= 600.0):
            raise ManoeuvreError(
                f"invalid value at duration_s: {self.duration_s!r}; allowed: 1..600 or null"
            )


def available() -> bool:
    """True if commonroad-vehicle-models is installed."""
    try:  # commonroad-vehicle-models is an optional extra ([vehicle])
        import vehiclemodels  # noqa: F401
    except ImportError:
        return False
    return True


def _params(vehicle: str, tyre_offsets: str = "none"):
    """A fresh parameter set of ``vehicle`` with its tyres per ``tyre_offsets``."""
    name = f"parameters_vehicle{VEHICLES[vehicle]}"
    try:  # the optional extra [vehicle]
        make = getattr(importlib.import_module(f"vehiclemodels.{name}"), name)
    except ImportError:
        raise ManoeuvreError(
            "manoeuvres need commonroad-vehicle-models: pip install 'simpro-sim[vehicle]' "
            "(or give a telemetry file)"
        ) from None
    p = make()  # a new object per call: the change below stays in this run
    if tyre_offsets == "none":
        p.tire.p_hy1 = 0.0
        p.tire.p_vy1 = 0.0
    return p


# ---------------------------------------------------------------- paths


def lane_change_path(width: float):
    """ISO 3888-1 centre line y(x) (x from the start of the entry lane), m."""
    offset = (1.1 * width + 0.25) / 2 + 1.0 + (width + 1.0) / 2
    x1, x2, x3, x4 = 15.0, 45.0, 70.0, 95.0

    def y(x):
        x = np.asarray(x, float)
        up = 0.5 * (1 - np.cos(np.pi * np.clip((x - x1) / (x2 - x1), 0, 1)))
        down = 0.5 * (1 - np.cos(np.pi * np.clip((x - x3) / (x4 - x3), 0, 1)))
        return offset * (up - down)

    return y, 125.0, offset


def slalom_path(spacing: float = 18.0, amplitude: float = 1.0, cones: int = 6):
    """Sine through ``cones`` cones ``spacing`` apart, starting 15 m in; y(x), end, amplitude."""
    x0 = 15.0
    end = x0 + spacing * (cones - 1)

    def y(x):
        x = np.asarray(x, float)
        s = np.clip((x - x0) / spacing, 0, cones - 1)
        return amplitude * np.sin(np.pi * s)

    return y, end + 20.0, amplitude


# ---------------------------------------------------------------- multi-body runs


def _run_mb(
    p, v0: float, t_end: float, steer_fn, acc_fn, rate_hz: float, v_stop=None, method="RK45"
):
    """The multi-body model on a ``rate_hz`` grid to ``t_end``, at rest from ``v_stop`` on (its
    wheels turn stiff below 0.1 m/s); ``method``: solve_ivp's (LSODA where tyres turn stiff)."""
    from scipy.integrate import solve_ivp  # on use: scipy's import is most of a --help

    # commonroad-vehicle-models is an optional extra ([vehicle]): imported when used
    from vehiclemodels.init_mb import init_mb
    from vehiclemodels.vehicle_dynamics_mb import vehicle_dynamics_mb

    x0 = init_mb([0.0, 0.0, 0.0, v0, 0.0, 0.0, 0.0], p)

    def rhs(t, x):
        return vehicle_dynamics_mb(x, [steer_fn(t, x), acc_fn(t, x)], p)

    # init_mb's suspension state is not the loaded equilibrium: the body bounces
    # (+-1 m/s^2) for ~2 s. Drive SETTLE_S straight at v0 first and start from there.
    t_settle = np.linspace(0.0, SETTLE_S, 3)
    pre = solve_ivp(
        lambda t, x: vehicle_dynamics_mb(x, [0.0, 2.0 * (v0 - x[3])], p),
        (0.0, SETTLE_S), x0, t_eval=t_settle, max_step=0.005, rtol=1e-6, atol=1e-8,
    )  # fmt: skip
    x0 = pre.y[:, -1].copy()
    x0[0] = x0[1] = x0[4] = 0.0  # back to the origin, heading along x

    events = None
    if v_stop is not None:

        def stopped(t, x):
            return x[3] - v_stop

        # solve_ivp's event attributes: end the integration when the speed falls through
        stopped.terminal = True  # type: ignore[attr-defined]
        stopped.direction = -1  # type: ignore[attr-defined]
        events = [stopped]
    t_eval = np.arange(0.0, t_end + 0.5 / rate_hz, 1.0 / rate_hz)
    sol = solve_ivp(
        rhs, (0.0, t_eval[-1]), x0, t_eval=t_eval, max_step=0.005, rtol=1e-6, atol=1e-8,
        events=events, method=method,
    )  # fmt: skip
    if sol.status < 0:
        raise ManoeuvreError(f"the vehicle model did not integrate: {sol.message}")
    x = sol.y.T
    dx = np.array([rhs(t, xi) for t, xi in zip(sol.t, x, strict=True)])
    n_rest = t_eval.size - sol.t.size
    if n_rest:  # at rest: position and attitude held, nothing moves
        rest = np.repeat(x[-1:], n_rest, axis=0)
        rest[:, 3:4] = 0.0
        rest[:, [5, 7, 9, 10, 12, 14, 15, 17, 19, 20, 22, 23, 24, 25, 26]] = 0.0
        x = np.vstack([x, rest])
        dx = np.vstack([dx, np.zeros((n_rest, dx.shape[1]))])
    return t_eval, x, dx


def _head_signals(t, x, dx, head=HEAD_OFFSET) -> Telemetry:
    """Specific force and angular velocity at the head, V frame, from MB states."""
    vx, vy, r = x[:, 3], x[:, 10], x[:, 5]
    ax = dx[:, 3] - r * vy
    ay = dx[:, 10] + r * vx
    az = dx[:, 12]
    roll, pitch = -x[:, 6], -x[:, 8]  # ISO signs (module docstring)
    droll, dpitch = -x[:, 7], -x[:, 9]
    ddroll, ddpitch, dr = -dx[:, 7], -dx[:, 9], dx[:, 5]
    f_yaw = np.stack([ax, ay, az + GRAVITY_MB], axis=-1)
    # R = Ry(pitch) Rx(roll) (ISO 8855 attitude of the body in the yaw frame); f_body = R^T f
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    fx = cp * f_yaw[:, 0] - sp * f_yaw[:, 2]
    fy = sr * sp * f_yaw[:, 0] + cr * f_yaw[:, 1] + sr * cp * f_yaw[:, 2]
    fz = cr * sp * f_yaw[:, 0] - sr * f_yaw[:, 1] + cr * cp * f_yaw[:, 2]
    w = np.stack([droll, dpitch, r], axis=-1)  # body rates, small-angle
    dw = np.stack([ddroll, ddpitch, dr], axis=-1)
    rr = np.broadcast_to(np.asarray(head, float), w.shape)
    f = np.stack([fx, fy, fz], axis=-1) + np.cross(dw, rr) + np.cross(w, np.cross(w, rr))
    return Telemetry(t=t, f=f, w=w, source="")


def _pure_pursuit(path_y, p, lead_x: float):
    wheelbase = p.a + p.b

    def steer(t, x):
        px, py, yaw, v = x[0], x[1], x[4], max(x[3], 1.0)
        look = 0.5 * v + 5.0
        gx = px + look * math.cos(yaw)
        gy = float(path_y(gx - lead_x))
        alpha = math.atan2(gy - py, gx - px) - yaw
        delta = math.atan2(2.0 * wheelbase * math.sin(alpha), look)
        return 20.0 * (delta - x[2])  # steering servo; the model limits the rate

    return steer


def _hold_speed(v_set: float):
    return lambda t, x: 2.0 * (v_set - x[3])


def generate(spec: ManoeuvreSpec) -> Telemetry:
    """Run one manoeuvre; returns head telemetry (V frame) at ``spec.rate_hz``."""
    spec.check()
    p = _params(spec.vehicle, spec.tyre_offsets)
    v0 = spec.speed_kmh / 3.6
    lead = spec.lead_s
    if spec.manoeuvre == "braking":
        a_b = spec.deceleration_mps2
        t_stop = lead + 0.2 + v0 / a_b + 1.0
        t_end = spec.duration_s or (t_stop + 5.0)

        def acc(t, x):
            # below 3 m/s the driver eases off (a comfort stop: deceleration
            # proportional to speed); the run ends at 0.2 m/s (-0.33 m/s^2)
            ramp = min(max((t - lead) / 0.4, 0.0), 1.0)
            return -a_b * ramp * min(1.0, x[3] / 3.0)

        t, x, dx = _run_mb(p, v0, t_end, lambda t, x: 0.0, acc, spec.rate_hz, v_stop=0.2)
    elif spec.manoeuvre in ("lane_change", "slalom"):
        if spec.manoeuvre == "lane_change":
            path, length, _ = lane_change_path(p.w)
        else:
            path, length, _ = slalom_path()
        lead_x = v0 * lead
        t_end = spec.duration_s or (lead + length / v0 + 5.0)
        t, x, dx = _run_mb(
            p, v0, t_end, _pure_pursuit(path, p, lead_x), _hold_speed(v0), spec.rate_hz
        )
    elif spec.manoeuvre == "braking_turn":
        t, x, dx = _braking_turn(spec, p, v0)
    else:
        return _bump(spec, p, v0)
    tel = _head_signals(t, x, dx)
    tel.source = f"{spec.manoeuvre} {spec.speed_kmh:g} km/h, {spec.vehicle} (commonroad MB)"
    tel.extra = {"speed_mps": x[:, 3].copy(), "x_m": x[:, 0].copy(), "y_m": x[:, 1].copy()}
    return tel


def _braking_turn(spec: ManoeuvreSpec, p, v0: float):
    """States of :data:`MANOEUVRES`' ``braking_turn`` (module docstring)."""
    lead, a_b = spec.lead_s, spec.deceleration_mps2
    turn = (lead, lead + TURN_S)
    brake = (lead + BRAKE_AFTER_S, lead + BRAKE_AFTER_S + BRAKE_S)
    delta = math.atan((p.a + p.b) * TURN_LATERAL_MPS2 / v0**2)

    def window(t, start, end):
        return min(max((t - start) / 0.4, 0.0), 1.0) - min(max((t - end) / 0.4, 0.0), 1.0)

    def steer(t, x):
        return 20.0 * (delta * window(t, *turn) - x[2])  # the servo of _pure_pursuit

    def acc(t, x):
        if t < brake[0]:
            return 2.0 * (v0 - x[3])  # speed held, then braking, then rolling on
        return -a_b * window(t, *brake) * min(1.0, x[3] / 3.0)

    t_end = spec.duration_s or (brake[1] + 4.0)
    return _run_mb(p, v0, t_end, steer, acc, spec.rate_hz, v_stop=0.2, method="LSODA")


def _bump(spec: ManoeuvreSpec, p, v0: float) -> Telemetry:
    """Half-car over a cosine bump (see the module docstring)."""
    ms, iy, a, b = p.m_s, p.I_y_s, p.a, p.b
    muf, mur = p.m_uf, p.m_ur
    ksf, ksr, csf, csr = 2 * p.K_sf, 2 * p.K_sr, 2 * p.K_sdf, 2 * p.K_sdr  # per axle
    kt = 2 * p.K_zt
    # state: z, theta (nose down +, ISO pitch), zf, zr and their rates; inputs: road
    # heights under the front and rear axles. Suspension deflections: front
    # z - a theta - zf, rear z + b theta - zr (nose down lowers the front).
    m = np.diag([ms, iy, muf, mur])
    k = np.array(
        [
            [ksf + ksr, -a * ksf + b * ksr, -ksf, -ksr],
            [-a * ksf + b * ksr, a * a * ksf + b * b * ksr, a * ksf, -b * ksr],
            [-ksf, a * ksf, ksf + kt, 0.0],
            [-ksr, -b * ksr, 0.0, ksr + kt],
        ]
    )
    c = np.array(
        [
            [csf + csr, -a * csf + b * csr, -csf, -csr],
            [-a * csf + b * csr, a * a * csf + b * b * csr, a * csf, -b * csr],
            [-csf, a * csf, csf, 0.0],
            [-csr, -b * csr, 0.0, csr],
        ]
    )
    kr = np.array([[0.0, 0.0], [0.0, 0.0], [kt, 0.0], [0.0, kt]])
    mi = np.linalg.inv(m)
    amat = np.block([[np.zeros((4, 4)), np.eye(4)], [-mi @ k, -mi @ c]])
    bmat = np.vstack([np.zeros((4, 2)), mi @ kr])
    cmat = np.vstack([amat[4:6], np.eye(8)[5:6]])  # z'', theta'', theta'
    dmat = np.vstack([bmat[4:6], np.zeros((1, 2))])
    from scipy import signal  # on use: scipy.signal's import is most of a --help

    sys = signal.StateSpace(amat, bmat, cmat, dmat)
    t_end = spec.duration_s or (spec.lead_s + (a + b + spec.bump_length_m) / v0 + 3.0)
    t = np.arange(0.0, t_end + 0.5 / spec.rate_hz, 1.0 / spec.rate_hz)

    def road(s):
        u = np.clip(s / spec.bump_length_m, 0.0, 1.0)
        return spec.bump_height_m * 0.5 * (1 - np.cos(2 * np.pi * u))

    s_front = v0 * (t - spec.lead_s)
    u = np.stack([road(s_front), road(s_front - (a + b))], axis=-1)
    _, y, _ = signal.lsim(sys, u, t)
    zdd, thdd, thd = y[:, 0], y[:, 1], y[:, 2]
    n = t.size
    w = np.stack([np.zeros(n), thd, np.zeros(n)], axis=-1)
    dw = np.stack([np.zeros(n), thdd, np.zeros(n)], axis=-1)
    rr = np.broadcast_to(np.asarray(HEAD_OFFSET, float), w.shape)
    f = np.stack([np.zeros(n), np.zeros(n), zdd + GRAVITY_MB], axis=-1)
    f = f + np.cross(dw, rr) + np.cross(w, np.cross(w, rr))
    tel = Telemetry(
        t=t, f=f, w=w, source=f"bump {spec.speed_kmh:g} km/h, {spec.vehicle} (half-car)"
    )
    tel.extra = {"speed_mps": np.full(n, v0)}
    return tel
