"""Vehicle telemetry as UDP datagrams: the input of a live session (``simpro-sim live``).

The formats (:data:`FORMATS`): ``outsim`` and ``csv`` below, and the games'
packets of :mod:`simpro_mj.config.games` (Forza Sled, Dash and Horizon,
Codemasters ``extradata=3``, BeamNG MotionSim); ``auto`` (:class:`AutoDecoder`)
tells them apart by size. All are decoded to one sample ``(time_s, f, w)`` of the telemetry
format (:mod:`simpro_mj.config.telemetry`): the specific force ``f`` (gravity
included, +9.81 m/s^2 on ``z`` at rest) and the angular velocity ``w`` at the
driver's head, ISO 8855 vehicle frame V (x forward, y left, z up), SI.

``csv``
    One datagram is one ASCII line of the seven telemetry columns in their
    order, ``time_s,fx_mps2,fy_mps2,fz_mps2,wx_rad_s,wy_rad_s,wz_rad_s``
    (a trailing newline is allowed), at most :data:`MAX_CSV_BYTES` bytes.

``outsim``
    Live for Speed's OutSim packet, the format many games imitate:
    little-endian, 64 bytes, or 68 with the optional ``int ID``::

        unsigned Time_ms; float AngVel[3]; float Heading, Pitch, Roll;
        float Accel[3]; float Vel[3]; int Pos[3] (1 m = 65536); [int ID]

    World axes W: X right, Y forward, Z up (at heading 0 the car faces +Y).
    ``Heading`` turns anticlockwise about Z seen from above, ``Pitch`` about
    X (nose up > 0), ``Roll`` about Y (right-handed); radians. ``Accel`` is
    the car's acceleration in W *without* gravity; ``AngVel`` is read in W
    as well (the classic OutSim gives every vector in world axes; rates in
    the car's axes, the alternative reading, would need ``R`` left out of
    ``w``: docs/live.md).
    ``Vel`` and ``Pos`` are not used.

    The car's frame C (x right, y forward, z up) is W turned by
    ``R = Rz(Heading) Rx(Pitch) Ry(Roll)`` (heading first, then pitch about
    the turned X, then roll about the car's Y: :func:`car_to_world`), so a
    vector seen in C is ``R^T`` of it in W. V is C with x forward and y left:
    ``M = [[0, 1, 0], [-1, 0, 0], [0, 0, 1]]`` (a proper rotation: rates map
    like forces). Then::

        f_V = M R^T (Accel + (0, 0, g))      # gravity added: specific force a - g
        w_V = M R^T AngVel

    A car braking at 5 m/s^2 while facing +Y sends ``Accel = (0, -5, 0)``
    and gives ``f_V = (-5, 0, 9.81)``; facing -X (Heading = +90 deg) it
    sends ``(5, 0, 0)`` and gives the same.

A datagram that is too short, too long or does not decode to finite values
inside :data:`~simpro_mj.config.games.common.MAX_SPECIFIC_FORCE` / ``MAX_RATE`` raises
:class:`DatagramError` (its ``kind`` says which); the receiver counts and
skips it, never stops for it.

:func:`telemetry_datagrams` is the other way round, for ``simpro-sim send``:
a telemetry file resampled at a rate and packed in either format. For
``outsim`` the car's attitude is integrated from the file's rates (starting
level, heading 0) and ``Accel``, ``AngVel`` are packed in W through that
attitude, so the receiver's rotation is exercised, not bypassed; ``Vel`` and
``Pos`` are zero (a telemetry file does not hold them, and nothing reads them).
"""

from __future__ import annotations

import math
import struct

import numpy as np

from controllers.frames import GRAVITY
from simpro_mj.config.games import beamng, codemasters, forza
from simpro_mj.config.games.common import DatagramError
from simpro_mj.config.games.common import check as _check
from simpro_mj.config.telemetry import TELEMETRY_COLUMNS, Telemetry, resample

#: What ``send`` packs and ``live`` reads (``live`` also takes ``auto``).
SEND_FORMATS = ("outsim", "csv", "forza_sled", "forza_dash", "forza_horizon", "codemasters",
                "beamng")  # fmt: skip
FORMATS = (*SEND_FORMATS, "auto")
#: OutSim packet sizes: without and with the optional ID.
OUTSIM_BYTES = (64, 68)
_OUTSIM = struct.Struct("<I3f3f3f3f3i")
_OUTSIM_ID = struct.Struct("<I3f3f3f3f3ii")
#: Longest ``csv`` datagram (seven numbers at full precision take about 180 bytes).
MAX_CSV_BYTES = 512
#: Largest accepted attitude angle (rad) in an OutSim packet.
_MAX_ANGLE = 4.0 * math.pi


