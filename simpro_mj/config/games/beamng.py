"""BeamNG.drive's MotionSim packet ("BNG1", 88 bytes).

Layout (``lua/vehicle/motionSim.lua`` of BeamNG.drive, its ``motionSim_t``;
documentation.beamng.com, "Protocols"), UDP, little-endian, at the rate set in
Options > Other (50-100 Hz)::

    offset  type    field
         0  char x4 magic                 "BNG1"
         4  f32 x3  posX, posY, posZ      world position (m)
        16  f32 x3  velX, velY, velZ      velocity (m/s)
        28  f32 x3  accX, accY, accZ      acceleration of the car, gravity not included (m/s^2)
        40  f32 x3  upVecX, upVecY, upVecZ   the car's up in world axes
        52  f32 x3  rollPos, pitchPos, yawPos    (rad)
        64  f32 x3  rollRate, pitchRate, yawRate (rad/s)
        76  f32 x3  rollAcc, pitchAcc, yawAcc    (rad/s^2)

The packet has no time stamp: samples are ordered by arrival.

Readings (the struct names the quantities, not their axes and signs):

* ``acc`` in the car's axes x right, y forward, z up (what motion software
  reads as sway, surge, heave), gravity not included as the struct says,
  added from the angles: ``f_V = (accY, -accX, accZ) + gravity_v(phi, theta)``;
* the angles and rates in the motion-rig convention the Lua's "negated angle"
  comment refers to: roll right side down > 0, pitch nose up > 0, yaw left
  > 0, so ``phi = rollPos``, ``theta = -pitchPos`` and
  ``w_V = (rollRate, -pitchRate, yawRate)``. The alternative (pitch nose down
  > 0) flips ``wy`` and the gravity's ``fx``.
"""

from __future__ import annotations

import struct

from simpro_mj.config.games.common import DatagramError, check, gravity_v, tilt_v

SIZE = 88
MAGIC = b"BNG1"
_PACKET = struct.Struct("<4s21f")


def decode(data: bytes) -> tuple[None, tuple, tuple]:
    """``(None, f, w)`` in V from one MotionSim packet (module docstring)."""
    n = len(data)
    if n != SIZE:
        raise DatagramError("short" if n < SIZE else "oversized", f"{n} bytes; allowed: {SIZE}")
    v = _PACKET.unpack(data)
    if v[0] != MAGIC:
        raise DatagramError("malformed", f"magic {v[0]!r}; allowed: {MAGIC!r}")
    acc, (roll, pitch, _), rate = v[7:10], v[13:16], v[16:19]
    g = gravity_v(roll, -pitch)
    f = (acc[1] + g[0], -acc[0] + g[1], acc[2] + g[2])
    return check(None, f, (rate[0], -rate[1], rate[2]))


def encode(f, w, up, yaw: float = 0.0) -> bytes:
    """One MotionSim packet of a V-frame sample, the car seeing the world's up as ``up`` (V)."""
    phi, theta = tilt_v(up)
    g = gravity_v(phi, theta)
    a = [f[i] - g[i] for i in range(3)]
    return _PACKET.pack(MAGIC, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -a[1], a[0], a[2],
                        0.0, 0.0, 1.0, phi, -theta, yaw, w[0], -w[1], w[2],
                        0.0, 0.0, 0.0)  # fmt: skip
