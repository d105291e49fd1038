"""Nothing left behind, nothing hung: ``--scheduler`` is probed within a bounded
time (a closed port, a server that accepts and stays silent, one that is not
Dask: one line, exit 2), render's workers end with a parent killed outright,
and a stopped batch counts a variant whose folder is complete as finished.

Loopback servers only; every wait polls with a deadline, none sleeps a guess.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from simpro_mj.core.errors import UserInputError
from simpro_mj.sim import executors

ROOT = Path(__file__).resolve().parents[1]


class _Server:
    """A loopback TCP server that greets each connection with ``greeting`` (or
    nothing) and then holds it open."""

    def __init__(self, greeting: bytes | None):
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(4)
        self.port = self.sock.getsockname()[1]
        self.greeting, self.conns = greeting, []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.conns.append(conn)
            if self.greeting:
                conn.sendall(self.greeting)

    def close(self):
        self.sock.close()
        for c in self.conns:
            c.close()


@pytest.mark.parametrize(
    "greeting, words",
    [
        (None, "sent no handshake within 0.5 s"),
        (b"HTTP/1.1 400 Bad Request\r\n\r\n", "it answered b'HTTP/1.1'"),
        (b"\xff" * 8, "not a Dask scheduler"),
    ],
    ids=["silent", "http", "huge length"],
)
def test_a_server_that_is_not_dask_is_refused_in_bounded_time(greeting, words):
    srv = _Server(greeting)
    try:
        t0 = time.monotonic()
        with pytest.raises(UserInputError, match=words) as info:
            executors.probe_scheduler(f"tcp://127.0.0.1:{srv.port}", timeout=0.5)
        assert time.monotonic() - t0 < 2.0
        assert "\n" not in str(info.value) and "--scheduler" in str(info.value)
    finally:
        srv.close()


def test_a_closed_port_and_a_bad_address_are_refused():
    free = socket.socket()
    free.bind(("127.0.0.1", 0))
    port = free.getsockname()[1]
    free.close()  # nothing listens there now
    t0 = time.monotonic()
    with pytest.raises(UserInputError, match="no scheduler at --scheduler"):
        executors.probe_scheduler(f"tcp://127.0.0.1:{port}", timeout=0.5)
    assert time.monotonic() - t0 < 2.0
    for bad in ("tcp://127.0.0.1:notaport", "tcp://:8786", "127.0.0.1:99999"):
        with pytest.raises(UserInputError, match="invalid value at --scheduler"):
            executors.probe_scheduler(bad, timeout=0.5)


def test_a_dask_like_handshake_passes_the_probe():
    srv = _Server(b":\x00\x00\x00\x00\x00\x00\x00")  # a 58-byte message follows, as Dask's
    try:
        executors.probe_scheduler(f"127.0.0.1:{srv.port}", timeout=2.0)
    finally:
        srv.close()


def test_batch_refuses_a_silent_scheduler_before_writing(tmp_path, capsys, monkeypatch):
    pytest.importorskip("distributed")
    from simpro_mj.commands.main import main

    monkeypatch.setattr(executors, "CONNECT_S", 0.5)
    srv = _Server(None)
    try:
        out = tmp_path / "b"
        argv = ["batch", "step_pitch", "--out", str(out), "--scheduler",
                f"tcp://127.0.0.1:{srv.port}", "--set", "duration_s=0.3", "--no-plots"]  # fmt: skip
        t0 = time.monotonic()
        assert main(argv) == 2
        assert time.monotonic() - t0 < 5.0
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "not a Dask scheduler" in err[0], err
        assert not out.exists()
    finally:
        srv.close()


def test_a_stopped_batch_counts_a_variant_whose_folder_is_complete(tmp_path, monkeypatch):
    """The first variant finishes and writes its folder, then the batch is stopped
    before its result comes back: the summary lists it ok, not cancelled."""
    from simpro_mj.batch import runner
    from simpro_mj.batch.worker import run_variant

    def stopped(tasks, done, **kw):
        run_variant(tasks[0][1])  # its folder is written, its result never delivered
        raise KeyboardInterrupt("signal SIGTERM")

    monkeypatch.setattr(runner, "run_tasks", stopped)
    scen = tmp_path / "g.yaml"
    scen.write_text(
        "name: g\nduration_s: 0.3\nlogging: {decimation: 10}\n"
        "sweep:\n  grid:\n    controller.outer.gains: [2, 3]\n"
    )
    report = runner.run_batch([str(scen)], tmp_path / "out", jobs=2, plots=False,
                              summary_plots=False)  # fmt: skip
    status = {r.variant: r.status for r in report.rows}
    assert status == {"gains=2": "ok", "gains=3": "cancelled"}, report.rows
    assert report.stopped


def _children(pid: int) -> set[int]:
    out = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.add(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc")
def test_render_workers_end_with_a_parent_killed_outright(tmp_path, recorded_run):
    pytest.importorskip("imageio_ffmpeg")
    recorded_run(tmp_path / "r", rows=200)
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    cmd = [sys.executable, "-m", "simpro_mj.commands.main", "render", str(tmp_path / "r"),
           "--jobs", "2", "--size", "32x32", "--fps", "240", "--speed", "0.01",
           "--no-strip"]  # fmt: skip
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120  # a guard against a broken build, not a timing
        kids: set[int] = set()
        while len(kids) < 3:  # two workers and the resource tracker
            assert proc.poll() is None and time.monotonic() < deadline, "render ended early"
            kids = _children(proc.pid)
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        deadline = time.monotonic() + 30  # workers poll their parent every 0.5 s
        while any(_alive(k) for k in kids):
            assert time.monotonic() < deadline, [k for k in kids if _alive(k)]
            time.sleep(0.05)
    finally:
        if proc.poll() is None:
            proc.kill()
