"""Forza "Data Out": the Sled (232 bytes), Dash (311) and Horizon (324) packets.

Layout (Turn 10's *Forza Motorsport Data Out Documentation*, the "Sled" and
"Car Dash" formats; Forza Horizon 4/5 insert 12 bytes after the Sled part and
end with one more byte), UDP, little-endian, sent at 60 Hz::

    offset  type    field
         0  s32     IsRaceOn            1 when driving, 0 in menus / paused
         4  u32     TimestampMS         wraps to 0 eventually
         8  f32 x3  EngineMaxRpm, EngineIdleRpm, CurrentEngineRpm
        20  f32 x3  AccelerationX, Y, Z   car's local space, X right, Y up, Z forward (m/s^2)
        32  f32 x3  VelocityX, Y, Z       same axes (m/s)
        44  f32 x3  AngularVelocityX, Y, Z   X pitch, Y yaw, Z roll (rad/s)
        56  f32 x3  Yaw, Pitch, Roll      (rad)
        68  ...     suspension, tyre slip, wheel speed, rumble, puddle, slip angle,
                    combined slip, suspension travel (9 x 4 values), then 5 x s32
                    (car ordinal, class, PI, drivetrain, cylinders): 232 bytes
       232  f32 x17, u16, u8 x6, s8 x3   the Dash part (position, speed, power, ... steer):
                    311 bytes; Horizon: the Dash part at 244, 324 bytes in all

Only the first 68 bytes are read: a Dash or Horizon packet is read as its
Sled part.

Readings (the documentation gives the axes, not the signs of the rotations
nor whether gravity is in the acceleration):

* The local space (X right, Y up, Z forward) is left-handed, as Direct3D's;
  its rotations (``AngularVelocity``, ``Pitch``, ``Roll``) are taken to turn
  by the left-hand rule in it, so that in V::

      w_V = (-wZ, wX, -wY)        roll rate, pitch rate (nose down > 0), yaw rate (left > 0)
      roll phi = -Roll,  pitch theta = Pitch   (ISO signs)

  The alternative, right-hand rotations in the same components, flips all
  three rates and both angles.
* ``Acceleration`` is the car's acceleration without gravity (it sits beside
  ``Velocity``, in the same space); gravity is added from ``Pitch`` and
  ``Roll``: ``f_V = (aZ, -aX, aY) + gravity_v(phi, theta)``. A game that puts
  gravity in would read ``fz`` about ``2 g`` at rest.

``IsRaceOn = 0`` is an ``idle`` packet: skipped, so the input fades to rest.
"""

from __future__ import annotations

import struct

from simpro_mj.config.games.common import DatagramError, check, gravity_v, tilt_v

#: Packet sizes by name.
SIZES = {"forza_sled": 232, "forza_dash": 311, "forza_horizon": 324}
_HEAD = struct.Struct("<iI3f3f3f3f3f")  # the first 68 bytes
_NAMES = {v: k for k, v in SIZES.items()}


def decode(data: bytes) -> tuple[float, tuple, tuple]:
    """``(time_s, f, w)`` in V from one Sled, Dash or Horizon packet (module docstring)."""
    n = len(data)
    if n not in _NAMES:
        kind = "short" if n < min(SIZES.values()) else "oversized"
        raise DatagramError(kind, f"{n} bytes; allowed: {sorted(SIZES.values())}")
    v = _HEAD.unpack_from(data)
    race_on, time_ms = v[0], v[1]
    acc, ang, (_, pitch, roll) = v[5:8], v[11:14], v[14:17]
    if race_on == 0:
        raise DatagramError("idle", "IsRaceOn = 0 (in menus or paused)")
    g = gravity_v(-roll, pitch)
    f = (acc[2] + g[0], -acc[0] + g[1], acc[1] + g[2])
    w = (-ang[2], ang[0], -ang[1])
    return check(time_ms * 1e-3, f, w)


def encode(fmt: str, t: float, f, w, up, yaw: float = 0.0) -> bytes:
    """One packet of ``fmt`` (:data:`SIZES`) for a V-frame sample of a car that sees the
    world's up as ``up`` (V); fields the decoder does not read are zero."""
    phi, theta = tilt_v(up)
    g = gravity_v(phi, theta)
    a = [f[i] - g[i] for i in range(3)]  # the car's acceleration without gravity, V
    head = _HEAD.pack(1, int(round(t * 1e3)) & 0xFFFFFFFF, 0.0, 0.0, 0.0,
                      -a[1], a[2], a[0], 0.0, 0.0, 0.0, w[1], -w[2], -w[0],
                      yaw, theta, -phi)  # fmt: skip
    return head + bytes(SIZES[fmt] - len(head))
