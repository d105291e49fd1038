"""Live sessions: telemetry datagrams in, the co-simulation paced to the wall clock, the pose out.

Network use is loopback only, bounded in count and in time; a session is
waited for through its readiness file and through what it sends back, never
through a fixed delay. Nothing here asserts how late the wall clock let the
loop be (that is a benchmark figure: docs/live.md), only that it is counted.
"""

from __future__ import annotations

import json
import math
import os
import select
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from controllers.frames import GRAVITY
from controllers.washout import ClassicalWashout
from simpro_mj.commands.main import main
from simpro_mj.config.datagrams import (
    decode,
    decode_csv,
    decode_outsim,
    encode_csv,
    telemetry_datagrams,
)
from simpro_mj.config.games.common import DatagramError
from simpro_mj.config.telemetry import Telemetry, read_telemetry, resample, write_telemetry
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.shipped import TELEMETRY_DIR
from simpro_mj.plant.faults import NEVER
from simpro_mj.sim.live import MAX_BEHIND_S, Pacer
from simpro_mj.sim.scheduling import request_realtime
from simpro_mj.sim.udp import MAX_DRAIN, Receiver, pose_template

ROOT = Path(__file__).resolve().parents[1]
BRAKING = TELEMETRY_DIR / "braking_100kmh.csv"
OUTSIM = struct.Struct("<I3f3f3f3f3i")
#: float32 packing: a relative 6e-8 of a 10 m/s^2 value, with margin
F32 = 1e-5


def _outsim(time_ms=0, ang=(0, 0, 0), att=(0, 0, 0), acc=(0, 0, 0)) -> bytes:
    return OUTSIM.pack(time_ms, *ang, *att, *acc, 0, 0, 0, 0, 0, 0)


# ------------------------------------------------------------------ formats


def test_outsim_braking_is_negative_fx_whatever_the_heading():
    """A car braking at 5 m/s^2 feels fx = -5 with gravity on z, facing +Y or facing -X."""
    _, f, w = decode_outsim(_outsim(1000, acc=(0.0, -5.0, 0.0)))
    assert f == pytest.approx((-5.0, 0.0, GRAVITY), abs=F32)
    # heading +90 deg (anticlockwise from above): the car faces -X, braking is +X in W
    t, f, w = decode_outsim(_outsim(2500, ang=(0, 0, 0.1), att=(math.pi / 2, 0, 0), acc=(5, 0, 0)))
    assert t == 2.5
    assert f == pytest.approx((-5.0, 0.0, GRAVITY), abs=F32)
    assert w == pytest.approx((0.0, 0.0, 0.1), abs=F32)  # yaw rate to the left: wz > 0


def test_outsim_attitude_tilts_gravity_and_rates_into_the_vehicle_frame():
    """Nose up by p at rest: gravity gives fx = +g sin p (as accelerating does), fz = g cos p;
    a nose-up rate about W's X is a negative ISO pitch rate (ISO wy > 0 is nose down)."""
    p = 0.1
    _, f, w = decode_outsim(_outsim(att=(0.0, p, 0.0), ang=(0.2, 0.0, 0.0)))
    assert f == pytest.approx((GRAVITY * math.sin(p), 0.0, GRAVITY * math.cos(p)), abs=F32)
    assert w == pytest.approx((0.0, -0.2, 0.0), abs=F32)  # X is the pitch axis in W and C
    # facing -X (heading +90 deg), a rate about W's X is about the car's backward axis
    _, _, w = decode_outsim(_outsim(att=(math.pi / 2, 0.0, 0.0), ang=(0.2, 0.0, 0.0)))
    assert w == pytest.approx((-0.2, 0.0, 0.0), abs=F32)
    # rolled by r about the car's forward axis (right side down): the driver is pressed to the
    # right as in a left turn, ISO fy (left) = +g sin r
    r = 0.2
    _, f, _ = decode_outsim(_outsim(att=(0.0, 0.0, r)))
    assert f == pytest.approx((0.0, GRAVITY * math.sin(r), GRAVITY * math.cos(r)), abs=F32)


@pytest.mark.parametrize("fmt", ["outsim", "csv"])
def test_a_telemetry_file_survives_the_round_trip(fmt):
    """send's datagrams decode to the file resampled (outsim: through the integrated attitude)."""
    tel = read_telemetry(BRAKING)
    t, grams = telemetry_datagrams(tel, fmt, 100.0)
    assert len(grams) == int(tel.t[-1] * 100) + 1
    f, w = resample(tel, t)
    got = [decode(fmt, g) for g in grams]
    tol = F32 if fmt == "outsim" else 1e-8
    assert np.abs(np.array([g[1] for g in got]) - f).max() < tol
    assert np.abs(np.array([g[2] for g in got]) - w).max() < tol
    assert np.abs(np.array([g[0] for g in got]) - t).max() < 1e-9
    if fmt == "outsim":  # the attitude is really exercised: heading and pitch move
        att = np.array([OUTSIM.unpack(g)[4:7] for g in grams])
        assert np.abs(att).max() > 1e-3