def car_to_world(heading: float, pitch: float, roll: float) -> tuple:
    """``R = Rz(heading) Rx(pitch) Ry(roll)`` as three row tuples (C -> W)."""
    ch, sh = math.cos(heading), math.sin(heading)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cr, sr = math.cos(roll), math.sin(roll)
    return (
        (ch * cr - sh * sp * sr, -sh * cp, ch * sr + sh * sp * cr),
        (sh * cr + ch * sp * sr, ch * cp, sh * sr - ch * sp * cr),
        (-cp * sr, sp, cp * cr),
    )


def _attitude(r) -> tuple[float, float, float]:
    """(heading, pitch, roll) of ``Rz Rx Ry`` (the inverse of :func:`car_to_world`)."""
    pitch = math.asin(max(-1.0, min(1.0, r[2][1])))
    roll = math.atan2(-r[2][0], r[2][2])
    heading = math.atan2(-r[0][1], r[1][1])
    return heading, pitch, roll


def world_to_vehicle(r, v) -> tuple[float, float, float]:
    """A W vector in V: ``M R^T v`` (module docstring)."""
    c0 = r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2]  # R^T v, car x (right)
    c1 = r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2]  # car y (forward)
    c2 = r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2]  # car z (up)
    return c1, -c0, c2


def vehicle_to_world(r, v) -> tuple[float, float, float]:
    """A V vector in W: ``R M^T v``."""
    c = (-v[1], v[0], v[2])  # M^T v: car (right, forward, up)
    return tuple(r[i][0] * c[0] + r[i][1] * c[1] + r[i][2] * c[2] for i in range(3))


def decode_outsim(data: bytes) -> tuple[float, tuple, tuple]:
    """``(time_s, f, w)`` in V from one OutSim packet (module docstring)."""
    n = len(data)
    if n not in OUTSIM_BYTES:
        kind = "short" if n < OUTSIM_BYTES[0] else "oversized"
        raise DatagramError(kind, f"{n} bytes; allowed: {' or '.join(map(str, OUTSIM_BYTES))}")
    v = (_OUTSIM if n == OUTSIM_BYTES[0] else _OUTSIM_ID).unpack(data)
    time_ms, ang, (heading, pitch, roll), acc = v[0], v[1:4], v[4:7], v[7:10]
    if (
        not all(map(math.isfinite, (heading, pitch, roll)))
        or max(abs(heading), abs(pitch), abs(roll)) > _MAX_ANGLE
    ):
        raise DatagramError("malformed", f"attitude {heading, pitch, roll} not in +-4 pi rad")
    r = car_to_world(heading, pitch, roll)
    f = world_to_vehicle(r, (acc[0], acc[1], acc[2] + GRAVITY))
    w = world_to_vehicle(r, ang)
    return _check(time_ms * 1e-3, f, w)


def decode_csv(data: bytes) -> tuple[float, tuple, tuple]:
    """``(time_s, f, w)`` from one ``csv`` line (module docstring)."""
    if len(data) > MAX_CSV_BYTES:
        raise DatagramError("oversized", f"{len(data)} bytes; allowed: <= {MAX_CSV_BYTES}")
    try:
        cells = data.decode("ascii").strip().split(",")
        vals = [float(c) for c in cells]
    except (UnicodeDecodeError, ValueError):
        raise DatagramError("malformed", "not a line of numbers") from None
    if len(vals) != len(TELEMETRY_COLUMNS):
        kind = "short" if len(vals) < len(TELEMETRY_COLUMNS) else "malformed"
        raise DatagramError(
            kind, f"{len(vals)} values; allowed: {len(TELEMETRY_COLUMNS)} ({TELEMETRY_COLUMNS})"
        )
    return _check(vals[0], tuple(vals[1:4]), tuple(vals[4:7]))


#: Datagram sizes of the binary formats (bytes) -> format, for ``auto``.
SIZES = {
    OUTSIM_BYTES[0]: "outsim",
    OUTSIM_BYTES[1]: "outsim",
    beamng.SIZE: "beamng",
    **{n: name for name, n in forza.SIZES.items()},
    codemasters.SIZE: "codemasters",
}


def make_decoder(fmt: str):
    """A callable ``data -> (time_s | None, f, w)`` for ``fmt`` (:data:`FORMATS`), raising
    :class:`DatagramError`; Codemasters' keeps state between packets (a new one per stream)."""
    # a Dash or Horizon packet has the Sled part first: one decoder for Forza's three
    stateless = {"outsim": decode_outsim, "csv": decode_csv, "beamng": beamng.decode}
    if fmt in stateless or fmt in forza.SIZES:
        return stateless.get(fmt, forza.decode)
    if fmt in ("codemasters", "auto"):
        return codemasters.Decoder() if fmt == "codemasters" else AutoDecoder()
    raise ValueError(f"format {fmt!r}; allowed: {', '.join(FORMATS)}")


def decode(fmt: str, data: bytes) -> tuple[float, tuple, tuple]:
    """Decode one datagram of a stateless format ``fmt`` (not ``codemasters`` or ``auto``)."""
    return make_decoder(fmt)(data)


