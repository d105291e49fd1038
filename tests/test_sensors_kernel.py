"""The compiled sensor kernel and fused state read (numba, ``SIMPRO_KERNEL``) equal the Python path.

``Sensors.sample_floats`` and the loop's ``StateReader.read`` + sensors +
``loop_closure_max`` run in ``simpro_mj/plant/sensors_kernel.py`` when numba is
selected; the results must be the Python path's bits (round-half-even, the
sign of a quantised zero, NaN), so every comparison here is exact.
"""

from __future__ import annotations

import struct

import mujoco
import numpy as np
import pytest

from simpro_mj.config.scenario import load_scenario
from simpro_mj.plant import kernels as pk
from simpro_mj.plant.model import StateReader
from simpro_mj.plant.sensors import DEFAULT_SENSORS, SensorConfig, Sensors
from simpro_mj.sim.loop import CoSimulation

needs_numba = pytest.mark.skipif(not pk._HAVE_NUMBA, reason="numba not installed")


def _bits(values) -> list:
    """Each float's IEEE bit pattern (tells -0.0 from 0.0; NaN equals NaN)."""
    return [struct.pack("<d", float(v)) for v in values]


def _tree(**changes) -> dict:
    tree = {k: dict(v) for k, v in DEFAULT_SENSORS.items()}
    for path, value in changes.items():
        group, key = path.split("__")
        tree[group][key] = value
    return tree


def _pair(monkeypatch, tree, seed=3, block=4096):
    cfg = SensorConfig.from_tree(tree, 1e-3)
    monkeypatch.setenv("SIMPRO_KERNEL", "python")
    a = Sensors(cfg, np.random.default_rng(seed), block=block)
    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    b = Sensors(cfg, np.random.default_rng(seed), block=block)
    assert a._kb is None and b._kb is not None
    return a, b


def test_python_path_has_no_kernel(monkeypatch):
    monkeypatch.setenv("SIMPRO_KERNEL", "python")
    s = Sensors(SensorConfig.from_tree(DEFAULT_SENSORS, 1e-3), np.random.default_rng(0))
    assert s._kb is None


@needs_numba
@pytest.mark.parametrize(
    "tree",
    [
        _tree(),
        _tree(
            potentiometer__offset_mm=[0.4, -0.3, 0.05],
            potentiometer__gain_error_pct=[0.5, -1.0, 0.2],
            potentiometer__rate_ms=2,
            height_encoder__noise_mm=0.02,
            height_encoder__rate_ms=3,
            imu__bias_deg=[0.1, -0.05],
            imu__rate_ms=7,
        ),
        _tree(height_encoder__resolution_mm=0.0, potentiometer__bits=8),
        _tree(potentiometer__noise_lsb=0.0, imu__noise_deg=0.0, height_encoder__noise_mm=0.0),
    ],
)
def test_kernel_equals_python_on_random_inputs(monkeypatch, tree):
    # a small block: the noise is redrawn many times along the way
    a, b = _pair(monkeypatch, tree, block=37)
    rng = np.random.default_rng(11)
    a.reset([0.25] * 3, [0.01, -0.02, 1.2])
    b.reset([0.25] * 3, [0.01, -0.02, 1.2])
    lsb, res = a.cfg.pot_lsb_m, a.cfg.enc_res_m
    for k in range(1, 4000):
        q = rng.uniform(-0.3, 0.8, 3)  # past the ADC's rails too
        pose = [rng.normal(0, 0.1), rng.normal(0, 0.1), rng.uniform(1.0, 1.5)]
        if k % 5 == 1:  # exact halves of an LSB and values that quantise to -0.0
            q = rng.integers(-3, 4, 3) * 0.5 * lsb
            pose[2] = (rng.integers(-3, 4) * 0.5 * res) if res > 0 else -1e-9
        if k % 13 == 0:
            q = -rng.uniform(0, 0.4 * lsb, 3)
        force = k % 97 == 0
        args = (q, pose) if k % 2 else (q.tolist(), pose)
        if k % 3:
            qa, pa = a.sample_floats(k, *(np.asarray(x).tolist() for x in args), force)
            qb, pb = b.sample_floats(k, *(np.asarray(x).tolist() for x in args), force)
        else:  # the array API goes through the same path
            qa, pa = a.sample(k, *args, force=force)
            qb, pb = b.sample(k, *args, force=force)
        assert _bits(qa) == _bits(qb) and _bits(pa) == _bits(pb), k
        assert _bits(a._imu_state) == _bits(b._k_imu), k
    # both drew the same noise blocks from the same generator
    assert a.rng.bit_generator.state == b.rng.bit_generator.state