@pytest.mark.parametrize(
    "data, kind",
    [
        (b"", "short"),
        (b"\x00" * 63, "short"),
        (b"\x00" * 65, "oversized"),
        (b"\x00" * 100, "oversized"),
        (OUTSIM.pack(0, math.nan, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0), "malformed"),
        (_outsim(acc=(1e6, 0, 0)), "malformed"),
        (_outsim(att=(1e9, 0, 0)), "malformed"),
    ],
)
def test_bad_outsim_datagrams_are_refused_by_kind(data, kind):
    with pytest.raises(DatagramError) as err:
        decode_outsim(data)
    assert err.value.kind == kind


@pytest.mark.parametrize(
    "data, kind",
    [
        (b"hello", "malformed"),
        (b"1,2,3", "short"),
        (b"0,0,0,9.8,0,0,0,0", "malformed"),
        (b"0,nan,0,9.8,0,0,0", "malformed"),
        (b"0,500,0,9.8,0,0,0", "malformed"),
        (b"\xff\xfe", "malformed"),
        (b"0," * 300, "oversized"),
    ],
)
def test_bad_csv_datagrams_are_refused_by_kind(data, kind):
    with pytest.raises(DatagramError) as err:
        decode_csv(data)
    assert err.value.kind == kind


def test_pose_template_names_an_unknown_field():
    assert pose_template("P{pitch_deg:.1f}\\n").format(pitch_deg=-2.25) == "P-2.2\n"
    with pytest.raises(UserInputError, match="unknown field 'yaw_deg'; allowed: t_s, roll_deg"):
        pose_template("{yaw_deg}")


def test_rt_says_in_one_line_when_it_is_not_permitted(monkeypatch):
    def refuse(*args):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    assert request_realtime() == (
        "--rt: real-time scheduling not permitted (Operation not permitted); running at "
        "normal priority"
    )


# ------------------------------------------------------------------ the receiver


def _drain(rx: Receiver, expected: int, bound_s: float = 10.0) -> None:
    """Poll until ``expected`` datagrams were read (loopback: at once; bounded)."""
    end = time.monotonic() + bound_s
    while rx.received < expected and time.monotonic() < end:
        select.select([rx.sock], [], [], 0.05)
        rx.poll(0.0)


def test_receiver_counts_bad_and_late_datagrams_and_keeps_the_newest():
    rx = Receiver(("127.0.0.1", 0), "csv", stale_after_s=0.5, fade_s=1.0)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        grams = [
            encode_csv(1.00, (-1.0, 0.0, GRAVITY), (0, 0, 0)),
            b"garbage",
            encode_csv(1.02, (-2.0, 0.0, GRAVITY), (0, 0, 0)),
            encode_csv(1.01, (-9.0, 0.0, GRAVITY), (0, 0, 0)),  # out of order: late
            encode_csv(1.02, (-9.0, 0.0, GRAVITY), (0, 0, 0)),  # repeated: late
            b"1" * 5000,  # oversized (cut at the read buffer)
            encode_csv(1.03, (-3.0, 0.5, GRAVITY), (0.1, 0, 0)),
        ]
        for g in grams:
            tx.sendto(g, rx.address)
        _drain(rx, len(grams))
        c = rx.counts()
        assert (c["received"], c["bad"], c["late"]) == (7, 2, 2)
        assert c["bad_kinds"] == {"short": 0, "oversized": 1, "malformed": 1}
        assert rx.sample(0.0)[:2] == ((-3.0, 0.5, GRAVITY), (0.1, 0.0, 0.0))
        # a game restarted: its time went back by more than RESTART_S, taken as a new stream
        tx.sendto(encode_csv(0.0, (-4.0, 0.0, GRAVITY), (0, 0, 0)), rx.address)
        _drain(rx, 8)
        assert rx.restarts == 1 and rx.sample(0.0)[0] == (-4.0, 0.0, GRAVITY)
    finally:
        tx.close()
        rx.close()


def test_a_burst_is_read_in_bounded_portions():
    """300 datagrams at once: no chunk boundary reads more than MAX_DRAIN of them."""
    rx = Receiver(("127.0.0.1", 0), "csv", stale_after_s=0.5, fade_s=1.0)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for i in range(300):
            tx.sendto(encode_csv(0.001 * i, (-1.0, 0.0, GRAVITY), (0, 0, 0)), rx.address)
        reads, end = [], time.monotonic() + 10.0
        while sum(reads) < 300 and time.monotonic() < end:
            select.select([rx.sock], [], [], 0.05)
            reads.append(rx.poll(0.0))
        assert sum(reads) == 300 and max(reads) <= MAX_DRAIN < 300
        assert rx.last_time == pytest.approx(0.299) and rx.late == 0
    finally:
        tx.close()
        rx.close()


