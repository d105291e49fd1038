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
