"""The batch's progress line: counts, the expected time left, each worker's variant
and phase (simpro_mj/sim/executors.py Progress)."""

from __future__ import annotations

import time

import pytest

from simpro_mj.sim.executors import Progress


def test_line_names_each_worker_and_the_time_left():
    now = time.monotonic()
    activity = {
        "w1": ("sample_007", "identifying", now - 3.0),
        "w2": ("sample_012", "simulating", now - 1.0),
    }
    bar = Progress(10, enabled=False, activity=activity, workers=2)
    assert "time left" not in bar.line()  # nothing finished: no estimate yet
    for wall in (4.0, 6.0):
        bar.update("ok", wall)
    bar.update("limit_cycle", 5.0)
    text = bar.line()
    assert text.startswith("ok=2 not ok=1 left=7")
    # 7 left x 5 s mean, less the 4 s the running two have done, over 2 workers
    eta = float(text.split("time left ~")[1].split(" s")[0])
    assert eta == pytest.approx((7 * 5.0 - 4.0) / 2, abs=1.0)
    assert "sample_007: identifying 3 s" in text and "sample_012: simulating 1 s" in text
    bar.close()


def test_pool_workers_say_their_phases_to_the_line(monkeypatch):
    """A pool worker puts its variant's phases on its parent's queue; the parent's
    reader keeps them for the line and drops a worker whose variant ended."""
    import multiprocessing
    import queue as queues

    from simpro_mj.batch import worker
    from simpro_mj.sim.executors import _Activity

    said = queues.Queue()
    monkeypatch.setattr(worker, "activity_queue", lambda: said)
    monkeypatch.setattr(worker, "_run_variant", lambda task: {"status": "ok"})
    worker.run_variant({"scenario": {}, "out": "out/mc003", "label": "mc003"})
    first, last = said.get_nowait(), said.get_nowait()
    assert first[0].startswith("pid ") and first[1:3] == ("mc003", "preparing")
    assert last == (first[0], None, None, None) and not worker.ACTIVITY

    q = multiprocessing.get_context("spawn").Queue()
    into: dict = {}
    reader = _Activity(q, into)
    try:
        q.put(("pid 7", "mc003", "simulating", time.monotonic() - 2.0))
        deadline = time.monotonic() + 10.0
        while "pid 7" not in into and time.monotonic() < deadline:
            time.sleep(0.01)
        bar = Progress(10, enabled=False, activity=into, workers=2)
        assert "mc003: simulating 2 s" in bar.line()
        q.put(("pid 7", None, None, None))
        while "pid 7" in into and time.monotonic() < deadline:
            time.sleep(0.01)
        assert "mc003" not in bar.line()
    finally:
        reader.close()