def test_stale_input_is_held_then_faded_to_rest():
    rx = Receiver(("127.0.0.1", 0), "csv", stale_after_s=0.5, fade_s=1.0)
    try:
        assert rx.sample(0.0) == ((0.0, 0.0, GRAVITY), (0.0, 0.0, 0.0), True)  # nothing yet
        rx.last_time, rx.last_wall = 3.0, 10.0
        rx.f, rx.w = (-4.0, 2.0, GRAVITY + 1.0), (0.2, 0.0, 0.0)
        assert rx.sample(10.5) == (rx.f, rx.w, False)  # held for stale_after_s
        f, w, stale = rx.sample(11.0)  # half-way through the fade
        assert stale and f == pytest.approx((-2.0, 1.0, GRAVITY + 0.5)) and w[0] == 0.1
        assert rx.sample(11.5)[:2] == ((0.0, 0.0, GRAVITY), (0.0, 0.0, 0.0))  # at rest
    finally:
        rx.close()


# ------------------------------------------------------------------ the pacer


class _FakeSim:
    dt, n_steps = 1e-3, 100

    def __init__(self):
        self.rows = {}

    def write_setpoints(self, k, poses, f, w):
        self.rows[k] = (np.array(poses), np.array(f))


class _Clock:
    """A wall clock the test moves; ``sleep`` oversleeps by 100 us."""

    def __init__(self, t):
        self.t = t

    def __call__(self):
        return self.t

    def sleep(self, s):
        self.t += s + 1e-4


def test_pacer_counts_lateness_and_missed_deadlines_and_reanchors_after_a_stall():
    sim, clock = _FakeSim(), _Clock(100.0)
    rx = Receiver(("127.0.0.1", 0), "csv", stale_after_s=0.5, fade_s=1.0)
    try:
        pacer = Pacer(sim, rx, ClassicalWashout(), wash_every=10, send_every=10,
                      clock=clock, sleep=clock.sleep)  # fmt: skip
        log = np.zeros((0, 1))
        assert pacer(0, log) == 10  # the first chunk: loads the kernels, no clock yet
        clock.t = 100.050
        assert pacer(10, log) == 20  # the anchor: D(k) = 100.040 + k dt
        clock.t = 100.053  # the chunk took 3 ms: sleep to D(20) = 100.060
        pacer(20, log)
        assert clock.t == pytest.approx(100.0601)
        clock.t = 100.075  # took 15 ms: D(30) = 100.070 missed by 5 ms
        pacer(30, log)
        clock.t = 100.300  # stalled: 220 ms behind D(40), beyond MAX_BEHIND_S
        pacer(40, log)
        clock.t = 100.305  # re-anchored: D(50) = 100.090 + 0.220 = 100.310
        pacer(50, log)
        st = pacer.stats
        lat = st.lateness_s[: st.n]
        assert lat == pytest.approx([0.0, 1e-4, 0.005, 0.220, 1e-4], abs=1e-9)
        assert st.missed == 2 and st.resyncs == 1 and st.lost_s == pytest.approx(0.220)
        # the loop's time on each chunk: from the pacer's return to its next call
        assert st.compute_s[1:4] == pytest.approx([0.003, 0.0149, 0.225], abs=1e-9)
        assert 0.220 > MAX_BEHIND_S
        for k in range(60, 101, 10):
            clock.t += 0.002
            nxt = pacer(k, log)
        assert nxt == NEVER  # the last step: the pacer is done
        rt = pacer.realtime(100)
        # it ends at D(100) + 100 us = 100.3601 s: 0.1 s simulated in 0.3201 s since the anchor
        # (100.040): the 220 ms stall is lost for good, and said so
        assert rt["drift_ms"] == pytest.approx(-220.1, abs=1e-6)
        assert rt["missed_deadlines"] == 2 and rt["lateness_us"]["max"] == pytest.approx(220e3)
        # the washout ran every 10 steps on the input at rest: home set-points, f = (0, 0, g)
        assert sorted(sim.rows) == list(range(0, 101, 10))  # the last step's row too
        poses, f = sim.rows[50]
        assert poses.shape == (10, 3) and np.allclose(f, [0.0, 0.0, GRAVITY])
        assert rt["stale_s"] == pytest.approx(0.090)  # no input ever: stale since the anchor
    finally:
        rx.close()


# ------------------------------------------------------------------ the commands


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--listen", "4444"], "invalid value at --listen: '4444'"),
        (["--listen", "127.0.0.1:0", "--send-rate", "300"], "invalid value at --send-rate: 300"),
        (["--listen", "127.0.0.1:0", "--send", "x:99999"], "invalid value at --send: 'x:99999'"),
        (["--listen", "127.0.0.1:0", "--send-format", "{q4_mm}"], "unknown field 'q4_mm'"),
        (["--listen", "127.0.0.1:0", "--duration", "-1"], "invalid value at --duration: -1"),
        (["--listen", "127.0.0.1:0", "--bias-tau", "-1"], "invalid value at --bias-tau: -1"),
        (["--listen", "127.0.0.1:0", "--spin-us", "6000"], "invalid value at --spin-us: 6000"),
        (["--listen", "127.0.0.1:0", "--vibration-hz", "60"], "invalid value at --vibration-hz"),
        (["--listen", "127.0.0.1:0", "--output", "tcp:x:1"], "invalid value at --output"),
        (
            ["--listen", "127.0.0.1:0", "--output", "udp:127.0.0.1:9", "--output-string", "<q9>"],
            "unknown token <q9>",
        ),
    ],
)
def test_live_refuses_bad_options_in_one_line(capsys, tmp_path, args, message):
    assert main(["live", "cue_braking.yaml", "--out", str(tmp_path / "o"), *args]) == 2
    assert message in _one_error_line(capsys)
    assert not (tmp_path / "o").exists()


