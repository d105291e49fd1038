"""The one step (simpro_mj.sim.step): interpreted and compiled, the callback's manners.

* The same functions run interpreted (``SIMPRO_KERNEL=python``) and compiled
  inside ``mj_step`` (numba) give the same bits on one machine, for every
  controller mode, both actuator models and a run with faults (which runs
  the compiled stages from Python).
* MuJoCo's control callback is process-wide: another ``MjData`` of the same
  model stepped while a run is registered moves exactly as without it, and
  the callback is gone after the run (also after an error).
* The plain functions: the ADC's rounding, the IK against the batched IK.
* Every function the stages call is in the list the compiled form compiles.
"""

from __future__ import annotations

import math
import sys

import mujoco
import numpy as np
import pytest

from controllers import step_functions as sf
from controllers.geometry import nominal_geometry
from controllers.kinematics import inverse_kinematics, reachable
from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.plant.kernels import kernel_choice
from simpro_mj.plant.step_functions import quantise
from simpro_mj.sim.build import Build

numba = pytest.importorskip("numba")


def _run(name, sets, kernel, monkeypatch):
    monkeypatch.setenv("SIMPRO_KERNEL", kernel)
    res = Build(load_scenario(name, sets)).simulation().run()
    return res


CASES = {
    "task_space": ("step_pitch.yaml", ["duration_s=0.6"]),
    "feedforward_joints_average": ("track_cues.yaml", ["duration_s=0.6"]),
    "feedforward_model_PI": (
        "track_cues.yaml",
        ["duration_s=0.6", "controller.feedforward.lag=model", "controller.outer.type=PI",
         "controller.feedforward.average=false"],
    ),
    "joint_only": ("step_roll.yaml", ["duration_s=0.6", "controller.mode=joint_only"]),
    # the cabin's bands, dither and conditional integration; the outer band holding and
    # released (2.5 s: the pose enters its band after the step at 1 s), and its gap kind
    "cabin_band_release": ("step_all.yaml", ["duration_s=2.5", "plant.preset=heavy_cabin"]),
    "cabin_band_gap": (
        "step_all.yaml",
        ["duration_s=2.5", "plant.preset=heavy_cabin", "controller.outer.dead_band.kind=gap"],
    ),
    "linear_plant": ("sweep_outer_gain.yaml", ["duration_s=0.6"]),
    "faults": (
        "fault_supply_drop.yaml",
        ["duration_s=0.6",
         "faults=[{type: supply_drop, time_s: 0.2, pressure_bar_gauge: 2.0, ramp_s: 0.1}, "
         "{type: valve_stuck, time_s: 0.3, leg: 2, voltage_v: 6.5}, "
         "{type: sensor_bias, time_s: 0.1, sensor: height_encoder, bias_mm: 2.0}]"],
    ),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(CASES))
def test_interpreted_and_compiled_agree_bit_for_bit(case, monkeypatch):
    name, sets = CASES[case]
    a = _run(name, sets, "python", monkeypatch)
    b = _run(name, sets, "numba", monkeypatch)
    steps = round(1000 * float(sets[0].split("=")[1]))  # duration_s at 1 ms
    assert a.status == b.status and a.sim["steps"] == b.sim["steps"] == steps
    for col, x in a.columns.items():
        assert np.array_equal(x, b.columns[col], equal_nan=True), col
    assert np.array_equal(a.qpos, b.qpos)
    # the loop acted: the valves moved and the chambers followed (sensor noise at least)
    assert np.ptp(a.columns["u1_v"]) > 0 and np.ptp(a.columns["p1a_pa"]) > 50.0


def test_callback_leaves_other_data_alone(monkeypatch):
    """A second MjData of the same model, stepped while a run is registered, is untouched."""
    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    sim = Build(load_scenario("step_pitch.yaml", ["duration_s=0.3"])).simulation()
    m = sim.model
    other = mujoco.MjData(m)
    other.ctrl[:] = 7.0
    alone = mujoco.MjData(m)
    alone.ctrl[:] = 7.0
    mujoco.mj_step(m, alone, 50)

    def pace(k, log):
        if k == 100:  # mid-run, the callback installed and our run registered
            assert mujoco.get_mjcb_control() is not None
            # MuJoCo's profiler clock frozen: 100 steps timed at 0 s in all
            assert mujoco.get_mjcb_time() is not None
            step_timer = sim.data.timer[mujoco.mjtTimer.mjTIMER_STEP]
            assert step_timer.number == 100 and step_timer.duration == 0.0
            mujoco.mj_step(m, other, 50)
        return k + 100

    res = sim.run(pace=pace)
    assert res.status in ("ok", "not_settled") and res.sim["steps"] == 300
    assert np.array_equal(other.qpos, alone.qpos) and np.array_equal(other.ctrl, alone.ctrl)
    assert mujoco.get_mjcb_control() is None and mujoco.get_mjcb_time() is None