class AutoDecoder:
    """``--format auto``: the first datagram that decodes fixes the format, told by its size.

    64/68 bytes OutSim, 88 BeamNG (magic ``BNG1``), 232/311/324 Forza Sled/Dash/Horizon,
    264 Codemasters; any other size is tried as a ``csv`` line. The sizes are distinct,
    so one good datagram is enough; a datagram that does not decode fixes nothing (it is
    counted by its kind). ``chosen`` names the format once fixed; ``on_choose(name)`` is
    called then (the session says it).
    """

    def __init__(self, on_choose=None):
        self.chosen: str | None = None
        self.on_choose = on_choose
        self._decoder = None

    def __call__(self, data: bytes):
        if self._decoder is not None:
            return self._decoder(data)
        name = SIZES.get(len(data), "csv")
        decoder = make_decoder(name)
        sample = decoder(data)  # a DatagramError leaves the choice open
        self.chosen, self._decoder = name, decoder
        if self.on_choose is not None:
            self.on_choose(name)
        return sample


def encode_csv(t: float, f, w) -> bytes:
    """One ``csv`` datagram."""
    return (",".join(f"{v:.9g}" for v in (t, *f, *w)) + "\n").encode("ascii")


def encode_outsim(t: float, f, w, attitude=(0.0, 0.0, 0.0)) -> bytes:
    """One OutSim packet of a V-frame sample, the car at ``attitude`` (heading, pitch, roll)."""
    r = car_to_world(*attitude)
    fw = vehicle_to_world(r, f)
    acc = (fw[0], fw[1], fw[2] - GRAVITY)
    ang = vehicle_to_world(r, w)
    fields = (int(round(t * 1e3)) & 0xFFFFFFFF, *ang, *attitude, *acc, 0.0, 0.0, 0.0, 0, 0, 0)
    return _OUTSIM.pack(*fields)


def _attitudes(w: np.ndarray, dt: float) -> list[tuple[float, float, float]]:
    """The car's attitude at each sample, integrated from V-frame rates (level, heading 0)."""
    r = np.eye(3)
    out = []
    for wv in w:
        out.append(_attitude(r))
        wc = np.array([-wv[1], wv[0], wv[2]]) * dt  # M^T w: car axes, rotation vector
        a = float(np.linalg.norm(wc))
        if a > 0.0:  # Rodrigues: R <- R exp([wc]x)
            k = wc / a
            kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
            r = r @ (np.eye(3) + math.sin(a) * kx + (1.0 - math.cos(a)) * (kx @ kx))
    return out


def telemetry_datagrams(tel: Telemetry, fmt: str, rate_hz: float) -> tuple[np.ndarray, list]:
    """(times, datagrams): ``tel`` resampled every ``1/rate_hz`` s and packed in ``fmt``.

    For the binary formats the car's attitude is integrated from the file's rates
    (level, heading 0) and each packet carries what that game would send of it:
    OutSim its world vectors, Forza and BeamNG the acceleration without gravity
    and the tilt angles, Codemasters the world velocity (integrated from the
    specific force less gravity) and the car's axes, taken after each sample's
    turn so that the receiver's difference of two packets gives that sample's rate.
    """
    n = int(math.floor(tel.t[-1] * rate_hz + 1e-9)) + 1
    t = np.arange(n) / rate_hz
    f, w = resample(tel, t)
    rows = list(zip(t.tolist(), f.tolist(), w.tolist(), strict=True))
    if fmt == "csv":
        return t, [encode_csv(*row) for row in rows]
    dt = 1.0 / rate_hz
    if fmt == "codemasters":
        att = _attitudes(np.vstack([w, w[-1:]]), dt)[1:]
        grams, v = [], np.zeros(3)
        for (ti, fi, _), a in zip(rows, att, strict=True):
            r = car_to_world(*a)
            fw = vehicle_to_world(r, fi)
            v = v + dt * np.array([fw[0], fw[1], fw[2] - GRAVITY])
            # the game's world: x right, y up, z forward (left-handed) = (X, Z, Y) of W
            swap = lambda u: (u[0], u[2], u[1])  # noqa: E731
            cols = [tuple(r[i][j] for i in range(3)) for j in range(2)]  # car right, forward
            grams.append(codemasters.encode(ti, swap(v.tolist()), swap(cols[1]), swap(cols[0])))
        return t, grams
    att = _attitudes(w, dt)
    grams = []
    for (ti, fi, wi), a in zip(rows, att, strict=True):
        if fmt == "outsim":
            grams.append(encode_outsim(ti, fi, wi, a))
            continue
        up = world_to_vehicle(car_to_world(*a), (0.0, 0.0, 1.0))
        if fmt == "beamng":
            grams.append(beamng.encode(fi, wi, up, a[0]))
        else:
            grams.append(forza.encode(fmt, ti, fi, wi, up, a[0]))
    return t, grams
