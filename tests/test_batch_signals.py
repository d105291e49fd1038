"""Batches end cleanly: signals, a killed parent, a cluster without workers.

Every test that signals a subprocess waits for its readiness file
(``SIMPRO_READY_FILE``, :mod:`simpro_mj.sim.readiness`): the batch writes it once
its handlers are installed and the variants submitted, and each pool worker
writes ``<file>.worker-<pid>`` once its variant steps. The waits are bounded
only so that a broken build fails instead of hanging; nothing depends on how
long anything takes.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from simpro_mj.report import marker

ROOT = Path(__file__).resolve().parents[1]
LONG = 600.0  # s simulated: the variants are still running when the signal comes


def _sweep(tmp_path: Path, n: int = 3) -> Path:
    doc = {
        "name": "long",
        "duration_s": LONG,
        "sweep": {"grid": {"seed": list(range(1, n + 1))}},
    }
    path = tmp_path / "long.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def _start(tmp_path: Path, argv: list[str]) -> tuple[subprocess.Popen, Path]:
    ready = tmp_path / "ready"
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT), SIMPRO_READY_FILE=str(ready))
    proc = subprocess.Popen(
        [sys.executable, "-m", "simpro_mj.commands.main", *argv],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    return proc, ready


def _signal_when_ready(tmp_path: Path, argv: list[str], sig, workers_of=None):
    """Start ``simpro-sim argv``, wait for its readiness file (and for
    ``workers_of(proc, ready)`` to name its workers), send ``sig``, wait for the
    end. Returns ``(returncode, stderr, worker pids, ready path)``."""
    proc, ready = _start(tmp_path, argv)
    workers: list[int] = []
    try:
        _wait_for(ready.is_file, proc)
        if workers_of is not None:
            workers = workers_of(proc, ready)
        proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, stderr, workers, ready


def _stepping_workers(proc, ready: Path) -> list[int]:
    assert ready.read_text().split()[0] == "batch"
    _wait_for(lambda: len(_worker_pids(ready)) == 2, proc)  # both variants stepping
    return _worker_pids(ready)


def _wait_for(condition, proc=None, bound_s: float = 300.0) -> None:
    """Wait until ``condition()`` holds (the bound only keeps a broken build from
    hanging the suite; it is not a timing assumption)."""
    deadline = time.monotonic() + bound_s
    while not condition():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"exited early ({proc.returncode}): {proc.communicate()}")
        if time.monotonic() > deadline:
            raise AssertionError("no readiness signal")
        time.sleep(0.05)


def _alive(pid: int) -> bool:
    """A process that exists and is not a zombie."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _worker_pids(ready: Path) -> list[int]:
    return [int(p.name.rsplit("-", 1)[1]) for p in ready.parent.glob(f"{ready.name}.worker-*")]


def _no_temp_folders(folder: Path) -> bool:
    return not [p for p in folder.rglob("*") if re.search(r"\.simpro-(tmp|old)-", p.name)]


linux = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")


@linux
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_a_signal_stops_the_pool_writes_the_summary_and_exits_130(tmp_path, sig):
    """SIGTERM or SIGHUP, a closed terminal (Ctrl-C takes the same path: each raises
    KeyboardInterrupt in the batch)."""
    out = tmp_path / "out"
    argv = ["batch", str(_sweep(tmp_path)), "--jobs", "2", "--processes", "--out", str(out),
            "--no-plots"]  # fmt: skip
    rc, stderr, workers, _ = _signal_when_ready(tmp_path, argv, sig, _stepping_workers)
    assert rc == 130, stderr
    last = stderr.strip().splitlines()[-1]
    assert last.startswith("error: batch stopped: interrupted"), stderr
    assert "0 variant(s) finished, 3 cancelled" in last and "summary.csv" in last
    assert "Traceback" not in stderr
    assert not [pid for pid in workers if _alive(pid)]  # gone when the batch exits
    doc = json.loads((out / "summary.json").read_text())
    assert doc["stopped"].startswith("interrupted")
    assert [v["status"] for v in doc["variants"]] == ["cancelled"] * 3
    assert all(v["reason"].startswith("not finished: batch stopped") for v in doc["variants"])
    assert (out / "summary.csv").read_text().count("cancelled") == 3
    # the two running variants wrote what they had, marked partial; the third never started
    partial = [out / v["folder"] for v in doc["variants"] if (out / v["folder"]).exists()]
    assert len(partial) == 2
    for folder in partial:
        assert (folder / marker.PARTIAL_MARKER).is_file() and not marker.is_complete(folder)
    assert _no_temp_folders(tmp_path)


