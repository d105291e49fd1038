"""Physical plausibility before the simulation: every plant parameter a scenario can
set, every calibration target, and every rate or period a command takes is
refused outside its physical range, in one line naming the field, the range and
why, before anything runs (here: when the scenario loads)."""

from __future__ import annotations

import time

import pytest

from simpro_mj.analysis.targets import load_targets
from simpro_mj.commands.main import main
from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError

PLANT = [
    # (override, field, words of the range or its reason)
    ("plant.payload.com_mm=[1e308,0,0]", "plant.payload.com_mm", "2000 mm"),
    ("plant.payload.com_mm=[0,0,-2500]", "plant.payload.com_mm", "2000 mm"),
    ("plant.anchor_offsets_mm.A1=[1e6,0,0]", "plant.anchor_offsets_mm.A1", "50 mm"),
    ("plant.anchor_offsets_mm.B3=[0,0,-80]", "plant.anchor_offsets_mm.B3", "50 mm"),
    ("plant.anchor_offsets_mm.C1=[0,2,0]", "plant.anchor_offsets_mm.C1", "x-z plane"),
    ("plant.guide.centre_offset_mm=[0,1e9]", "plant.guide.centre_offset_mm", "50 mm"),
    ("plant.loop_timeconst_s=1e-320", "plant.loop_timeconst_s", "two physics steps"),
    ("plant.loop_timeconst_s=5", "plant.loop_timeconst_s", "at most 1 s"),
    ("plant.payload.mass_kg=1e308", "plant.payload.mass_kg", "3,750 kg"),
    ("plant.platform_mass_kg=1e-320", "plant.platform_mass_kg", "120 kg as built"),
    ("actuator.pneumatics.valve.spool_bandwidth_hz=1e-320", "spool_bandwidth_hz", "MPYE"),
    ("actuator.pneumatics.cylinder.bore_mm=1e6", "bore_mm", "ISO 15552"),
    ("actuator.pneumatics.cylinder.viscous_friction_n_s_per_m=1e9", "viscous_friction", "10 kN"),
    ("actuator.pneumatics.cylinder.coulomb_friction_n=[1,2,1e7]", "coulomb_friction_n", "40 %"),
    ("actuator.pneumatics.cylinder.dead_volume_cap_l=1e-320", "dead_volume_cap_l", "hose"),
    ("actuator.pneumatics.atmospheric_pressure_kpa=1e-320", "atmospheric_pressure", "Everest"),
    ("actuator.pneumatics.temperature_c=1e4", "temperature_c", "rating"),
    ("controller.outer.gains=[1e6,1e6,1e6]", "controller.outer.gains", "K T = 2"),
]


@pytest.mark.parametrize("override, field, words", PLANT, ids=[p[0] for p in PLANT])
def test_an_impossible_plant_is_refused_with_its_range_and_reason(override, field, words):
    t0 = time.process_time()  # CPU time: what the refusal costs, whatever the load
    with pytest.raises(UserInputError) as info:
        load_scenario("step_pitch", [override])
    assert time.process_time() - t0 < 2.0
    msg = str(info.value)
    assert "\n" not in msg and field in msg and words in msg and "allowed" in msg, msg


def test_the_shipped_plant_and_its_offsets_are_inside_the_ranges():
    sc = load_scenario("step_pitch", ["plant.anchor_offsets_mm.A1=[50,0,-50]",
                                      "plant.payload.mass_kg=1000"])  # fmt: skip
    assert sc.plant.anchor_offsets_mm.A1 == [50.0, 0.0, -50.0]


@pytest.mark.parametrize(
    "node, words",
    [
        ("{b: 1, a1: 1, a0: 1e-320}", "actuator1.wn_rad_s"),  # b/a0 = inf
        ("{b: 1e-300, a1: 1, a0: 100}", "velocity_gain_m_s_per_v"),
        ("{wn_rad_s: 20, zeta: 1e3, velocity_gain_m_s_per_v: 0.05}", "zeta"),
        ("{wn_rad_s: 1e5, zeta: 0.5, velocity_gain_m_s_per_v: 0.05}", "1..1000"),
    ],
)
def test_an_impossible_calibration_target_is_refused(tmp_path, node, words):
    p = tmp_path / "t.yaml"
    ok = "{wn_rad_s: 20, zeta: 0.5, velocity_gain_m_s_per_v: 0.05}"
    p.write_text(f"actuator1: {node}\nactuator2: {ok}\nactuator3: {ok}\n")
    with pytest.raises(UserInputError, match="implausible target") as info:
        load_targets(p)
    assert words in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize(
    "argv, field",
    [
        (["response", "step_pitch", "--freq-hz", "1e-320"], "--freq-hz"),
        (["response", "step_pitch", "--amplitude-deg", "1e-320"], "--amplitude-deg"),
        (["analyze", "--set", "outer.period_s=1e-320", "--no-plots"], "outer.period_s"),
        (["analyze", "--set", "inner.dt_s=1e-320", "--no-plots"], "inner.dt_s"),
        (["render", "{run}", "--speed", "1e-320"], "--speed"),
        (["render", "{run}", "--fps", "1e-320"], "--fps"),
    ],
)
def test_a_subnormal_rate_or_period_is_one_line(tmp_path, capsys, recorded_run, argv, field):
    if "{run}" in argv:  # a result folder with a recording (no simulation)
        recorded_run(tmp_path / "r")
        argv = [a.replace("{run}", str(tmp_path / "r")) for a in argv]
    t0 = time.process_time()  # CPU time: what the refusal costs, whatever the load
    assert main(argv) == 2
    assert time.process_time() - t0 < 2.0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and field in err[0] and "internal error" not in err[0], err


@pytest.mark.parametrize("key", ["duration_s\n", "dura\x1b[2Jtion_s", "seed\r", "a.\x00b"])
def test_a_set_key_with_a_control_character_is_refused(key):
    with pytest.raises(UserInputError, match="control character U\\+00") as info:
        load_scenario("step_pitch", [f"{key}=3"])
    assert "\n" not in str(info.value)


def test_names_never_hold_a_path_separator(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for argv in (["calibrate", "--name", "../cal_trav"], ["calibrate", "--name", "a/b"]):
        assert main(argv) == 2
        assert "no path separator" in capsys.readouterr().err
    with pytest.raises(UserInputError, match="file-name-safe"):
        load_scenario("step_pitch", ["name=../x"])
    assert list(tmp_path.iterdir()) == []
