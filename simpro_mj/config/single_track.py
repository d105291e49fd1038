"""A braking in a turn from CommonRoad's single-track model, which the shipped drives are not
made with.

The shipped telemetry (:mod:`simpro_mj.config.manoeuvres`) comes from CommonRoad's
multi-body model: a sprung mass that rolls and pitches on its suspension, Pacejka
tyres. The cueing law's parameters were chosen on those drives. This module drives the
same manoeuvre through another model of the same library, the single-track model
(``vehiclemodels.vehicle_dynamics_st``: Althoff & Würsching, "CommonRoad: Vehicle
Models", 2020, section 5: one axle's linear cornering stiffness each, the load transfer
from the longitudinal acceleration, no suspension, so no roll or pitch of the body), so
that the chain can be judged on a drive it was not tuned on.

The manoeuvre is ``braking_turn``'s (:mod:`simpro_mj.config.manoeuvres`): 60 km/h, a left
turn of constant curvature (3 m/s^2 at the entry speed) from ``lead_s`` for 3 s, steered
by the kinematic angle ``atan(L k)`` through a first-order servo (20 1/s), braking at
``deceleration_mps2`` (0.4 s ramps) from 1.5 s into the turn for 2 s, then straight on.
The model's own steering and acceleration limits apply
(``vehiclemodels.utils.steering_constraints``, ``acceleration_constraints``).

Head signals (V frame, ISO 8855, SI): the body's velocity ``v (cos b, sin b)`` (speed
``v``, side slip ``b``) and yaw rate ``r`` give the centre of gravity's acceleration
``(v' cos b - v sin b (b' + r), v' sin b + v cos b (b' + r))``; the head is
:data:`~simpro_mj.config.manoeuvres.HEAD_OFFSET` from it (``r' x p + r x (r x p)``); the
body does not roll or pitch, so ``f_z = g`` and ``w = (0, 0, r)``.

An optional extra (``pip install "simpro-sim[vehicle]"``), as the multi-body drives.
"""

from __future__ import annotations

import math

import numpy as np

from simpro_mj.config.manoeuvres import (
    BRAKE_AFTER_S,
    BRAKE_S,
    GRAVITY_MB,
    HEAD_OFFSET,
    TURN_LATERAL_MPS2,
    TURN_S,
    VEHICLES,
    ManoeuvreError,
    _params,
)
from simpro_mj.config.telemetry import Telemetry

#: Steering servo bandwidth (1/s) and the brake ramp (s), as the multi-body drives'.
STEER_SERVO = 20.0
RAMP_S = 0.4
#: Integration step (s): RK4, five steps per output sample at 200 Hz; the fastest mode is
#: the steering servo's (50 ms), so 1 ms resolves it (halved, the head's specific force
#: moves by at most 0.01 m/s^2, at the brake ramps' corners).
STEP_S = 1e-3


def _accel(t: float, lead: float, decel: float) -> float:
    """The longitudinal acceleration command: the braking with its ramps."""
    t0 = lead + BRAKE_AFTER_S
    up = np.clip((t - t0) / RAMP_S, 0.0, 1.0)
    down = np.clip((t - (t0 + BRAKE_S)) / RAMP_S, 0.0, 1.0)
    return -decel * float(up - down)


def braking_turn_single_track(
    speed_kmh: float = 60.0,
    deceleration_mps2: float = 6.0,
    lead_s: float = 1.0,
    duration_s: float = 12.0,
    rate_hz: float = 200.0,
    vehicle: str = "bmw_320i",
) -> Telemetry:
    """The braking in a turn of :mod:`simpro_mj.config.manoeuvres` from the single-track
    model (module docstring): a :class:`Telemetry` at the driver's head, ``rate_hz``."""
    if vehicle not in VEHICLES:
        raise ManoeuvreError(f"invalid value at vehicle: {vehicle!r}; allowed: {sorted(VEHICLES)}")
    p = _params(vehicle, "commonroad")  # the published set: no tyre of this model reads them
    from vehiclemodels.vehicle_dynamics_st import vehicle_dynamics_st  # the optional extra

    v0 = speed_kmh / 3.6
    wheelbase = p.a + p.b
    steer_turn = math.atan(wheelbase * TURN_LATERAL_MPS2 / v0**2)

    def rhs(t: float, x: np.ndarray) -> tuple[np.ndarray, float]:
        target = steer_turn if lead_s <= t < lead_s + TURN_S else 0.0
        u = [STEER_SERVO * (target - x[2]), _accel(t, lead_s, deceleration_mps2)]
        return np.asarray(vehicle_dynamics_st(list(x), u, p), float), u[1]

    every = int(round(1.0 / (rate_hz * STEP_S)))
    n = int(round(duration_s * rate_hz)) + 1
    x = np.array([0.0, 0.0, 0.0, v0, 0.0, 0.0, 0.0])
    xs = np.empty((n, 7))
    dxs = np.empty((n, 7))
    t = 0.0
    for i in range(n):
        xs[i] = x
        dxs[i] = rhs(t, x)[0]
        if i == n - 1:
            break
        for _ in range(every):
            k1 = rhs(t, x)[0]
            k2 = rhs(t + STEP_S / 2, x + STEP_S / 2 * k1)[0]
            k3 = rhs(t + STEP_S / 2, x + STEP_S / 2 * k2)[0]
            k4 = rhs(t + STEP_S, x + STEP_S * k3)[0]
            x = x + STEP_S / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            t += STEP_S
    tt = np.arange(n) / rate_hz
    v, b, r = xs[:, 3], xs[:, 6], xs[:, 5]
    dv, db, dr = dxs[:, 3], dxs[:, 6], dxs[:, 5]
    ax = dv * np.cos(b) - v * np.sin(b) * (db + r)
    ay = dv * np.sin(b) + v * np.cos(b) * (db + r)
    px, py, _ = HEAD_OFFSET
    f = np.zeros((n, 3))
    f[:, 0] = ax - dr * py - r * r * px
    f[:, 1] = ay + dr * px - r * r * py
    f[:, 2] = GRAVITY_MB
    w = np.zeros((n, 3))
    w[:, 2] = r
    tel = Telemetry(
        t=tt,
        f=f,
        w=w,
        source=(
            f"braking_turn {speed_kmh:g} km/h, {deceleration_mps2:g} m/s^2, {vehicle} "
            "(commonroad single-track, vehicle_dynamics_st)"
        ),
    )
    tel.extra = {"speed_mps": v.copy(), "x_m": xs[:, 0].copy(), "y_m": xs[:, 1].copy()}
    return tel
