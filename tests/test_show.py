"""Every parameter is discoverable: ``simpro-sim show`` lists it with its value, default,
unit, allowed range and meaning, and a run's ``scenario.yaml`` holds it."""

from __future__ import annotations

import json

import yaml

from simpro_mj import api
from simpro_mj.commands.main import main
from simpro_mj.config.scenario import load_scenario, parameters
from simpro_mj.plant.pneumatics.params import DEFAULT_PNEUMATIC_PARAMS

SUPPLY = "actuator.pneumatics.supply_pressure_bar_gauge"


def test_show_lists_the_supply_pressure_with_its_unit_and_default(capsys):
    assert main(["show", "step_pitch.yaml"]) == 0
    (line,) = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith(SUPPLY)]
    key, value, default, unit = line.split()[:4]
    assert (value, default) == ("6.0", "6.0")  # the plant's 6 bar gauge (FESTO MPYE typical)
    assert "bar gauge" in line and "<= 12" in line  # unit and the plant's plausible range
    assert main(["show", "step_pitch.yaml", "--set", f"{SUPPLY}=4.5", "--json"]) == 0
    rows = {r["key"]: r for r in json.loads(capsys.readouterr().out)["parameters"]}
    assert rows[SUPPLY] == {
        "key": SUPPLY,
        "value": 4.5,
        "default": DEFAULT_PNEUMATIC_PARAMS["supply_pressure_bar_gauge"],
        "unit": "bar gauge",
        "allowed": "> 0 and <= 12",
        "meaning": rows[SUPPLY]["meaning"],
    }
    assert rows["duration_s"]["allowed"] == "0.01..3600"
    assert rows["controller.mode"]["allowed"] == "one of joint_only, task_space, feedforward"


def test_every_parameter_has_a_meaning_and_every_leaf_is_listed():
    """One row per leaf of the resolved scenario (nothing hidden, nothing invented),
    each with one line of meaning."""
    s = load_scenario("step_pitch")
    rows = parameters(s)

    def leaves(tree, prefix=""):
        for k, v in tree.items():
            if isinstance(v, dict) and v and k != "cueing":
                yield from leaves(v, f"{prefix}{k}.")
            else:
                yield f"{prefix}{k}"

    assert [r.key for r in rows] == list(leaves(s.model_dump()))
    assert len(rows) > 100
    missing = [r.key for r in rows if not r.meaning]
    assert not missing, missing


def test_changed_lists_only_what_differs_from_the_defaults(capsys):
    assert main(["show", "step_pitch", "--changed", "--set", "seed=7"]) == 0
    keys = [ln.split()[0] for ln in capsys.readouterr().out.splitlines()[1:]]
    assert "seed" in keys and "controller.mode" not in keys
    # the paper preset's fitted seal friction differs from the plant's default
    assert "actuator.pneumatics.cylinder.coulomb_friction_n" in keys


def test_the_resolved_scenario_holds_the_whole_pneumatics_block():
    s = api.load_scenario("step_pitch")
    pn = s.actuator.pneumatics
    assert set(type(pn).model_fields) == set(DEFAULT_PNEUMATIC_PARAMS)
    assert pn.supply_pressure_bar_gauge == 6.0
    assert pn.cylinder.coulomb_friction_n == [1.7, 1.7, 1.7]  # the paper preset's fit


def test_a_runs_scenario_yaml_holds_the_supply_pressure(tmp_path):
    out = tmp_path / "run"
    code = main(["run", "step_pitch", "--set", "duration_s=0.2", "--no-plots", "--quiet",
                 "--out", str(out)])  # fmt: skip
    assert code in (0, 1)  # 1: "not settled", 0.2 s is before the 1 s step has settled
    text = (out / "scenario.yaml").read_text()
    assert "supply_pressure_bar_gauge: 6.0" in text
    doc = yaml.safe_load(text)
    assert doc["actuator"]["pneumatics"]["supply_pressure_bar_gauge"] == 6.0


def test_the_typed_pneumatics_block_is_the_plants_tree():
    """Every key of the plant's parameter tree is a field with the plant's default, in its
    order: a plant parameter without its field (its unit and meaning) fails here."""
    from simpro_mj.plant.pneumatics.params import Pneumatics

    assert json.dumps(Pneumatics.defaults()) == json.dumps(DEFAULT_PNEUMATIC_PARAMS)
