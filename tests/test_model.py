"""The MJCF model: geometry, mobility, loop closure, perturbations, stability."""

import mujoco
import numpy as np
import pytest

from controllers.geometry import PAPER_POINTS_MM, nominal_geometry
from controllers.kinematics import inverse_kinematics
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import apply_overrides
from simpro_mj.plant.model import (
    PlantIndex,
    add_slide_drives,
    assemble,
    load_model,
    load_spec,
    loop_closure_error,
    measured_pose,
    mobility,
)
from simpro_mj.plant.model_params import DEFAULT_MODEL_PARAMS
from simpro_mj.plant.pneumatics.params import PneumaticParams

G = nominal_geometry()


@pytest.fixture(scope="module")
def model():
    return load_model()


def test_compiles_with_1ms_step(model):
    from simpro_mj.core.rates import PHYSICS_DT_S

    # the one timestep every period is checked against (simpro_mj.core.rates)
    assert model.opt.timestep == PHYSICS_DT_S == pytest.approx(1e-3)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.nu == 3


def test_geometry_equals_paper_point_list(model):
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    for name, mm in PAPER_POINTS_MM.items():
        np.testing.assert_allclose(data.site(name).xpos, np.asarray(mm) * 1e-3, atol=1e-12)
    # loops are closed as written
    assert loop_closure_error(model, data).max() < 1e-9
    # slides at qpos0 are the IK's home joint values
    idx = PlantIndex.of(model)
    np.testing.assert_allclose(data.qpos[idx.slide_qpos], inverse_kinematics(G.home), atol=1e-9)
    # stroke limits are the joint ranges
    for i in (1, 2, 3):
        np.testing.assert_allclose(model.joint(f"leg{i}").range, [0.0, 0.5])


def test_mobility_is_three_free_and_zero_held(model):
    data = mujoco.MjData(model)
    rng = np.random.default_rng(2)
    poses = [G.home, G.home + [0.1, -0.05, 0.08], G.home + [-0.15, 0.1, -0.03]]
    for x in poses + [G.home + rng.uniform(-0.05, 0.05, 3)]:
        assemble(model, data, inverse_kinematics(x))
        assert mobility(model, data) == 3
        assert mobility(model, data, hold_slides=True) == 0


def test_mujoco_pose_equals_ik_pose_when_assembled(model):
    """Closing the loops at IK(x) puts the platform at x (geometry agreement)."""
    data = mujoco.MjData(model)
    idx = PlantIndex.of(model)
    rng = np.random.default_rng(7)
    for _ in range(20):
        x = G.home + rng.uniform(-1, 1, 3) * [0.15, 0.12, 0.1]
        assemble(model, data, inverse_kinematics(x), index=idx)
        np.testing.assert_allclose(measured_pose(data, idx.site_p), x, atol=1e-9)
        # y and yaw are held at zero by the guide
        assert abs(data.site_xpos[idx.site_p, 1]) < 1e-12
        assert abs(data.site_xmat[idx.site_p].reshape(3, 3)[1, 0]) < 1e-12


def test_loop_closure_at_rest_under_full_payload():
    spec = load_spec(
        apply_overrides(
            DEFAULT_MODEL_PARAMS, ["payload.mass_kg=400", "payload.com_mm=[100, 0, 500]"]
        )
    )
    add_slide_drives(spec)  # slides held at mid-stroke
    heavy = spec.compile()
    data = mujoco.MjData(heavy)
    idx = PlantIndex.of(heavy)
    assemble(heavy, data, [0.25, 0.25, 0.25], index=idx)
    for _ in range(1500):
        mujoco.mj_step(heavy, data)
    assert np.all(data.warning.number == 0)
    err = loop_closure_error(heavy, data, idx)
    assert err.max() < 1e-4  # 0.1 mm, the assembly bound
    assert np.abs(data.qvel).max() < 1e-4  # really at rest
    # the loops carry the load: the held slides push with about the weight
    g = 9.81 * (heavy.body_subtreemass[0])
    assert 0.3 * g < np.abs(data.efc_force[: data.ne]).sum()


def test_random_leg_forces_raise_no_warning(model):
    """2 s of random leg forces within the cylinders' range: no warning, finite, loops hold."""
    data = mujoco.MjData(model)
    idx = PlantIndex.of(model)
    rng = np.random.default_rng(11)
    # the cylinders' force range at 6 bar gauge (the pneumatic model bounds the
    # forces; the MJCF motors are not ctrllimited, so a higher supply is not capped)
    lo, hi = PneumaticParams.from_tree(None).force_range
    assert hi > 7000 and lo < -6500
    mujoco.mj_forward(model, data)
    worst = 0.0
    for k in range(2000):
        if k % 20 == 0:  # new random forces every 20 ms
            data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data)
        worst = max(worst, loop_closure_error(model, data, idx).max())
    assert np.all(data.warning.number == 0), data.warning.number
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    q = data.qpos[idx.slide_qpos]
    assert np.all(q > -0.01) and np.all(q < 0.51)  # end stops hold
    assert worst < 5e-4  # 0.5 mm, the loop-closure bound during motion


def test_loader_overrides_change_the_plant():
    base = load_model()
    heavy = load_model(apply_overrides(DEFAULT_MODEL_PARAMS, ["payload.mass_kg=300"]))
    assert heavy.body_subtreemass[0] - base.body_subtreemass[0] == pytest.approx(50.0)
    shifted = load_model(apply_overrides(DEFAULT_MODEL_PARAMS, ["anchor_offsets_mm.B2=[5, 0, -3]"]))
    np.testing.assert_allclose(
        shifted.site("B2").pos - base.site("B2").pos, [0.005, 0.0, -0.003], atol=1e-12
    )
    # a longer guide: the closed chain assembles, the platform sits elsewhere
    longer = load_model(apply_overrides(DEFAULT_MODEL_PARAMS, ["guide.radius_offset_mm=10"]))
    d = mujoco.MjData(longer)
    idx = PlantIndex.of(longer)
    assemble(longer, d, [0.25, 0.25, 0.25], index=idx)
    assert loop_closure_error(longer, d, idx).max() < 1e-9
    x = measured_pose(d, idx.site_p)
    assert abs(x[2] - G.home[2]) > 1e-4  # the as-built plant differs from the nominal


def test_loader_rejects_bad_parameters():
    with pytest.raises(UserInputError, match="payload.mass_kg"):
        load_model(apply_overrides(DEFAULT_MODEL_PARAMS, ["payload.mass_kg=-5"]))
    with pytest.raises(UserInputError, match="did you mean 'payload'"):
        apply_overrides(DEFAULT_MODEL_PARAMS, ["paylod.mass_kg=5"])
    with pytest.raises(UserInputError, match="anchor_offsets_mm.B2"):
        load_model(apply_overrides(DEFAULT_MODEL_PARAMS, ["anchor_offsets_mm.B2=[1, 2]"]))
