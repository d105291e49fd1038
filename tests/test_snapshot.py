"""Snapshot and restore: a run stopped at 0.7 s and resumed is the run never stopped.

Bit for bit on one machine, with the compiled and the interpreted step, on
the same simulation object and on a fresh one of the same scenario; the
heavy cabin carries sensor noise and seal friction in the state. A snapshot
from another scenario or model is refused, naming the field.
"""

from __future__ import annotations

import numpy as np
import pytest

from simpro_mj.config.scenario import load_scenario
from simpro_mj.sim.build import Build
from simpro_mj.sim.snapshot import NoiseState
from simpro_mj.sim.stages import NoiseBlock

SNAP_K = 700  # 0.7 s at 1 ms
CASES = {
    "step_pitch": ["duration_s=1.5"],
    "heavy_cabin": ["duration_s=1.5", "plant.preset=heavy_cabin"],
}
KERNELS = ["python", "numba"]


def _scenario(case):
    return load_scenario("step_pitch.yaml", CASES[case])


def _snap_at(sim, k_snap, out):
    def pace(k, log):
        if k == k_snap:
            out.append(sim.snapshot())
        return k_snap if k < k_snap else sim.n_steps + 1

    return pace


def _same(a, b):
    assert a.status == b.status and a.sim["steps"] == b.sim["steps"]
    assert a.columns.keys() == b.columns.keys()
    for col, x in a.columns.items():
        assert np.array_equal(x, b.columns[col], equal_nan=True), col
    assert np.array_equal(a.qpos, b.qpos)


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("case", sorted(CASES))
def test_resumed_run_equals_uninterrupted(case, kernel, monkeypatch):
    if kernel == "numba":
        pytest.importorskip("numba")
    monkeypatch.setenv("SIMPRO_KERNEL", kernel)
    scenario = _scenario(case)
    whole = Build(scenario).simulation().run()
    sim = Build(scenario).simulation()
    snaps = []
    a = sim.run(pace=_snap_at(sim, SNAP_K, snaps))
    (snap,) = snaps
    assert snap.k == SNAP_K and snap.log.shape[0] == SNAP_K // sim.decimation
    sim.restore(snap)
    b = sim.run()
    fresh = Build(scenario).simulation()
    fresh.restore(snap)
    c = fresh.run()
    for res in (a, b, c):
        _same(whole, res)
    assert whole.sim["steps"] == 1500
    # the resumed part moved: the pitch step (0.1 rad class) and noisy sensors
    assert np.ptp(whole.columns["pitch_rad"][SNAP_K // sim.decimation :]) > 0
    assert np.ptp(whole.columns["u1_v"]) > 0


def test_snapshot_holds_copies(monkeypatch):
    monkeypatch.setenv("SIMPRO_KERNEL", "python")
    sim = Build(_scenario("heavy_cabin")).simulation()
    snaps = []
    sim.run(pace=_snap_at(sim, 300, snaps))
    (snap,) = snaps
    for a, b in ((snap.S, sim.S), (snap.log, sim._log.log), (snap.noise.rows, sim.noise.rows)):
        assert not np.shares_memory(a, b)
    # the run went on after the snapshot: its state moved, the snapshot's did not
    assert not np.array_equal(snap.S, sim.S)


def test_restore_refuses_another_scenario_or_model(monkeypatch):
    monkeypatch.setenv("SIMPRO_KERNEL", "python")
    sim = Build(load_scenario("step_pitch.yaml", ["duration_s=0.2"])).simulation()
    snaps = []
    sim.run(pace=_snap_at(sim, 100, snaps))
    other = Build(load_scenario("step_pitch.yaml", ["duration_s=0.2", "seed=7"])).simulation()
    with pytest.raises(ValueError, match="field 'scenario'"):
        other.restore(snaps[0])
    heavy = load_scenario("step_pitch.yaml", ["duration_s=0.2", "plant.preset=heavy_cabin"])
    heavy = Build(heavy).simulation()
    with pytest.raises(ValueError, match="field 'model'"):
        heavy.restore(snaps[0])
    with pytest.raises(ValueError, match="no run has started"):
        other.snapshot()
    faulty = Build(load_scenario("fault_supply_drop.yaml")).simulation()
    with pytest.raises(ValueError, match="at faults"):
        faulty.snapshot()


LONG = {
    # past the noise block's 4096 draws: the resumed block refills from its generator
    "heavy_cabin_4.5s": ("step_pitch.yaml", ["duration_s=4.5", "plant.preset=heavy_cabin"]),
    # the head accelerometer is logged from MuJoCo's sensor values of the step before
    "cue_step_fx": ("cue_step_fx.yaml", ["duration_s=1.5"]),
}


@pytest.mark.parametrize("case", sorted(LONG))
def test_restored_into_a_fresh_simulation(case, monkeypatch):
    pytest.importorskip("numba")
    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    scenario = load_scenario(*LONG[case])
    whole = Build(scenario).simulation().run()
    sim = Build(scenario).simulation()
    snaps = []
    sim.run(pace=_snap_at(sim, SNAP_K, snaps))
    fresh = Build(scenario).simulation()
    fresh.restore(snaps[0])
    _same(whole, fresh.run())
    assert whole.sim["steps"] == fresh.n_steps


def test_noise_state_resumes_the_generator():
    """A block that refilled before the snapshot goes on with the stream's own rows."""
    whole = np.random.default_rng(3).standard_normal((40, 6))
    block = NoiseBlock(np.random.default_rng(3), block=8)
    for i in range(0, 20, 4):
        block.ensure(i, i + 4)
    state = NoiseState.of(block)
    fresh = NoiseBlock(np.random.default_rng(3), block=8)
    state.into(fresh)
    for i in range(20, 40, 4):
        i0 = fresh.ensure(i, i + 4)
        assert np.array_equal(fresh.rows[i - i0 : i - i0 + 4], whole[i : i + 4])
