"""Games' telemetry packets: each format's decoder against its packer, its signs on a
known case, ``--format auto`` and the same drive through a loopback socket in every format.

Network use is loopback only and bounded: each datagram is sent, waited for with a
bounded ``select`` and read before the next.
"""

from __future__ import annotations

import math
import select
import socket
import struct

import numpy as np
import pytest

from controllers.frames import GRAVITY
from simpro_mj.config.datagrams import (
    FORMATS,
    SEND_FORMATS,
    SIZES,
    AutoDecoder,
    make_decoder,
    telemetry_datagrams,
)
from simpro_mj.config.games import beamng, codemasters, forza
from simpro_mj.config.games.common import DatagramError
from simpro_mj.config.telemetry import read_telemetry, resample
from simpro_mj.core.shipped import TELEMETRY_DIR
from simpro_mj.sim.udp import Receiver

LANE = TELEMETRY_DIR / "lane_change_80kmh.csv"
GAMES = ("forza_sled", "forza_dash", "forza_horizon", "codemasters", "beamng")
#: float32 packing of values up to ~10 (6e-8 relative), with margin
F32 = 1e-5
#: Codemasters: the force is a difference of float32 velocities over 1/60 s
#: (|v| < 5 m/s here: 5 * 6e-8 * 60 = 2e-5), the rate a float32 rotation's over 1/60 s
CM_TOL = 1e-3


def _samples(fmt, grams):
    dec = make_decoder(fmt)
    return [dec(g) for g in grams]


@pytest.mark.parametrize("fmt", GAMES)
def test_each_game_packet_returns_the_drive_it_packed(fmt):
    """The packer's datagrams, of the format's size, decode to the file resampled at 60 Hz
    (Codemasters from its second packet: the first has nothing to differentiate)."""
    tel = read_telemetry(LANE)
    t, grams = telemetry_datagrams(tel, fmt, 60.0)
    size = {**{v: k for k, v in SIZES.items()}, **forza.SIZES}.get(fmt)
    assert {len(g) for g in grams} == {size or len(grams[0])}
    f, w = resample(tel, t)
    got = _samples(fmt, grams)
    first = 1 if fmt == "codemasters" else 0
    tol = CM_TOL if fmt == "codemasters" else F32
    assert np.abs(np.array([g[1] for g in got])[first:] - f[first:]).max() < tol
    assert np.abs(np.array([g[2] for g in got])[first:] - w[first:]).max() < tol
    if fmt != "beamng":  # BeamNG's packet has no clock; Forza's counts whole milliseconds
        tol_t = 0.5e-3 if fmt.startswith("forza") else 1e-5 * t.max()
        assert np.abs(np.array([g[0] for g in got]) - t).max() <= tol_t + 1e-12
    # the drive really turns the car: the packed tilt or axes move
    assert np.abs(w).max() > 0.05


def test_forza_signs_braking_yawing_left_and_idle():
    """Braking at 5 m/s^2 (AccelerationZ = -5, Z forward), level: fx = -5, fz = g; a left
    turn's yaw rate (left-hand rule about Y up: negative) is ISO wz > 0; nose down by
    0.1 rad (Pitch = +0.1, left-hand about X right) gives fx = -g sin 0.1."""
    head = struct.Struct("<iI3f3f3f3f3f")

    def packet(acc=(0, 0, 0), ang=(0, 0, 0), ypr=(0, 0, 0), race_on=1):
        h = head.pack(race_on, 1500, 0, 0, 0, *acc, 0, 0, 0, *ang, *ypr)
        return h + bytes(311 - len(h))

    t, f, w = forza.decode(packet(acc=(0, 0, -5.0), ang=(0, -0.3, 0)))
    assert t == 1.5
    assert f == pytest.approx((-5.0, 0.0, GRAVITY), abs=F32)
    assert w == pytest.approx((0.0, 0.0, 0.3), abs=F32)
    _, f, _ = forza.decode(packet(ypr=(0, 0.1, 0)))
    assert f == pytest.approx((-GRAVITY * math.sin(0.1), 0.0, GRAVITY * math.cos(0.1)), abs=F32)
    with pytest.raises(DatagramError) as err:
        forza.decode(packet(race_on=0))
    assert err.value.kind == "idle"


