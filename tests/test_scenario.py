"""Scenarios: loading, overrides, validation messages, reachability, reference()."""

import json
import math

import numpy as np
import pytest

from controllers.errors import WorkspaceError
from controllers.geometry import H0
from controllers.kinematics import reachable
from simpro_mj.config.models import DEFAULT_SCENARIO
from simpro_mj.config.reference import SetpointError, reference
from simpro_mj.config.scenario import (
    load_scenario,
    resolve_scenario,
    scenario_hash,
    scenarios_dir,
    shipped_scenarios,
)
from simpro_mj.core.errors import UserInputError

SHIPPED = [
    "cue_braking",
    "cue_braking_turn",
    "cue_bump",
    "cue_lane_change",
    "cue_ramp_fx",
    "cue_slalom",
    "cue_step_fx",
    "fault_supply_drop",
    "step_all",
    "step_heave",
    "step_pitch",
    "step_roll",
    "sweep_cueing",
    "sweep_monte_carlo",
    "sweep_outer_gain",
    "sweep_robustness",
    "sweep_seal_friction",
    "track_cues",
    "track_sines",
]


def test_shipped_scenarios_load_and_validate():
    assert shipped_scenarios() == SHIPPED
    for name in SHIPPED:
        s = load_scenario(name).model_dump()  # the resolved document
        assert s["name"] == name
        # track_cues' base is the feed-forward scheme (its sweep adds the other two)
        # moving set-points (tracking, cueing) go through the feed-forward scheme
        moving = name == "track_cues" or name.startswith(("cue_", "sweep_cueing"))
        assert s["controller"]["mode"] == ("feedforward" if moving else "task_space")
        assert s["duration_s"] > 0
        # every key of the defaults is present in the resolved scenario
        assert set(s) == set(DEFAULT_SCENARIO)
        assert set(s["plant"]) == set(DEFAULT_SCENARIO["plant"])
    assert load_scenario("step_pitch.yaml") == load_scenario("step_pitch")


def test_found_from_any_folder_by_name_and_by_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert load_scenario("step_pitch").name == "step_pitch"
    path = scenarios_dir() / "step_roll.yaml"
    assert load_scenario(str(path)).name == "step_roll"


def test_env_overrides_the_shipped_folder(tmp_path, monkeypatch):
    (tmp_path / "mine.yaml").write_text("duration_s: 2.0\n")
    monkeypatch.setenv("SIMPRO_SCENARIOS", str(tmp_path))
    assert shipped_scenarios() == ["mine"]
    s = load_scenario("mine")
    assert s.name == "mine" and s.duration_s == 2.0


def test_as_built_defaults_and_plant_tree():
    s = load_scenario("step_pitch").model_dump()  # the resolved document
    plant = s["plant"]
    assert plant["payload"]["com_mm"] == [60.0, 0.0, 400.0]
    assert plant["anchor_offsets_mm"]["A2"] == [3.0, 0.0, -2.0]
    assert plant["guide"] == {"radius_offset_mm": 4.0, "centre_offset_mm": [3.0, -2.0]}
    assert s["sensors"]["potentiometer"]["offset_mm"] == [1.5, -1.0, 2.0]
    assert s["sensors"]["potentiometer"]["gain_error_pct"] == [0.8, -0.6, 0.5]
    # the plant tree is accepted by the model loader as is
    from simpro_mj.plant.model import load_spec

    load_spec(plant)


def test_sets_apply_after_file_and_before_validation():
    s = load_scenario(
        "step_pitch",
        [
            "controller.mode=joint_only",
            "duration_s=4",
            "controller.outer.gains=[1, 2, 3]",
            "plant.payload={mass_kg: 100}",  # a mapping merges: com_mm kept
            "setpoint.heave_mm=[{type: ramp, start_s: 1, end_s: 2, value: 10}]",
        ],
    ).model_dump()  # the resolved document
    assert s["controller"]["mode"] == "joint_only"
    assert s["duration_s"] == 4.0 and isinstance(s["duration_s"], float)
    assert s["controller"]["outer"]["gains"] == [1.0, 2.0, 3.0]
    assert s["plant"]["payload"] == {
        "mass_kg": 100.0,
        "com_mm": [60.0, 0.0, 400.0],
        "inertia_kg_m2": None,
        "inertia_mass_kg": None,
    }
    assert s["setpoint"]["heave_mm"][0]["type"] == "ramp"
    # validation runs after the overrides: an override can make a file valid
    with pytest.raises(UserInputError, match="duration_s"):
        load_scenario("step_pitch", ["duration_s=0"])


