"""Codemasters' legacy UDP telemetry with ``extradata="3"`` (66 floats, 264 bytes).

Layout (the DiRT Rally / DiRT Rally 2.0 / GRID / F1 2017-and-earlier
"extradata" packet, set in ``hardware_settings_config.xml`` as
``<udp enabled="true" extradata="3" .../>``), UDP, 66 little-endian f32::

    index  field
        0  total_time (s)              1  lap_time     2  lap_distance   3  total_distance
      4-6  position x, y, z (world)    7  speed (m/s)
     8-10  velocity x, y, z (world, m/s)
    11-13  roll vector: the car's right axis in world axes (unit)
    14-16  pitch vector: the car's forward axis in world axes (unit)
    17-28  suspension position, velocity, wheel speed (4 each, RL RR FL FR)
    29-33  throttle, steer, brake, clutch, gear
    34-35  gforce_lat, gforce_lon (g)
    36-65  lap, rpm, ..., brake temperatures, tyre pressures, ..., max_rpm, idle_rpm, max_gears

There are no angular rates and no vertical force: the decoder derives the
sample from two packets in a row. With ``B`` the car's axes (forward, left,
up) in world axes and ``dt`` the difference of ``total_time``::

    f_V = B^T ((v_k - v_(k-1)) / dt + g up_world)      specific force, gravity added
    w_V = log(B_(k-1)^T B_k) / dt                      the turn between the packets

so both come out in V whatever the world's handedness (``B^T B`` is a proper
rotation either way). The first packet, or one after a gap of more than
:data:`MAX_GAP_S`, gives gravity alone and no rate (nothing to differentiate);
a packet not newer than the last is returned unchanged and leaves the state
alone (the receiver counts it late).

Readings: the world is y up and left-handed (x right, z forward at zero yaw,
Direct3D's), so the car's up is ``forward x right`` in components; a
right-handed world would flip the up axis. ``gforce_lat`` and ``gforce_lon``
are not used: their signs differ between titles, and the velocity gives the
same horizontal force with its signs known (half a packet period later).
"""

from __future__ import annotations

import math
import struct

from controllers.frames import GRAVITY
from simpro_mj.config.games.common import DatagramError, check

SIZE = 264
#: Longest interval (s) differentiated across; beyond it the stream restarts.
MAX_GAP_S = 0.5
_PACKET = struct.Struct("<66f")


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _unit(a):
    n = math.sqrt(_dot(a, a))
    if not n > 0.5:  # a unit vector, packed in float32
        raise DatagramError("malformed", f"axis {a} is not a unit vector")
    return (a[0] / n, a[1] / n, a[2] / n)


class Decoder:
    """The stateful decoder (module docstring): call it with each packet."""

    def __init__(self):
        self._last = None  # (t, v, axes, f, w)

    def __call__(self, data: bytes) -> tuple[float, tuple, tuple]:
        n = len(data)
        if n != SIZE:
            raise DatagramError("short" if n < SIZE else "oversized", f"{n} bytes; allowed: {SIZE}")
        p = _PACKET.unpack(data)
        if not all(map(math.isfinite, p[:17])):
            raise DatagramError("malformed", "a value is not finite")
        t, vel = p[0], p[8:11]
        right, fwd = _unit(p[11:14]), _unit(p[14:17])
        up = _unit(_cross(fwd, right))
        axes = (fwd, (-right[0], -right[1], -right[2]), up)  # V's axes in world axes
        last = self._last
        if last is not None and t <= last[0]:
            return check(t, last[3], last[4])
        grav = (0.0, GRAVITY, 0.0)
        if last is None or t - last[0] > MAX_GAP_S:
            fw, w = grav, (0.0, 0.0, 0.0)
        else:
            dt = t - last[0]
            fw = tuple((vel[i] - last[1][i]) / dt + grav[i] for i in range(3))
            w = _rate(last[2], axes, dt)
        f = tuple(_dot(a, fw) for a in axes)
        self._last = (t, vel, axes, f, w)
        return check(t, f, w)


def _rate(prev, now, dt: float) -> tuple[float, float, float]:
    """``log(B_prev^T B_now) / dt`` as a vector in V (the body's turn between two packets)."""
    r = [[_dot(prev[i], now[j]) for j in range(3)] for i in range(3)]
    c = max(-1.0, min(1.0, (r[0][0] + r[1][1] + r[2][2] - 1.0) / 2.0))
    angle = math.acos(c)
    k = 0.5 if angle < 1e-6 else angle / (2.0 * math.sin(angle))
    return (
        k * (r[2][1] - r[1][2]) / dt,
        k * (r[0][2] - r[2][0]) / dt,
        k * (r[1][0] - r[0][1]) / dt,
    )


def encode(t: float, vel_world, fwd_world, right_world) -> bytes:
    """One packet: time, world velocity and the car's forward and right axes (world axes,
    y up, left-handed); fields the decoder does not read are zero."""
    vals = [0.0] * 66
    vals[0] = t
    vals[7] = math.sqrt(_dot(vel_world, vel_world))
    vals[8:11], vals[11:14], vals[14:17] = vel_world, right_world, fwd_world
    return _PACKET.pack(*vals)