@linux
def test_a_signal_stops_a_batch_in_this_process(tmp_path):
    out = tmp_path / "out"
    argv = ["batch", str(_sweep(tmp_path, 2)), "--jobs", "1", "--out", str(out), "--no-plots"]
    rc, stderr, _, _ = _signal_when_ready(tmp_path, argv, signal.SIGINT)
    assert rc == 130, stderr
    assert stderr.strip().splitlines()[-1].startswith("error: batch stopped: interrupted")
    doc = json.loads((out / "summary.json").read_text())
    assert {v["status"] for v in doc["variants"]} <= {"cancelled", "interrupted"}
    assert doc["variants"][1]["status"] == "cancelled"
    assert _no_temp_folders(tmp_path)


@linux
def test_a_signal_stops_a_threaded_batch(tmp_path):
    """``--jobs 2 --threads``: SIGTERM reaches the main thread, the
    running simulations are asked to stop at their next chunk and hand back what
    they computed; the batch writes its summary and exits 130."""
    out = tmp_path / "out"
    argv = ["batch", str(_sweep(tmp_path)), "--jobs", "2", "--threads", "--out", str(out),
            "--no-plots"]  # fmt: skip
    rc, stderr, _, ready = _signal_when_ready(tmp_path, argv, signal.SIGTERM)
    assert ready.read_text().split()[0] == "batch"
    assert rc == 130, stderr
    assert stderr.strip().splitlines()[-1].startswith("error: batch stopped: interrupted")
    assert "Traceback" not in stderr
    doc = json.loads((out / "summary.json").read_text())
    assert {v["status"] for v in doc["variants"]} <= {"cancelled", "interrupted"}
    assert _no_temp_folders(tmp_path)


def _main_thread_waits(ready: Path) -> bool:
    """The batch's tasks submitted (its readiness file) and the main thread in a wait."""
    import threading

    if not ready.is_file():
        return False
    frame = sys._current_frames().get(threading.main_thread().ident)
    while frame is not None:
        if frame.f_code is threading.Condition.wait.__code__:
            return True
        frame = frame.f_back
    return False


def test_a_signal_a_runs_thread_received_stops_the_threads(tmp_path, monkeypatch):
    """The kernel gives a signal sent to the process to any of its threads that does
    not block it; CPython runs the handler in the main thread only, when that thread
    next runs Python code. Here SIGTERM goes to one of the runs' threads (``pthread_kill``)
    while the main thread waits for the tasks: the runs are still stopped, each
    reports ``interrupted``, and the batch sees the signal. (A main thread that
    slept until a task ended let the two 600 s variants of the test above run to
    their end, ``ok``, after the SIGTERM.) The tasks' wait is bounded only so that
    a broken build fails instead of hanging."""
    import threading

    from simpro_mj.core.interrupts import interruptible
    from simpro_mj.sim import readiness
    from simpro_mj.sim.executors import run_threads

    # the handler is installed in the main thread (elsewhere SIGTERM would end pytest)
    assert threading.current_thread() is threading.main_thread()
    ready = tmp_path / "ready"
    monkeypatch.setenv(readiness.ENV, str(ready))
    statuses: dict[int, str] = {}

    def task(t: dict) -> dict:
        if t["first"]:
            _wait_for(lambda: _main_thread_waits(ready))
            signal.pthread_kill(threading.get_ident(), signal.SIGTERM)
        stopped = t["stop"].wait(timeout=60.0)
        return {"status": "interrupted" if stopped else "ok"}

    def done(key: int, result: dict) -> None:
        statuses[key] = result["status"]

    with interruptible(), pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        run_threads([(0, {"first": True}), (1, {"first": False})], 2, done, fn=task)
    assert statuses == {0: "interrupted", 1: "interrupted"}


@linux
@pytest.mark.slow  # process plumbing: 15 s of the suite
@pytest.mark.parametrize("command", ["batch", "dask"])
def test_workers_end_themselves_when_the_parent_is_killed(tmp_path, command):
    """``kill -9`` of the parent: no handler runs there; each worker sees that its
    parent is gone (it was re-parented) and ends itself (Dask's local workers
    watch their parent's pipe)."""
    if command == "dask":
        pytest.importorskip("distributed")
        argv = ["batch", str(_sweep(tmp_path, 2)), "--jobs", "2", "--out", "out", "--no-plots",
                "--scheduler", "local"]  # fmt: skip
    else:
        argv = ["batch", str(_sweep(tmp_path, 2)), "--jobs", "2", "--processes", "--out", "out",
                "--no-plots"]  # fmt: skip
    proc, ready = _start(tmp_path, argv)
    workers: list[int] = []
    try:
        _wait_for(ready.is_file, proc)
        if command == "batch":
            _wait_for(lambda: len(_worker_pids(ready)) == 2, proc)
            workers = _worker_pids(ready)
        else:
            workers = _children_running_spawn(proc.pid)
        assert workers
        proc.kill()
        proc.communicate(timeout=60)
        _wait_for(lambda: not [pid for pid in workers if _alive(pid)])
    finally:
        if proc.poll() is None:
            proc.kill()
        for pid in workers:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