def test_hash_is_canonical():
    a = load_scenario("step_pitch")
    b = load_scenario("step_pitch", ["duration_s=20", "controller.outer.period_ms=60.0"])
    assert scenario_hash(a) == scenario_hash(b)
    c = load_scenario("step_pitch", ["seed=2"])
    assert scenario_hash(a) != scenario_hash(c)
    assert len(scenario_hash(a)) == 64


def test_sine_optional_keys_are_spelled_out():
    s = load_scenario("track_sines").model_dump()  # the resolved document
    comp = s["setpoint"]["roll_deg"][0]
    assert comp == {
        "type": "sine",
        "amplitude": 3.0,
        "period_s": 8.0,
        "phase_deg": 0.0,
        "start_s": 1.0,
        "end_s": None,
    }


BAD_SETS = [
    # (override, field named in the message, other words that must appear)
    (["controller.outr.gains=[1,1,1]"], "controller.outr", ["did you mean 'outer'"]),
    (["duration_s=abc"], "duration_s", ["wrong type", "number"]),
    (["duration_s=0"], "duration_s", ["0.01..3600 s"]),
    (["duration_s=-3"], "duration_s", ["0.01..3600 s"]),
    (["controller.outer.period_ms=2.5"], "controller.outer.period_ms", ["multiple of the 1 ms"]),
    (["sensors.imu.rate_ms=0"], "sensors.imu.rate_ms", ["multiple"]),
    (["controller.mode=task"], "controller.mode", ["joint_only", "task_space"]),
    (["controller.inner.variant=fancy"], "controller.inner.variant", ["printed", "redesigned"]),
    (["actuator.model=linar"], "actuator.model", ["did you mean 'linear'"]),
    (["controller.outer.delay_samples=3"], "controller.outer.delay_samples", ["[1, 2]"]),
    (["controller.clamp_setpoints=1"], "controller.clamp_setpoints", ["true or false"]),
    (["controller.outer.gains=[1, 2]"], "controller.outer.gains", ["list of 3"]),
    (["controller.outer.gains=[1, -2, 3]"], "controller.outer.gains", [">= 0"]),
    (["seed=1.5"], "seed", ["integer"]),
    (["plant.payload.mass_kg=-1"], "plant.payload.mass_kg", ["0..5000 kg"]),
    (["plant.anchor_offsets_mm.A4=[0,0,0]"], "plant.anchor_offsets_mm.A4", ["A1"]),
    (["sensors.potentiometer.bits=0"], "sensors.potentiometer.bits", ["4..24"]),
    (["actuator.pneumatics.valv={}"], "actuator.pneumatics.valv", ["did you mean 'valve'"]),
    (["name=a b"], "name", ["file-name-safe"]),
    (
        ["setpoint.pitch_deg=[{type: table, times_s: [0, 2, 1], values: [0, 1, 2]}]"],
        "setpoint.pitch_deg[0].times_s",
        ["strictly increasing"],
    ),
    (
        ["setpoint.pitch_deg=[{type: table, times_s: [0, 1], values: [0]}]"],
        "setpoint.pitch_deg[0].values",
        ["as many values"],
    ),
    (
        ["setpoint.roll_deg=[{type: stp, time_s: 1, value: 2}]"],
        "setpoint.roll_deg[0].type",
        ["did you mean 'step'"],
    ),
    (
        ["setpoint.roll_deg=[{type: step, time_s: 1, valu: 2}]"],
        "setpoint.roll_deg[0].valu",
        ["did you mean 'value'"],
    ),
    (["setpoint.roll_deg=[{type: step, time_s: 1}]"], "setpoint.roll_deg[0].value", ["missing"]),
    (
        ["setpoint.heave_mm=[{type: ramp, start_s: 2, end_s: 1, value: 5}]"],
        "setpoint.heave_mm[0].end_s",
        ["> start_s"],
    ),
    (
        ["setpoint.heave_mm=[{type: sine, amplitude: 5, period_s: 0}]"],
        "setpoint.heave_mm[0].period_s",
        ["0.002..1e+06 s"],
    ),
    (["setpoint.yaw_deg=[]"], "setpoint.yaw_deg", ["roll_deg"]),
    (["setpoint.roll_deg=3"], "setpoint.roll_deg", ["list of components"]),
    (["duration_s"], "KEY=VALUE", []),
]


@pytest.mark.parametrize("sets, field, words", BAD_SETS, ids=[b[1] for b in BAD_SETS])
def test_bad_inputs_name_the_field(sets, field, words):
    with pytest.raises(UserInputError) as info:
        load_scenario("step_pitch", sets)
    msg = str(info.value)
    assert "\n" not in msg
    assert field in msg
    for word in words:
        assert word in msg
    if field != "KEY=VALUE":
        assert f" at {field}" in msg  # '<what> at <dotted.path>: <what is allowed>'


