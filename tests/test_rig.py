"""A rig of your own: one geometry file from which the MJCF and the controllers follow."""

from __future__ import annotations

import copy
import json
import math

import mujoco
import numpy as np
import pytest

import simpro_mj as s
from controllers.geometry import PAPER_RIG_MM, geometry_from_rig, nominal_geometry
from controllers.kinematics import inverse_kinematics
from simpro_mj.analysis.validate_ik import IkParams, validate
from simpro_mj.commands.main import main
from simpro_mj.config.messages import from_sets
from simpro_mj.config.rig import RIGS_DIR, rig_value
from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import read_yaml
from simpro_mj.plant.model import assemble, load_spec, measured_pose
from simpro_mj.plant.model_params import DEFAULT_MODEL_PARAMS

WIDE = "wide_base"  # the shipped example: every base anchor moved by 100 mm


def _model(rig):
    params = copy.deepcopy(DEFAULT_MODEL_PARAMS)
    params["rig"] = rig
    return load_spec(params).compile()


def test_the_paper_rig_file_is_the_shipped_model_and_the_nominal_geometry():
    assert rig_value("paper") == rig_value(PAPER_RIG_MM)  # the shipped file is the record
    shipped, rebuilt = _model(None), _model(rig_value("paper"))
    # the MJCF writes the legs' home lengths to 9 digits: 1e-9 m is its own precision
    for name in ("body_pos", "body_quat", "site_pos", "jnt_pos", "jnt_range", "qpos0"):
        np.testing.assert_allclose(getattr(rebuilt, name), getattr(shipped, name), atol=1e-9)
    g, n = geometry_from_rig(None), nominal_geometry()
    for name in ("base_points", "platform_points", "guide_centre", "retracted_length"):
        assert np.array_equal(getattr(g, name), getattr(n, name))


def test_the_moved_rig_moves_every_base_anchor_by_100_mm():
    moved, paper = rig_value(WIDE), rig_value("paper")
    for k in ("A1", "A2", "A3"):
        d = math.dist(moved["base_anchors_mm"][k], paper["base_anchors_mm"][k])
        assert d == pytest.approx(100.0)
    assert {k: v for k, v in moved.items() if k != "base_anchors_mm"} == {
        k: v for k, v in paper.items() if k != "base_anchors_mm"
    }


def test_the_rebuilt_model_assembles_where_the_controllers_ik_says():
    """One source: off home, the MJCF's closed chain at the IK's leg lengths takes the
    pose the IK was given (both built from the moved rig alone)."""
    rig = rig_value(WIDE)
    model, g = _model(rig), geometry_from_rig(rig)
    data = mujoco.MjData(model)
    pose = g.home + np.array([math.radians(4.0), math.radians(-3.0), 0.06])
    assemble(model, data, inverse_kinematics(pose, g))
    np.testing.assert_allclose(measured_pose(data, model.site("P").id), pose, atol=1e-9)
    # the paper's geometry would give other slide positions there (1.1 mm apart)
    assert np.abs(inverse_kinematics(pose, g) - inverse_kinematics(pose)).max() > 5e-4


def test_validate_ik_passes_on_the_moved_rig_within_the_paper_rigs_bounds():
    kin = validate(
        from_sets(IkParams, [f"model.rig={WIDE}", "drive=kinematic", "trajectory.duration_s=5"])
    )
    assert kin.max_position_error_m < 1e-8 and kin.max_angle_error_rad < 1e-8
    dyn = validate(from_sets(IkParams, [f"model.rig={WIDE}", "trajectory.duration_s=8"]))
    # the bounds of the paper rig's own test (tests/test_validate_ik.py)
    assert dyn.max_position_error_m < 1e-4
    assert dyn.max_angle_error_rad < np.radians(0.01)
    assert dyn.max_loop_closure_error_m < 5e-4
    assert dyn.paper_ik_max_leg_error_m is None  # eqs. 30-33 are the paper rig's


def test_step_pitch_on_the_moved_rig_settles_ok():
    res = s.run("step_pitch", {"duration_s": 6.0, "plant.rig": WIDE})
    assert res.metrics["status"] == "ok"
    assert res.scenario.plant.rig.base_anchors_mm.A2 == [180.0, -600.0, 0.0]
    # the 3 deg step, held: the pitch ends within 0.05 deg of it
    pitch = np.degrees(res.columns["pitch_rad"][-500:])
    assert np.abs(pitch - 3.0).max() < 0.05


@pytest.mark.parametrize(
    ("sets", "field"),
    [
        (["plant.rig=no_such_rig"], "plant.rig"),
        (["plant.rig={stroke_mm: 200}"], "plant.rig.home_stroke_mm"),
        (["plant.rig={base_anchors_mm: {A1: [0, 5, 0]}}"], "plant.rig.base_anchors_mm.A1"),
        (
            ["plant.rig={platform_anchors_mm: {B1: [-840, 0, 1300]}}"],
            "plant.rig.platform_anchors_mm.B1",
        ),
        (["plant.rig={guide_centre_from_b1_mm: [10, 0]}"], "plant.rig.guide_centre_from_b1_mm"),
        (["plant.rig={stroke: 500}"], "plant.rig.stroke"),
    ],
)
def test_a_bad_rig_is_one_line_naming_the_field(sets, field):
    with pytest.raises(UserInputError) as err:
        load_scenario("step_pitch", sets)
    text = str(err.value)
    assert f"at {field}" in text and "allowed" in text and "\n" not in text


def test_a_rig_file_beside_the_scenario_is_found_and_named_in_its_errors(tmp_path, capsys):
    doc = read_yaml(RIGS_DIR / f"{WIDE}.yaml")
    doc["stroke_mm"] = -5
    (tmp_path / "my_rig.yaml").write_text(json.dumps(doc))  # JSON is YAML
    (tmp_path / "s.yaml").write_text("duration_s: 2\nplant: {rig: my_rig.yaml}\n")
    assert main(["show", str(tmp_path / "s.yaml")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1
    assert "plant.rig.stroke_mm" in err and str(tmp_path / "my_rig.yaml") in err