def test_live_refuses_a_busy_port_and_a_scenario_without_cueing(capsys, tmp_path):
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", 0))
    try:
        port = busy.getsockname()[1]
        argv = ["live", "cue_braking.yaml", "--listen", f"127.0.0.1:{port}"]
        assert main([*argv, "--out", str(tmp_path / "a")]) == 2
        assert f"cannot listen at --listen 127.0.0.1:{port}" in _one_error_line(capsys)
    finally:
        busy.close()
    argv = ["live", "step_pitch.yaml", "--listen", "127.0.0.1:0", "--out", str(tmp_path / "b")]
    assert main(argv) == 2
    assert "invalid value at setpoint.cueing: a live session needs" in _one_error_line(capsys)


@pytest.mark.parametrize("fmt", ["csv", "outsim"])
def test_send_replays_a_file_as_datagrams(capsys, tmp_path, fmt):
    tel = Telemetry(
        t=np.array([0.0, 0.02, 0.05]),
        f=np.array([[0.0, 0.0, GRAVITY], [-2.0, 0.5, GRAVITY], [-5.0, 1.0, 10.0]]),
        w=np.array([[0.0, 0.0, 0.0], [0.01, 0.02, 0.03], [0.0, 0.0, 0.0]]),
    )
    path = write_telemetry(tmp_path / "tel.csv", tel)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.setblocking(False)
    try:
        to = f"127.0.0.1:{rx.getsockname()[1]}"
        assert (
            main(["send", str(path), "--to", to, "--format", fmt, "--rate", "200", "--json"]) == 0
        )
        info = json.loads(capsys.readouterr().out)
        assert info["sent"] == 11 and info["errors"] == 0  # 0..0.05 s at 5 ms
        got = []
        while True:
            try:
                got.append(decode(fmt, rx.recv(4096)))
            except BlockingIOError:
                break
    finally:
        rx.close()
    assert len(got) == 11
    f, w = resample(tel, np.arange(11) * 0.005)
    tol = F32 if fmt == "outsim" else 1e-8
    assert np.abs(np.array([g[1] for g in got]) - f).max() < tol
    assert np.abs(np.array([g[2] for g in got]) - w).max() < tol


def _listening_at(proc, ready: Path, bound_s: float = 300.0):
    """The session's address from its readiness file once written, not after a guessed
    delay (the bound only stops a hang); None if the session exits first."""
    end = time.monotonic() + bound_s
    while time.monotonic() < end and proc.poll() is None:
        line = ready.read_text() if ready.is_file() else ""  # written whole (renamed)
        if line.startswith("listening@"):
            host, port = line.split()[0].removeprefix("listening@").rsplit(":", 1)
            return host, int(port)
        time.sleep(0.02)
    return None


def _pose_lines(sock) -> list[list[float]]:
    out = []
    while True:
        try:
            data = sock.recv(4096)
        except BlockingIOError:
            return out
        out.append([float(v) for v in data.decode("ascii").strip().split(",")])