def test_unknown_key_in_a_file_with_suggestion(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("duration_s: 5.0\ncontroller:\n  outer:\n    gain: [1, 1, 1]\n")
    with pytest.raises(UserInputError, match=r"controller\.outer\.gain: .*did you mean 'gains'"):
        load_scenario(str(path))


def test_unknown_scenario_lists_the_shipped_ones():
    with pytest.raises(UserInputError) as info:
        load_scenario("step_pich")
    msg = str(info.value)
    for name in SHIPPED:
        assert name in msg
    assert "did you mean 'step_pitch'" in msg
    with pytest.raises(UserInputError, match="step_all"):
        load_scenario("/no/such/file.yaml")


def test_invalid_yaml_names_line_and_column(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("name: broken\nduration_s: 5.0\ncontroller:\n  mode: [task_space\n")
    with pytest.raises(UserInputError, match=r"line \d+, column \d+") as info:
        load_scenario(str(path))
    assert "broken.yaml" in str(info.value)
    path.write_text("duration_s: 5.0\nseed: 1\nduration_s: 6.0\n")
    with pytest.raises(UserInputError, match=r"duplicate key 'duration_s'.*|line 3"):
        load_scenario(str(path))
    path.write_text("- a list\n- not a mapping\n")
    with pytest.raises(UserInputError, match="mapping"):
        load_scenario(str(path))


def test_yaml_exponent_without_dot_is_a_number():
    s = load_scenario("step_pitch", ["sensors.imu.noise_deg='5e-3'"])
    assert s.sensors.imu.noise_deg == pytest.approx(0.005)


def test_unreachable_setpoint_names_limit_setpoint_and_time():
    sets = ["setpoint.heave_mm=[{type: step, time_s: 2.0, value: 400}]"]
    with pytest.raises(SetpointError) as info:
        load_scenario("step_pitch", sets)
    msg = str(info.value)
    assert "setpoint" in msg and "t = 2.000 s" in msg
    assert "leg" in msg or "guide" in msg  # the limit, from check_reachable
    assert "clamp_setpoints" in msg
    assert isinstance(info.value, WorkspaceError) and isinstance(info.value, UserInputError)


def test_unreachable_ramp_is_named_at_its_first_unreachable_millisecond():
    """Held poses are checked once; a ramp's first unreachable sample is still the one
    named (against every sample of the 1 ms grid checked one by one)."""
    from controllers.kinematics import reachable

    base = load_scenario("step_pitch", ["setpoint.pitch_deg=[]"]).model_dump()
    sets = ["setpoint.pitch_deg=[]",
            "setpoint.heave_mm=[{type: ramp, start_s: 1.0, end_s: 3.0, value: 400}]"]  # fmt: skip
    with pytest.raises(SetpointError) as info:
        load_scenario("step_pitch", sets)
    t = np.arange(int(round(base["duration_s"] / 1e-3)) + 1) * 1e-3
    sc = dict(base, setpoint=dict(base["setpoint"], heave_mm=[
        {"type": "ramp", "start_s": 1.0, "end_s": 3.0, "value": 400.0}]))  # fmt: skip
    first = t[np.argmin(reachable(reference(sc, t, clamp=False)))]
    assert 1.0 < first < 3.0
    assert f"t = {first:.3f} s" in str(info.value)


def test_clamping_keeps_the_reference_in_the_workspace():
    sets = [
        "setpoint.heave_mm=[{type: step, time_s: 2.0, value: 400}]",
        "controller.clamp_setpoints=true",
    ]
    s = load_scenario("step_pitch", sets)
    t = np.array([0.0, 1.5, 2.5, 10.0])
    x = reference(s, t)
    assert np.all(reachable(x))
    # before the heave step: untouched (pitch 3 deg from 1 s)
    np.testing.assert_allclose(x[1], [0.0, math.radians(3.0), H0], atol=1e-12)
    # after: on the segment from home towards the request, near its boundary
    want = np.array([0.0, math.radians(3.0), H0 + 0.4])
    d = want - np.array([0.0, 0.0, H0])
    frac = np.zeros(3)
    frac[1:] = (x[2] - np.array([0.0, 0.0, H0]))[1:] / d[1:]
    assert x[2, 0] == 0.0
    assert 0.3 < frac[2] < 0.9
    np.testing.assert_allclose(frac[1], frac[2], rtol=1e-9)
    assert not reachable(np.array([0.0, 0.0, H0]) + (frac[2] + 1e-6) * d)
    # unclamped evaluation still gives the raw request
    np.testing.assert_allclose(reference(s, t, clamp=False)[2], want, atol=1e-12)


def _scenario_with(setpoint: dict) -> dict:
    doc = {"setpoint": setpoint, "duration_s": 20.0}
    return resolve_scenario(doc, default_name="hand")


def test_reference_step_ramp_sine_table_against_hand_values():
    s = _scenario_with(
        {
            "roll_deg": [{"type": "step", "time_s": 1.0, "value": 2.0}],
            "pitch_deg": [
                {"type": "ramp", "start_s": 2.0, "end_s": 4.0, "value": 4.0},
                {"type": "sine", "amplitude": 1.0, "period_s": 4.0, "start_s": 1.0, "end_s": 9.0},
            ],
            "heave_mm": [
                {"type": "table", "times_s": [1.0, 3.0, 5.0], "values": [0.0, 20.0, -10.0]},
                {"type": "sine", "amplitude": 10.0, "period_s": 2.0, "phase_deg": 90.0},
            ],
        }
    )
    t = np.array([0.0, 0.999, 1.0, 2.0, 3.0, 4.0, 6.0, 9.0, 12.0])
    x = reference(s, t)
    deg = math.pi / 180.0
    roll = np.array([0, 0, 2, 2, 2, 2, 2, 2, 2]) * deg
    # ramp: 0 until 2 s, 2 deg at 3 s, 4 deg from 4 s; sine from 1 s to 9 s, period 4 s
    ramp = np.array([0, 0, 0, 0, 2, 4, 4, 4, 4])
    sine = np.sin(2 * np.pi * (t - 1.0) / 4.0) * ((t >= 1.0) & (t < 9.0))
    pitch = (ramp + sine) * deg
    # table: 0 held before 1 s, 10 at 2 s, 20 at 3 s, 5 at 4 s, -10 held after 5 s;
    # sine with phase 90 deg from 0 s: 10 cos(pi t)
    table = np.array([0, 0, 0, 10, 20, 5, -10, -10, -10])
    heave = H0 + (table + 10.0 * np.cos(np.pi * t)) * 1e-3
    np.testing.assert_allclose(x[:, 0], roll, atol=1e-12)
    np.testing.assert_allclose(x[:, 1], pitch, atol=1e-12)
    np.testing.assert_allclose(x[:, 2], heave, atol=1e-12)
    assert x.shape == (t.size, 3)


def test_reference_is_vectorised():
    """One call on 30 000 times gives what one call per time gives (how fast is a
    benchmark's question, not a test's)."""
    s = load_scenario("track_sines")
    t = np.arange(0, 30.0, 0.001)
    x = reference(s, t)
    assert x.shape == (t.size, 3)
    np.testing.assert_allclose(x[0], [0.0, 0.0, H0])
    for k in (0, 1234, 17_000, 29_999):
        np.testing.assert_array_equal(reference(s, t[k : k + 1])[0], x[k])


def test_the_typed_scenario_holds_every_default():
    """Every block's field has its default (the model is the one source of them);
    the plain tree a file is merged over is the model's, and it validates to itself."""
    from pydantic import BaseModel

    from simpro_mj.config.models import Scenario
    from simpro_mj.core.keys import Block

    def blocks(model):
        yield model
        for f in model.model_fields.values():
            if isinstance(f.annotation, type) and issubclass(f.annotation, BaseModel):
                yield from blocks(f.annotation)

    seen = list(blocks(Scenario))
    assert len(seen) >= 15
    missing = [f"{m.__name__}.{k}" for m in seen if issubclass(m, Block)
               for k, f in m.model_fields.items() if f.is_required()]  # fmt: skip
    assert not missing, missing
    assert Scenario.defaults() == DEFAULT_SCENARIO
    named = dict(DEFAULT_SCENARIO, name="defaults")  # the loader names a run (file stem)
    again = Scenario.model_validate(named).model_dump()
    # design_plant "auto" resolves to the plant it means (the paper's on the paper preset)
    assert DEFAULT_SCENARIO["controller"]["inner"]["design_plant"] == "auto"
    assert again["controller"]["inner"]["design_plant"] == "paper"
    again["controller"]["inner"]["design_plant"] = "auto"
    assert json.dumps(again) == json.dumps(named)
    # and the resolved scenario validates to itself
    once = Scenario.model_validate(named).model_dump()
    assert json.dumps(Scenario.model_validate(once).model_dump()) == json.dumps(once)