def test_callback_keeps_a_clock_set_before(monkeypatch):
    """A profiler clock set before the run (``mjcb_time``) times it and is left in place."""
    import ctypes

    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    sim = Build(load_scenario("step_pitch.yaml", ["duration_s=0.3"])).simulation()
    ticks = [0.0]

    def clock():
        ticks[0] += 1.0  # 1 "s" per read
        return ticks[0]

    theirs = ctypes.CFUNCTYPE(ctypes.c_double)(clock)
    mujoco.set_mjcb_time(theirs)
    try:
        res = sim.run()
        assert mujoco.get_mjcb_time() is theirs
    finally:
        mujoco.set_mjcb_time(None)
    assert res.sim["steps"] == 300
    assert sim.data.timer[mujoco.mjtTimer.mjTIMER_STEP].duration > 0


def test_callback_removed_after_an_error(monkeypatch):
    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    sim = Build(load_scenario("step_pitch.yaml", ["duration_s=0.3"])).simulation()

    def pace(k, log):
        raise KeyboardInterrupt

    res = sim.run(pace=pace)
    assert res.status == "interrupted" and mujoco.get_mjcb_control() is None
    assert mujoco.get_mjcb_time() is None


def test_kernel_switch(monkeypatch):
    monkeypatch.setenv("SIMPRO_KERNEL", "python")
    assert kernel_choice() == "python"
    monkeypatch.setenv("SIMPRO_KERNEL", "x")
    with pytest.raises(UserInputError) as e:
        kernel_choice()
    assert str(e.value) == (
        "invalid value at SIMPRO_KERNEL: 'x'; allowed: one of ['auto', 'python', 'numba']"
    )


def test_quantise_rounds_half_to_even_like_an_adc():
    assert quantise(2.5, 1.0) == 2.0 and quantise(3.5, 1.0) == 4.0
    assert quantise(-2.5, 1.0) == -2.0 and quantise(0.49, 1.0) == 0.0
    z = quantise(-0.3, 1.0)
    assert z == 0.0 and math.copysign(1.0, z) == 1.0  # no negative zero
    assert math.isnan(quantise(math.nan, 1e-3)) and quantise(math.inf, 1e-3) == math.inf
    lsb = 20.0 / 2**14 / 20.0  # the MF624 count as slide travel (1.22 mV at 20 V/m)
    assert quantise(0.25 + 0.4 * lsb, lsb) == pytest.approx(round(0.25 / lsb) * lsb)


def test_pose_ik_equals_the_batched_ik():
    g = nominal_geometry()
    gc = sf.geometry_constants(g)
    rng = np.random.default_rng(1)
    poses = g.home + rng.uniform(-1, 1, (400, 3)) * [0.2, 0.2, 0.15]
    q = np.empty(3)
    ok = reachable(poses, g)
    for pose, want_ok in zip(poses, ok, strict=True):
        code = sf.ik_pose(*pose, gc, 0.0, True, q)
        assert (code == sf.IK_OK) == bool(want_ok)
        if want_ok:
            np.testing.assert_allclose(q, inverse_kinematics(pose, g), rtol=0, atol=1e-12)
    assert 50 < ok.sum() < 400  # both outcomes are exercised


def _called_by_the_stages(cases, monkeypatch):
    """The code of every project function the stages call in short interpreted runs."""
    from simpro_mj.sim import step

    stages = {f.__code__ for f in (step.sense, step.control, step.actuate, step.record)}
    roots = (str(step.__file__).rsplit("simpro_mj", 1)[0],)
    seen, depth = set(), [0]

    def profile(frame, event, arg):
        code = frame.f_code
        if event == "call":
            if code in stages:
                depth[0] += 1
            elif depth[0] and code.co_filename.startswith(roots):
                seen.add(code)
        elif event == "return" and code in stages:
            depth[0] -= 1

    monkeypatch.setenv("SIMPRO_KERNEL", "python")
    for case in cases:
        name, sets = CASES[case]
        sim = Build(load_scenario(name, [*sets, "duration_s=0.05"])).simulation()
        sys.setprofile(profile)
        try:
            sim.run()
        finally:
            sys.setprofile(None)
    return seen


def test_the_compiled_list_holds_every_function_the_stages_call(monkeypatch):
    """The compile list is read from the code: a run calls nothing outside it.

    Traced in interpreted runs of both actuator models and the outer loop's
    modes; a list without the seal friction law is caught naming it.
    """
    from simpro_mj.sim import step

    called = _called_by_the_stages(
        ["task_space", "feedforward_joints_average", "feedforward_model_PI", "linear_plant"],
        monkeypatch,
    )
    names = {c.co_name for c in called}
    assert {"seal_friction", "joint_step", "outer_update", "linear_step", "ik_pose"} <= names
    compiled = {f.__code__ for f in step._PLAIN}
    assert called <= compiled, sorted(c.co_name for c in called - compiled)
    without = {c for c in compiled if c.co_name != "seal_friction"}
    assert [c.co_name for c in called - without] == ["seal_friction"]