@needs_numba
def test_kernel_rounds_like_python(monkeypatch):
    """Half-even, +0.0 for a value quantised to zero, NaN and inf passed through."""
    a, b = _pair(monkeypatch, _tree(potentiometer__noise_lsb=0.0, height_encoder__noise_mm=0.0))
    lsb, res = a.cfg.pot_lsb_m, a.cfg.enc_res_m
    cases = [
        ([0.5 * lsb, 1.5 * lsb, 2.5 * lsb], -0.5 * res),
        ([-0.5 * lsb, -1.5 * lsb, -0.2 * lsb], -0.3 * res),
        ([-0.0, 0.0, 1e300], 2.5 * res),
        ([np.nan, np.inf, -np.inf], np.nan),
        ([0.1, 0.2, 0.3], np.inf),
    ]
    for k, (q, h) in enumerate(cases):
        qa, pa = a.sample_floats(k, q, [0.0, 0.0, h], force=True)
        qb, pb = b.sample_floats(k, q, [0.0, 0.0, h], force=True)
        assert _bits(qa) == _bits(qb) and _bits(pa) == _bits(pb), k
    qa, pa = a.sample_floats(9, [-0.2 * lsb] * 3, [0.0, 0.0, -0.2 * res], force=True)
    assert _bits(qa[:1]) == _bits([0.0]) and _bits(pa[2:]) == _bits([0.0])  # not -0.0


def _runs(monkeypatch, name, overrides, front_off=False):
    out = {}
    for kernel in ("python", "numba"):
        monkeypatch.setenv("SIMPRO_KERNEL", kernel)
        if front_off and kernel == "numba":
            monkeypatch.setattr(StateReader, "buffer_view", lambda self: None)
        res = CoSimulation(load_scenario(name, overrides)).run()
        assert res.status == "ok", res.reason
        out[kernel] = res
    return out["python"], out["numba"]


@needs_numba
@pytest.mark.parametrize(
    "overrides",
    [
        ["duration_s=1.5"],
        ["duration_s=1.5", "logging.decimation=7"],
        [
            "duration_s=2",
            "faults=[{type: sensor_frozen, time_s: 0.5, sensor: imu, axis: pitch}, "
            "{type: sensor_dropout, time_s: 0.3, end_s: 1.5, sensor: imu, axis: roll, "
            "probability: 0.5}, {type: sensor_bias, time_s: 0.7, sensor: height_encoder, "
            "bias_mm: 2.0}, {type: potentiometer_failure, time_s: 1.2, leg: 3, mode: open}]",
        ],
    ],
)
def test_cosimulation_bit_identical(monkeypatch, overrides):
    a, b = _runs(monkeypatch, "step_pitch", overrides)
    assert set(a.columns) == set(b.columns)
    for col in a.columns:
        assert np.array_equal(a.columns[col], b.columns[col], equal_nan=True), col
    assert a.sim["max_loop_closure_error_m"] == b.sim["max_loop_closure_error_m"]


@needs_numba
def test_cosimulation_without_the_fused_read(monkeypatch):
    """If MuJoCo's state is not one buffer, the loop reads in Python: same bits."""
    a, b = _runs(monkeypatch, "step_roll", ["duration_s=1"], front_off=True)
    for col in a.columns:
        assert np.array_equal(a.columns[col], b.columns[col], equal_nan=True), col


@needs_numba
def test_front_equals_read_sample_and_loop_closure(monkeypatch):
    """The fused call against StateReader.read + sample_floats + loop_closure_max."""
    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    cs = CoSimulation(load_scenario("step_heave", ["duration_s=0.3"]))
    cs.run()
    m, d = cs.model, cs.data
    reader = StateReader(m, d, cs.idx)
    front = cs.sensors.front(reader)
    assert front is not None
    monkeypatch.setenv("SIMPRO_KERNEL", "python")
    ref = Sensors(cs.sensor_cfg, np.random.default_rng(5), block=50)
    cs.sensors.rng = np.random.default_rng(5)
    cs.sensors.block = 50
    cs.sensors._init_kernel()
    front = cs.sensors.front(reader)
    q, _, pose, _ = reader.read()
    ref.reset(q, pose)
    cs.sensors.reset(q, pose)
    rng = np.random.default_rng(2)
    for k in range(1, 300):
        d.ctrl[:] = rng.normal(0, 200, m.nu)
        mujoco.mj_step(m, d)
        mujoco.mj_step1(m, d)
        q, qd, pose, x = reader.read()
        qm, pm = ref.sample_floats(k, q, pose)
        got = front(k)
        want = (q, qd, pose, qm, pm, [reader.loop_closure_max(x)])
        for g, w in zip(got[:5] + ([got[5]],), want, strict=True):
            assert _bits(g) == _bits(w), k
