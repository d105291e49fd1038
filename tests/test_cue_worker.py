"""The MPC in its own process: the same set-points as the law run inline, one period later;
its solve times kept, the child gone after close."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from controllers.geometry import nominal_geometry
from controllers.mpc_cueing import ModelPredictiveCueing
from simpro_mj.config.cue_params import washout_params
from simpro_mj.config.scenario import load_scenario
from simpro_mj.sim.cue_worker import CueWorker
from simpro_mj.sim.scheduling import cpu_split


def _inputs(n):
    for k in range(n):
        t = 0.01 * k
        yield (2.0 * math.sin(t), 1.5 * math.sin(2 * t), 9.7), (0.05 * math.sin(2 * t), 0.0, 0.1)


def test_the_law_in_its_process_plays_the_inline_set_points_one_period_late():
    cue = load_scenario("cue_lane_change.yaml", []).setpoint.cueing
    params = washout_params(cue).replace(preview=0.0)
    geometry = nominal_geometry()
    inline = ModelPredictiveCueing(params, geometry=geometry).stream(0.01)
    worker = CueWorker(params, geometry, 0.01)
    try:
        n = 120  # 1.2 s: 20 solves at the 60 ms period
        want = [inline.step(f, w) for f, w in _inputs(n)]
        got = []
        for f, w in _inputs(n):
            got.append(worker.step(f, w))
            assert worker.settle()  # the test waits for each result; a session never does
        assert np.array_equal(got[0], geometry.home)  # nothing computed yet: home
        # bit for bit: the same computation on the same machine, one period later
        assert all(np.array_equal(got[k + 1], want[k]) for k in range(n - 1))
        assert np.abs(np.array(want)[:, 1]).max() > 1e-3  # the law really moved
        assert worker.late == 0 and worker.periods == n
    finally:
        worker.close()
    assert len(worker.solve_times) >= n // 6 and all(s > 0 for s in worker.solve_times)
    assert not worker._proc.is_alive()


@pytest.mark.skipif(
    not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
    reason="needs two cores to keep one free of the law",
)
def test_the_law_and_every_thread_of_its_process_run_on_the_cores_given():
    """A live session keeps the pacer's core free of the solves: every thread of the
    child (the interpreter's, BLAS's) is on the cores handed to it."""
    cue = load_scenario("cue_lane_change.yaml", []).setpoint.cueing
    params = washout_params(cue).replace(preview=0.0)
    pacer_cpus, law_cpus = cpu_split(os.sched_getaffinity(0))
    worker = CueWorker(params, nominal_geometry(), 0.01, cpus=law_cpus)
    try:
        for f, w in _inputs(12):  # two solves: the solver's threads, if any, exist now
            worker.step(f, w)
            assert worker.settle()
        tids = [int(t) for t in os.listdir(f"/proc/{worker.pid}/task")]
        assert tids and all(os.sched_getaffinity(t) == law_cpus for t in tids)
        assert not law_cpus & pacer_cpus
    finally:
        worker.close()
