"""Controllers for the heavy cabin: joint loops placed on the plant's identified
models (``design_plant: auto``), the dead band against seal friction, the preset's
controller block (docs/paper-notes.md, controllers for the heavy cabin)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import simpro_mj.identification.auto as ai
from controllers.dead_band import dead_band
from controllers.joint import JointControllers
from controllers.task_space import TaskSpaceController
from simpro_mj.analysis.metrics import compute_metrics
from simpro_mj.analysis.verdict import verdict
from simpro_mj.config.presets import load_preset
from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.sim.loop import simulate

HOME = TaskSpaceController().geometry.home
HEAVY = "plant.preset=heavy_cabin"
# the seal friction of a DNC-125 on every leg (the cabin's plant: docs/paper-notes.md)
SEALS = "actuator.pneumatics.cylinder.coulomb_friction_n=[150, 150, 150]"


def test_dead_band_is_zero_inside_and_continuous_at_its_edges():
    w = 1e-3
    assert dead_band(0.9e-3, w) == 0.0 and dead_band(-w, w) == 0.0
    assert dead_band(1.5e-3, w) == pytest.approx(0.5e-3)
    assert dead_band(-1.5e-3, w) == pytest.approx(-0.5e-3)
    assert dead_band(w * (1 + 1e-9), w) == pytest.approx(0.0, abs=1e-11)  # no step
    assert dead_band(0.3e-3, 0.0) == 0.3e-3  # width 0: none
    assert math.isnan(dead_band(math.nan, w))  # a NaN is not hidden


def test_joint_dead_band_holds_the_valve_at_centre_inside_and_shifts_the_error_outside():
    band = JointControllers(dead_band=1e-3)
    free = JointControllers()
    # within the band for 200 steps: every state stays zero, the valves at 5 V centre
    for _ in range(200):
        v = band.update([0.2505, 0.25, 0.25], [0.25, 0.2509, 0.25])
        assert v.tolist() == [5.0, 5.0, 5.0]
    assert not np.any(band.state)
    # outside: the same commands as a controller without the band given e -+ 1 mm
    for k in range(50):
        e = 1e-3 + 2e-3 * np.sin(0.1 * k) * np.array([1.0, -1.0, 0.5])
        shifted = np.sign(e) * np.maximum(np.abs(e) - 1e-3, 0.0)
        np.testing.assert_allclose(band.update(e, [0.0] * 3), free.update(shifted, [0.0] * 3),
                                   rtol=1e-12, atol=1e-12)  # fmt: skip
    with pytest.raises(ValueError, match="dead_band"):
        JointControllers(dead_band=-1e-3)


def test_task_space_dead_band_holds_the_integrated_pose_within_the_band():
    band = np.radians([0.02, 0.02, 0.0])
    band[2] = 0.2e-3
    ctl = TaskSpaceController("I", gains=3.0, dead_band=band)
    ctl.reset()
    inside = HOME + np.array([np.radians(0.019), -np.radians(0.015), 0.15e-3])
    for _ in range(10):
        ctl.update(HOME, inside)
    np.testing.assert_array_equal(ctl.pose_command, HOME)
    # 0.05 deg of pitch error: 0.03 deg past the band, integrated at T K K_I = 0.18 per period
    ctl.update(HOME, HOME + np.array([0.0, np.radians(0.05), 0.0]))
    ctl.update(HOME, HOME)
    assert ctl.pose_command[1] - HOME[1] == pytest.approx(-0.18 * np.radians(0.03), rel=1e-9)


def test_design_plant_auto_is_the_paper_plant_on_paper_and_identified_on_other_presets():
    assert load_scenario("step_pitch")["controller"]["inner"]["design_plant"] == "paper"
    heavy = load_scenario("step_pitch", [HEAVY])
    assert heavy["controller"]["inner"]["design_plant"] == "identified"
    kept = load_scenario("step_pitch", [HEAVY, "controller.inner.design_plant=paper"])
    assert kept["controller"]["inner"]["design_plant"] == "paper"
    with pytest.raises(UserInputError, match="controller.inner.design_plant.*'auto'"):
        load_scenario("step_pitch", ["controller.inner.design_plant=own"])


def test_the_presets_controller_block_lies_under_the_scenarios_own_values():
    preset = load_preset("heavy_cabin")["controller"]
    heavy = load_scenario("step_pitch", [HEAVY])["controller"]
    assert heavy["outer"]["dead_band"] == preset["outer"]["dead_band"]
    assert heavy["setpoint_filter"]["time_ms"] == preset["setpoint_filter"]["time_ms"]
    assert heavy["outer"]["gains"] == [3.0, 3.0, 3.0]  # the scenario's, the preset has none
    own = load_scenario("step_pitch", [HEAVY, "controller.outer.dead_band.pitch_deg=0"])
    assert own["controller"]["outer"]["dead_band"]["pitch_deg"] == 0.0
    # the paper preset carries no controller block: no dead band
    paper = load_scenario("step_pitch")["controller"]
    assert paper["outer"]["dead_band"] == {"roll_deg": 0.0, "pitch_deg": 0.0, "heave_mm": 0.0}
    assert paper["inner"]["dead_band_mm"] == [0.0, 0.0, 0.0]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SIMPRO_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(ai, "_memo", {})


def _run(*sets):
    """(scenario, verdict, metrics, columns) of the cabin's pitch step."""
    sc = load_scenario("step_pitch", [HEAVY, SEALS, "duration_s=12", *sets])
    res = simulate(sc)
    assert res.status == "ok", res.reason  # ran to its end
    return sc, verdict(res.columns, res.sensor_floor), compute_metrics(res.columns, sc), res.columns


def test_the_cabin_with_seal_friction_settles_with_the_dead_band_and_hunts_without(cache):
    """150 N Coulomb per leg: the I law keeps integrating what friction holds and
    the platform hunts (a limit cycle at about 1 Hz); the preset's 0.02 deg / 0.2 mm
    band stops it, and the pitch step meets the cabin's floors."""
    sc, judged, m, c = _run()
    assert sc["controller"]["inner"]["design_plant"] == "identified"
    assert judged["status"] == "ok", judged["reason"]
    pitch = m["axes"]["pitch"]
    assert pitch["overshoot_pct"] <= 10.0 and pitch["settling_time_s"] <= 3.0
    after = c["time_s"] >= 1.0
    assert np.abs(c["heave_m"][after] - c["heave_ref_m"][after]).max() <= 2e-3
    zero = "controller.outer.dead_band={roll_deg: 0, pitch_deg: 0, heave_mm: 0}"
    _, hunting, _, _ = _run(zero)
    assert hunting["status"] == "limit_cycle", hunting["reason"]
    assert 0.5 <= hunting["frequency_hz"] <= 2.0