def test_beamng_signs_and_magic():
    """accY (forward) = -5 is braking; pitchPos nose up 0.1 gives fx = +g sin 0.1; a packet
    without the BNG1 magic is malformed."""
    p = struct.Struct("<4s21f")
    z = [0.0] * 21
    acc = list(z)
    acc[7] = -5.0  # accY
    _, f, _ = beamng.decode(p.pack(b"BNG1", *acc))
    assert f == pytest.approx((-5.0, 0.0, GRAVITY), abs=F32)
    tilt = list(z)
    tilt[13] = 0.1  # pitchPos, nose up
    _, f, _ = beamng.decode(p.pack(b"BNG1", *tilt))
    assert f == pytest.approx((GRAVITY * math.sin(0.1), 0.0, GRAVITY * math.cos(0.1)), abs=F32)
    with pytest.raises(DatagramError) as err:
        beamng.decode(p.pack(b"XXXX", *z))
    assert err.value.kind == "malformed"


def test_codemasters_braking_and_a_left_turn_from_two_packets():
    """Level, facing the world's z: the velocity along forward drops by 0.1 m/s in 20 ms
    (braking at 5 m/s^2), while the forward axis turns to the left by 0.01 rad (yaw rate
    0.5 rad/s). Left is -x in the left-handed world (x right, y up, z forward)."""
    dec = codemasters.Decoder()
    dec(codemasters.encode(1.00, (0.0, 0.0, 20.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0)))
    a = 0.01
    fwd, right = (-math.sin(a), 0.0, math.cos(a)), (math.cos(a), 0.0, math.sin(a))
    t, f, w = dec(codemasters.encode(1.02, (0.0, 0.0, 19.9), fwd, right))
    assert t == pytest.approx(1.02)
    assert f[0] == pytest.approx(-5.0 * math.cos(a), abs=1e-3)  # braking
    assert f[2] == pytest.approx(GRAVITY, abs=1e-4)
    assert w == pytest.approx((0.0, 0.0, 0.5), abs=1e-3)  # yawing left: wz > 0
    # an older packet changes nothing and returns the last sample (the receiver skips it)
    assert dec(codemasters.encode(1.01, (0.0, 0.0, 0.0), fwd, right))[1:] == (f, w)


def test_auto_tells_the_formats_apart_by_size_and_says_which():
    tel = read_telemetry(LANE)
    for fmt in SEND_FORMATS:
        _, grams = telemetry_datagrams(tel, fmt, 60.0)
        said = []
        dec = AutoDecoder(on_choose=said.append)
        with pytest.raises(DatagramError):
            dec(b"hello")  # garbage fixes nothing
        assert dec.chosen is None and said == []
        dec(grams[0])
        assert dec.chosen == fmt
        assert said == [fmt]
        dec(grams[1])
        assert said == [fmt]  # said once
    assert "auto" in FORMATS and "auto" not in SEND_FORMATS


def _through_socket(fmt: str, grams) -> np.ndarray:
    """Each datagram sent to a Receiver on loopback and read back: rows (f, w) per sample."""
    rx = Receiver(("127.0.0.1", 0), fmt, stale_after_s=0.5, fade_s=1.0)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rows = []
    try:
        for i, g in enumerate(grams):
            tx.sendto(g, rx.address)
            select.select([rx.sock], [], [], 1.0)  # loopback: at once; bounded
            rx.poll(float(i))  # an arrival clock for BeamNG, one step a datagram
            rows.append([*rx.f, *rx.w])
        assert rx.received == len(grams) and rx.bad == 0 and rx.late == 0
    finally:
        tx.close()
        rx.close()
    return np.array(rows)


def test_the_same_drive_in_every_format_gives_the_outsim_signals():
    """The lane change at 60 Hz through a socket as OutSim and as each game's packet: the
    received vehicle signals agree channel by channel (correlation >= 0.99)."""
    tel = read_telemetry(LANE)
    ref = _through_socket("outsim", telemetry_datagrams(tel, "outsim", 60.0)[1])
    moving = [j for j in range(6) if ref[:, j].std() > 1e-3]
    assert len(moving) >= 4  # fx, fy, fz and the rates of a lane change
    for fmt in ("forza_dash", "forza_horizon", "codemasters", "beamng"):
        got = _through_socket(fmt, telemetry_datagrams(tel, fmt, 60.0)[1])
        for j in moving:
            r = np.corrcoef(ref[1:, j], got[1:, j])[0, 1]
            assert r >= 0.99, (fmt, j, r)