def test_a_live_session_driven_over_udp_and_ended_by_sigterm(tmp_path):
    """The whole path on loopback: csv datagrams (garbage among them) in, the washout tilting
    the platform nose down for a braking input, the pose lines out, SIGTERM, the folder."""
    pose = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    pose.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    pose.bind(("127.0.0.1", 0))
    pose.setblocking(False)
    rig = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rig.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    rig.bind(("127.0.0.1", 0))
    rig.setblocking(False)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    out, ready = tmp_path / "live", tmp_path / "ready"
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT), SIMPRO_READY_FILE=str(ready))
    cmd = [sys.executable, "-m", "simpro_mj.commands.main", "live", "cue_braking.yaml",
           "--listen", "127.0.0.1:0", "--format", "csv", "--send",
           f"127.0.0.1:{pose.getsockname()[1]}", "--duration", "300", "--out", str(out),
           "--output", f"udp:127.0.0.1:{rig.getsockname()[1]}", "--output-rate", "50",
           "--no-plots", "--json"]  # fmt: skip
    proc = subprocess.Popen(
        cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    garbage = [b"", b"hello", b"1,2,3", b"0,nan,0,9.8,0,0,0", b"9" * 3000, _outsim()]
    lines: list[list[float]] = []
    try:
        address = _listening_at(proc, ready)
        assert address is not None and address[0] == "127.0.0.1", proc.communicate()
        for g in garbage:
            tx.sendto(g, address)
        # braking at 4 m/s^2, a sample every 20 ms, until the pose lines show the tilt
        # (3 deg/s rate limit: 2 deg within about 0.7 s); one sample out of order
        end, t_game, n_sent = time.monotonic() + 120, 0.0, 0
        while time.monotonic() < end and proc.poll() is None:
            t_game += 0.02
            tx.sendto(encode_csv(t_game, (-4.0, 0.0, GRAVITY), (0.0, 0.0, 0.0)), address)
            n_sent += 1
            if n_sent == 5:
                tx.sendto(encode_csv(t_game - 0.01, (-9.0, 0.0, GRAVITY), (0, 0, 0)), address)
            select.select([pose], [], [], 0.02)
            lines += _pose_lines(pose)
            if lines and min(p[2] for p in lines) < -2.0:
                break
        proc.send_signal(signal.SIGTERM)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
        tx.close()
    lines += _pose_lines(pose)
    pose.close()
    strings = []
    while True:
        try:
            strings.append(rig.recv(4096))
        except BlockingIOError:
            break
    rig.close()
    assert proc.returncode == 0, stderr
    assert "Traceback" not in stderr
    doc = json.loads(stdout)
    assert doc == json.loads((out / "metrics.json").read_text())
    rt = doc["realtime"]
    assert doc["status"] == "ok" and rt["ended"] == "signal" and "signal" in doc["reason"]
    assert rt["packets"]["bad"] == len(garbage)
    assert rt["packets"]["bad_kinds"] == {"short": 1, "oversized": 1, "malformed": 4}
    assert rt["packets"]["late"] == 1
    # the last samples may still wait in the socket when the signal ends the session
    assert len(garbage) + 1 < rt["packets"]["received"] <= len(garbage) + n_sent + 1
    for key in ("p50", "p99", "max"):
        assert rt["lateness_us"][key] >= 0.0  # measured, not judged here
    assert rt["deadlines"] > 0 and isinstance(rt["drift_ms"], float)
    # the pose lines: t_s, roll, pitch, heave, q1..q3, one per 10 ms of simulated time; no
    # more than the session says it sent (a test starved of CPU may let the kernel drop some)
    assert 0 < len(lines) <= rt["pose_sent"]["datagrams"]
    assert all(len(p) == 7 for p in lines)
    t_pose = np.array([p[0] for p in lines])
    assert np.all(np.diff(t_pose) > 0)
    assert np.allclose(np.round((t_pose + 0.001) / 0.01), (t_pose + 0.001) / 0.01, atol=1e-3)
    assert min(p[2] for p in lines) < -2.0  # braking: nose down (tilt coordination)
    assert all(0.0 < q < 500.0 for p in lines for q in p[4:])  # leg set-points in the stroke
    # the folder: the received signals logged, the motion recorded for render
    from simpro_mj.report.recording import load_recording
    from simpro_mj.report.results import read_timeseries

    cols = read_timeseries(out / "timeseries.csv")
    assert cols["veh_fx_mps2"].min() == pytest.approx(-4.0, abs=1e-9)
    assert np.all(np.abs(cols["veh_fz_mps2"] - GRAVITY) < 1e-9)
    assert np.degrees(cols["pitch_rad"].min()) < -2.0
    assert np.degrees(cols["pitch_ref_rad"].min()) < -1.0  # the washout set-point: nose down
    assert doc["sim"]["simulated_s"] == pytest.approx(cols["time_s"][-1], abs=1.5e-3)
    rec = load_recording(out)
    assert rec.qpos.shape[0] == cols["time_s"].size
    assert doc["metrics"]["cueing"]["source"].startswith("udp csv 127.0.0.1:")
    assert doc["metrics"]["cueing"]["channels"]["longitudinal_f"]["vehicle_peak"] < 0
    # the law that ran, its solves, commanded against simulated actuator positions
    assert doc["metrics"]["cueing"]["algorithm"] == "mpc"
    assert rt["cue_solve_ms"]["solves"] > 0 and rt["cue_solve_ms"]["p50_ms"] > 0
    assert doc["live"]["actuators"]["q1"]["max_abs_mm"] >= doc["live"]["actuators"]["q1"]["rms_mm"]
    # the rig's strings ('S', three 16-bit counts, LF) are logged leg set-points within a count
    assert 0 < len(strings) <= rt["rig_out"]["strings"]
    q_ref = np.column_stack([cols[f"q{i}_ref_m"] for i in (1, 2, 3)]) / 0.5 * 65535
    for data in strings:
        assert len(data) == 8 and data[:1] == b"S" and data[-1:] == b"\n"
        counts = np.array([int.from_bytes(data[1 + 2 * i : 3 + 2 * i], "big") for i in range(3)])
        assert np.abs(q_ref - counts).max(axis=1).min() <= 1.0
    lat = np.load(out / "realtime.npz")
    assert lat["lateness_us"].size == rt["deadlines"]
    # what the pacing cost, counted: the collector's passes, the pacer's core kept apart
    assert len(rt["gc_collections"]) == 3 and rt["spin_us"] == 0.0
    if len(os.sched_getaffinity(0)) >= 2:
        assert not set(rt["cpus"]["pacer"]) & set(rt["cpus"]["cue"])
    assert rt["pacer_switches"]["voluntary"] > 0  # it slept between deadlines


# ------------------------------------------------------------------ strict templates, send


@pytest.mark.parametrize(
    "template, why",
    [
        ("{t_s.__class__}", "attribute or index access"),
        ("{t_s.__class__.__mro__}", "attribute or index access"),
        ("{t_s[0]}", "attribute or index access"),
        ("{t_s:>900000000}", "format '>900000000'"),
        ("{t_s:>99}", "width 99"),
        ("{t_s:.40f}", "precision 40"),
        ("{t_s!r}", "conversion !r"),
        ("{t_s:{pitch_deg}}", "format"),
        ("{t_s:s}", "format 's'"),
        ("x" * 513, "too long"),
        ("{t_s} \u00b0", "not ASCII"),
    ],
)
def test_pose_template_takes_only_the_fields_with_bounded_number_formats(template, why):
    with pytest.raises(UserInputError) as err:
        pose_template(template)
    msg = str(err.value)
    assert msg.startswith("invalid value at --send-format:") and why in msg and "\n" not in msg


def test_pose_templates_within_the_bounds_format_any_value_briefly():
    tpl = pose_template("{t_s:>32.12f}|{heave_mm:+08.2f}|{pitch_deg:e}|{roll_deg:%}\\r\\n")
    line = tpl.format(**dict.fromkeys(["t_s", "heave_mm", "pitch_deg", "roll_deg"], -1e300))
    assert line.endswith("\r\n") and len(line) < 2000  # fits a datagram
    assert pose_template("{{literal}}{q1_mm:.1f}").format(q1_mm=1.25) == "{literal}1.2"


def test_live_refuses_an_unbounded_send_format_at_start(capsys, tmp_path):
    argv = ["live", "cue_braking.yaml", "--listen", "127.0.0.1:0", "--out", str(tmp_path / "o")]
    assert main([*argv, "--send-format", "{t_s:>900000000}"]) == 2
    assert "invalid value at --send-format" in _one_error_line(capsys)
    assert not (tmp_path / "o").exists()


def test_send_refuses_a_host_that_does_not_resolve(capsys, tmp_path, monkeypatch):
    """The resolver answers no (patched: no name server is asked): exit 2, one line."""

    def no(*args, **kwargs):
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")

    monkeypatch.setattr(socket, "getaddrinfo", no)
    path = write_telemetry(tmp_path / "t.csv", Telemetry(np.array([0.0, 0.01]),
                           np.array([[0, 0, GRAVITY]] * 2), np.zeros((2, 3))))  # fmt: skip
    assert main(["send", str(path), "--to", "nohost.invalid:9"]) == 2
    line = _one_error_line(capsys)
    assert "invalid value at --to: nohost.invalid:9: the host does not resolve" in line


def test_send_stops_at_once_when_nothing_can_be_sent(capsys, tmp_path, monkeypatch):
    """Every send refused locally (as a broadcast address without permission is; patched, so
    nothing leaves the machine): exit 2 at the first send, one line, not 'sent 0'."""
    real = socket.socket
    attempts = []

    class Refusing(real):
        def sendto(self, *args):
            attempts.append(args)
            raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(socket, "socket", Refusing)
    n = 50
    path = write_telemetry(tmp_path / "t.csv", Telemetry(np.arange(n) * 0.01,
                           np.array([[0, 0, GRAVITY]] * n), np.zeros((n, 3))))  # fmt: skip
    assert main(["send", str(path), "--to", "127.0.0.1:9"]) == 2
    line = _one_error_line(capsys)
    assert "nothing could be sent (Permission denied)" in line
    assert len(attempts) == 1


def test_send_takes_the_shipped_telemetry_names_that_list_shows(capsys):
    from simpro_mj.commands.send import _telemetry_path

    assert main(["list"]) == 0
    listed = capsys.readouterr().out
    for name in ("braking_100kmh.csv", "lane_change_80kmh.csv"):
        assert name in listed
        assert _telemetry_path(name) == TELEMETRY_DIR / name
    assert _telemetry_path("no_such.csv").name == "no_such.csv"  # refused by the reader


# ------------------------------------------------------------------ rest after the feed


def test_after_the_feed_stops_the_set_point_goes_home_and_stays_for_the_mpc():
    """A biased drive (fz 9.6 m/s^2, as a real accelerometer's bias) for 6 s, then nothing:
    the pacer's set-point is home exactly from stale_after + HOME_S after the last sample on,
    and stays; the MPC alone is within 1 mm of home a second later (its heave's high-passed
    target and its rate and position weights: the otoliths' slow error does not let it coast)."""
    from controllers.geometry import nominal_geometry
    from controllers.mpc_cueing import ModelPredictiveCueing
    from simpro_mj.config.cue_params import washout_params
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.sim.live import HOME_S

    cue = load_scenario("cue_lane_change.yaml", []).setpoint.cueing
    law = ModelPredictiveCueing(washout_params(cue).replace(preview=0.0), nominal_geometry())
    stream = law.stream(0.01)
    raw = {}

    class Recorded:  # the law's own output, before the pacer's blend
        geometry, box = stream.geometry, stream.box
        last_rate_limited = last_softened = False

        def step(self, f, w):
            raw[len(raw)] = stream.step(f, w)
            return raw[len(raw) - 1]

    sim, clock = _FakeSim(), _Clock(100.0)
    sim.n_steps = 14000
    rx = Receiver(("127.0.0.1", 0), "csv", stale_after_s=0.5, fade_s=1.0)
    try:
        pacer = Pacer(sim, rx, Recorded(), wash_every=10, send_every=10, clock=clock,
                      sleep=clock.sleep)  # fmt: skip
        log = np.zeros((0, 1))
        for k in range(0, 14001, 10):
            t = k * 1e-3
            if t < 6.0:  # a sample every 10 ms: lane changes on a biased vertical force
                rx.last_wall, rx.last_time = clock(), t
                rx.f = (2.0 * math.sin(t), 2.0 * math.sin(2 * t), 9.6)
                rx.w = (0.05 * math.sin(2 * t), 0.0, 0.1 * math.sin(2 * t))
            pacer(k, log)
    finally:
        rx.close()
    home = np.asarray(law.geometry.home)
    poses = {k: sim.rows[k][0][0] for k in sim.rows}
    law_out = np.array([raw[i] for i in range(len(raw))])
    t_home = 6.0 + 0.5 + HOME_S  # the last sample, held until stale, blended home
    after = [k for k in poses if k * 1e-3 >= t_home + 0.011]
    assert after and all(np.array_equal(poses[k], home) for k in after)
    before = [k for k in poses if 6.6 <= k * 1e-3 < t_home - 0.1]
    assert [k for k in before if np.array_equal(poses[k], home)] == []  # on its way, no jump
    # the law alone: its heave within 1 mm of home a second later, and from then on
    late = law_out[int((t_home + 1.0) / 0.01) :]
    assert np.abs(late[:, 2] - home[2]).max() < 0.001
    # while the drive came, the law's set-points were played (after the soft start)
    mid = [k for k in poses if 3.0 <= k * 1e-3 < 6.0]
    assert max(abs(poses[k][0] - home[0]) for k in mid) > math.radians(0.5)  # roll: the sway
    assert all(np.array_equal(poses[k], law_out[k // 10]) for k in mid)


def test_the_pacer_gives_the_law_the_conditioned_input():
    """A feed biased to fz = 9.6 m/s^2 held for 30 s with --bias-tau 5: what the law is given
    (and what is logged as the received signal) comes back to g, to exp(-6) of the bias."""
    from controllers.conditioning import InputConditioner

    sim, clock = _FakeSim(), _Clock(100.0)
    sim.n_steps = 30000
    rx = Receiver(("127.0.0.1", 0), "csv", stale_after_s=0.5, fade_s=1.0)
    try:
        pacer = Pacer(sim, rx, ClassicalWashout(), wash_every=10, send_every=10, clock=clock,
                      sleep=clock.sleep, conditioner=InputConditioner(0.01, 5.0, 0.0))  # fmt: skip
        log = np.zeros((0, 1))
        for k in range(0, 30001, 10):
            rx.last_wall, rx.last_time, rx.f = clock(), k * 1e-3, (0.0, 0.0, 9.6)
            pacer(k, log)
    finally:
        rx.close()
    f_first, f_last = sim.rows[0][1][0], sim.rows[30000][1][0]
    assert abs(f_first[2] - 9.6) < 1e-3  # a step passes at once (Tustin: to 0.1 %)
    assert abs(f_last[2] - GRAVITY) < abs(9.6 - GRAVITY) * math.exp(-6.0) * 1.05


def test_the_simulated_platform_is_home_within_3_s_after_a_biased_feed_stops():
    """The real plant (the lane change's MPC, pneumatics and loops), paced by a clock that
    moves only when the pacer sleeps (no wall clock): 3.5 s of swaying input on a biased
    vertical force (9.6 m/s^2), then nothing. From 3 s after the last sample the simulated
    pose is within 1 mm and 0.05 deg of home; the set-point goes there within the MPC's
    own rate and acceleration limits (15 deg/s, 30 deg/s^2; 0.2 m/s, 3 m/s^2)."""
    from controllers.mpc_cueing import ModelPredictiveCueing
    from simpro_mj.config.cue_params import washout_params
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.sim.build import Build
    from simpro_mj.sim.live import HOME_S, LiveOptions

    stop_s, end_s = 3.5, 7.0
    shipped = LiveOptions(listen=("127.0.0.1", 0))  # the session's stale and fade times
    scenario = load_scenario("cue_lane_change.yaml", [f"duration_s={end_s}"])
    params = washout_params(scenario.setpoint.cueing).replace(preview=0.0)
    sim = Build(scenario, setpoints="external").simulation()
    law = ModelPredictiveCueing(params, sim.geometry).stream(0.01)
    clock = _Clock(100.0)
    origin = 100.0 - 0.010  # the pacer anchors its clock at the second chunk (k = 10)

    class Feed(Receiver):  # a sample every 10 ms of the clock until stop_s, then silence
        def poll(self, now):
            t = now - origin
            if t < stop_s:
                self.last_wall, self.last_time = now, t
                self.f = (0.3 * math.sin(2.4 * t), 3.0 * math.sin(2.4 * t), 9.6)
                self.w = (0.06 * math.sin(2.4 * t), 0.0, 0.25 * math.sin(2.4 * t))
            return 0

    rx = Feed(("127.0.0.1", 0), "csv", shipped.stale_after_s, shipped.fade_s)
    try:
        pacer = Pacer(sim, rx, law, wash_every=10, send_every=10, clock=clock,
                      sleep=clock.sleep)  # fmt: skip
        res = sim.run(pace=pacer)
    finally:
        rx.close()
    cols = res.columns
    t = cols["time_s"]
    home = np.asarray(sim.geometry.home)
    off = np.column_stack([np.degrees(cols["roll_rad"]), np.degrees(cols["pitch_rad"]),
                           (cols["heave_m"] - home[2]) * 1e3])  # fmt: skip
    assert np.abs(off[(t > 2.0) & (t < stop_s), 0]).max() > 1.0  # the sway: rolled > 1 deg
    settled = t >= stop_s + 3.0
    assert settled.sum() > 400
    assert np.abs(off[settled, :2]).max() < 0.05 and np.abs(off[settled, 2]).max() < 1.0
    # the set-point's way home, sampled at the law's 10 ms: within the MPC's limits
    ref = np.column_stack([cols["roll_ref_rad"], cols["pitch_ref_rad"], cols["heave_ref_m"]])
    way = ref[(t >= stop_s) & (t <= stop_s + 2.5)][::10]
    rate = np.abs(np.diff(way, axis=0)).max(axis=0) / 0.01
    accel = np.abs(np.diff(way, 2, axis=0)).max(axis=0) / 0.01**2
    assert np.all(rate[:2] <= params.tilt_rate_max) and rate[2] <= params.heave_rate_max
    assert np.all(accel[:2] <= params.tilt_accel_max) and accel[2] <= params.heave_accel_max
    assert np.allclose(ref[t >= stop_s + shipped.stale_after_s + HOME_S + 0.011], home, atol=1e-12)


# ------------------------------------------------------------------ what the pacer costs


class _TickingClock(_Clock):
    """Each reading moves the clock 20 us on (a spin has something to wait for)."""

    def __call__(self):
        self.t += 2e-5
        return self.t


def test_the_pacer_sleeps_to_a_margin_before_the_deadline_then_spins_to_it():
    sim, clock = _FakeSim(), _TickingClock(100.0)
    sleeps = []

    def sleep(s):
        sleeps.append(s)
        clock.sleep(s)

    rx = Receiver(("127.0.0.1", 0), "csv", stale_after_s=0.3, fade_s=1.5)
    try:
        pacer = Pacer(sim, rx, ClassicalWashout(), wash_every=10, send_every=10, spin_s=1e-3,
                      clock=clock, sleep=sleep)  # fmt: skip
        log = np.zeros((0, 1))
        pacer(0, log)
        pacer(10, log)  # the anchor: D(k) = t + (k - 10) dt
        d20 = pacer.wall0 + 0.020
        clock.t = d20 - 0.004  # 4 ms early: sleep 3 ms, spin the last
        pacer(20, log)
        assert sleeps == [pytest.approx(0.004 - 1e-3 - 2e-5)]
        # the sleep overslept by 100 us, still 0.9 ms early: the spin took it to the deadline,
        # a reading (20 us) past it at most
        assert 0.0 <= pacer.stats.lateness_s[1] <= 2e-5 + 1e-12
        clock.t = pacer.wall0 + 0.030 - 5e-4  # within the margin: no sleep, a spin
        pacer(30, log)
        assert len(sleeps) == 1 and 0.0 <= pacer.stats.lateness_s[2] <= 2e-5 + 1e-12
    finally:
        rx.close()


def test_the_pacing_thread_is_pinned_with_a_fine_timer_slack_and_then_as_it_was():
    import ctypes
    import ctypes.util

    from simpro_mj.sim.scheduling import cpu_split, pinned, thread_switches

    assert cpu_split({3}) is None  # one core: nothing to keep apart
    assert cpu_split({0, 2, 5}) == ({5}, {0, 2})
    switches = thread_switches()
    assert switches is None or all(n >= 0 for n in switches)
    if not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2:
        pytest.skip("needs two cores")
    before = os.sched_getaffinity(0)
    prctl = ctypes.CDLL(ctypes.util.find_library("c")).prctl
    slack = prctl(30, 0, 0, 0, 0)  # PR_GET_TIMERSLACK
    pacer_cpus, _ = cpu_split(before)
    with pinned(pacer_cpus):
        assert os.sched_getaffinity(0) == pacer_cpus
        assert prctl(30, 0, 0, 0, 0) == 1
    assert os.sched_getaffinity(0) == before and prctl(30, 0, 0, 0, 0) == slack