def _children_running_spawn(pid: int) -> list[int]:
    """Pool workers of ``pid`` (spawned: ``spawn_main`` on the command line)."""
    kids = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        text = (task / "children").read_text().split()
        kids += [int(k) for k in text]
    return [k for k in kids if b"spawn_main" in Path(f"/proc/{k}/cmdline").read_bytes()]


@linux
@pytest.mark.slow  # Dask plumbing: a local cluster started and stopped
def test_a_signal_stops_a_local_dask_batch(tmp_path):
    pytest.importorskip("distributed")
    out = tmp_path / "out"
    argv = ["batch", str(_sweep(tmp_path, 2)), "--jobs", "2", "--out", str(out), "--no-plots",
            "--scheduler", "local"]  # fmt: skip
    # ready: the cluster is up and the variants submitted
    workers_of = lambda proc, ready: _children_running_spawn(proc.pid)  # noqa: E731
    rc, stderr, workers, _ = _signal_when_ready(tmp_path, argv, signal.SIGTERM, workers_of)
    assert rc == 130, stderr
    assert stderr.strip().splitlines()[-1].startswith("error: batch stopped: interrupted")
    assert workers and not [pid for pid in workers if _alive(pid)]
    doc = json.loads((out / "summary.json").read_text())
    assert [v["status"] for v in doc["variants"]] == ["cancelled"] * 2


def test_a_dask_cluster_without_workers_ends_the_batch(tmp_path, capsys, monkeypatch):
    distributed = pytest.importorskip("distributed")
    import simpro_mj.batch.runner as batch
    from simpro_mj.commands.main import main

    monkeypatch.setattr(batch, "NO_WORKERS_S", 1.0)  # the stated time, shortened
    with distributed.LocalCluster(
        n_workers=0, processes=False, dashboard_address="127.0.0.1:0"
    ) as cluster:  # a scheduler that has no worker
        out = tmp_path / "out"
        argv = ["batch", "step_pitch", "--scheduler", cluster.scheduler_address, "--out",
                str(out), "--no-plots", "--set", "duration_s=1.1"]  # fmt: skip
        rc = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1
    assert err[-1].startswith("error: batch stopped: no live Dask worker for 1 s at --scheduler")
    assert "1 variant(s) not run" in err[-1] and "summary.csv" in err[-1]
    doc = json.loads((out / "summary.json").read_text())
    assert doc["stopped"].startswith("no live Dask worker")
    assert [v["status"] for v in doc["variants"]] == ["cancelled"]


def _sleep_a_minute(task: dict) -> dict:
    """A pool task that ends ``ok`` after 60 s unless its worker is stopped first."""
    time.sleep(60.0)
    return {"status": "ok"}


def test_a_signal_another_thread_received_stops_the_pool(tmp_path, monkeypatch):
    """The same for the process pool: SIGTERM taken by a thread of the batch other
    than the main one (here one started for it; in a batch the pool's own threads)
    while the main thread waits for the workers. The batch acts on it at once: its
    workers are stopped, and neither task reports an end it never reached (a main
    thread that slept until a task ended would have collected both ``ok`` after a
    minute). The waits are bounded only so that a broken build fails."""
    import threading

    from simpro_mj.core.interrupts import interruptible
    from simpro_mj.sim import readiness
    from simpro_mj.sim.executors import run_pool

    assert threading.current_thread() is threading.main_thread()
    ready = tmp_path / "ready"
    monkeypatch.setenv(readiness.ENV, str(ready))
    statuses: dict[int, str] = {}

    def send() -> None:  # from this thread, not the main one
        _wait_for(lambda: _main_thread_waits(ready))
        signal.pthread_kill(threading.get_ident(), signal.SIGTERM)

    sender = threading.Thread(target=send, name="sender")
    with interruptible(), pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        sender.start()
        run_pool([(0, {}), (1, {})], 2, lambda k, r: statuses.__setitem__(k, r["status"]),
                 fn=_sleep_a_minute)  # fmt: skip
    sender.join()
    assert statuses == {}
