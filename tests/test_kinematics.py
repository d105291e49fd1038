"""Kinematic model (controllers/, no MuJoCo): IK, FK, Jacobian, workspace, paper IK."""

import subprocess
import sys

import numpy as np
import pytest

from controllers.errors import ConvergenceError, WorkspaceError
from controllers.geometry import nominal_geometry
from controllers.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    jacobian,
    leg_lengths,
    line_circle_intersection,
    paper_inverse_kinematics,
    platform_position,
    reachable,
)
from controllers.workspace import axis_range, workspace_ranges

G = nominal_geometry()


def random_reachable(n, seed=0):
    rng = np.random.default_rng(seed)
    x = G.home + rng.uniform(-1, 1, (4 * n, 3)) * [0.5, 0.4, 0.22]
    x = x[reachable(x, margin=1e-3)]
    assert len(x) >= n
    return x[:n]


def test_home_pose_is_mid_stroke_and_matches_point_list():
    # |A1C1|, |A2B2| from the paper's point list (section 5.2.1)
    l1 = np.hypot(-760 + 180, 1055) * 1e-3
    l2 = np.hypot(896 - 180, 1265) * 1e-3
    np.testing.assert_allclose(leg_lengths(G.home), [l1, l2, l2], atol=1e-12)
    np.testing.assert_allclose(inverse_kinematics(G.home), [0.25, 0.25, 0.25], atol=1e-12)


def test_fk_of_ik_and_ik_of_fk_round_trip():
    x = random_reachable(300)
    q = inverse_kinematics(x)
    np.testing.assert_allclose(forward_kinematics(q), x, atol=1e-9, rtol=0)
    rng = np.random.default_rng(3)
    q2 = inverse_kinematics(x[:100]) + rng.uniform(-0.02, 0.02, (100, 3))
    q2 = np.clip(q2, 0.0, 0.5)
    np.testing.assert_allclose(
        inverse_kinematics(forward_kinematics(q2), check=False), q2, atol=1e-9
    )


def test_jacobian_matches_finite_differences():
    x = random_reachable(50, seed=5)
    eps = 1e-6
    fd = np.stack(
        [
            (
                inverse_kinematics(x + eps * e, check=False)
                - inverse_kinematics(x - eps * e, check=False)
            )
            / (2 * eps)
            for e in np.eye(3)
        ],
        axis=-1,
    )
    np.testing.assert_allclose(jacobian(x), fd, atol=1e-7)


def test_symmetry_roll_swaps_legs_2_and_3():
    x = np.array([0.1, 0.05, 1.3])
    q = inverse_kinematics(x)
    q_mirror = inverse_kinematics(x * [-1, 1, 1])
    np.testing.assert_allclose(q[[0, 2, 1]], q_mirror, atol=1e-12)


def test_curvilinear_heave_follows_guide_arc():
    # Fig. 4: rising by dh moves P back by r - sqrt(r^2 - ...) (eq. 14 corrected)
    r, (xc, zc) = G.guide_radius, G.guide_centre
    for dh in (-0.1, 0.05, 0.15):
        pos, _ = platform_position(G.home + [0, 0, dh])
        b1x_expected = xc - np.sqrt(r**2 - (G.home[2] + dh - zc) ** 2)
        assert pos[0] == pytest.approx(b1x_expected + 0.84, abs=1e-12)
    # eq. 14 with a sloped line agrees with a direct circle check
    x = line_circle_intersection(0.3, 1.0, xc, zc, r, -1)
    assert (x - xc) ** 2 + (0.3 * x + 1.0 - zc) ** 2 == pytest.approx(r**2, rel=1e-12)


def test_unreachable_pose_names_the_limit():
    with pytest.raises(WorkspaceError, match=r"leg \d stroke"):
        inverse_kinematics(G.home + [0, 0, 0.4])
    with pytest.raises(WorkspaceError, match="guide arc"):
        inverse_kinematics(G.home + [0, 0, 5.0])
    with pytest.raises(WorkspaceError, match="stroke"):
        forward_kinematics([0.1, 0.6, 0.2])


def test_fk_reports_non_convergence():
    with pytest.raises(ConvergenceError, match="did not converge"):
        forward_kinematics([0.25, 0.25, 0.3], max_iter=1)


def test_workspace_edges_sit_on_stroke_limits():
    rng = workspace_ranges(G)
    for axis, name in enumerate(("roll", "pitch", "heave")):
        for edge in rng[name]:
            x = G.home.copy()
            x[axis] = edge
            q = inverse_kinematics(x)
            # at the edge one leg is at an end stop (within the bisection tolerance)
            assert min(q.min(), 0.5 - q.max()) < 1e-6
    assert rng["roll"][0] == pytest.approx(-rng["roll"][1], abs=1e-9)  # y-symmetric
    lo, hi = axis_range(2, G, at=[0.0, np.radians(10), G.home[2]])
    assert lo < G.home[2] < hi


def test_paper_closed_form_agrees_where_the_geometries_agree():
    """Eqs. (30)-(33) describe another geometry; in heave the rear legs agree.

    dq2/dh from eq. (31) and from the point list differ by < 0.1 %; the
    pitch sensitivity of legs 2, 3 has the opposite sign (docs/paper-notes.md).
    """
    eps = 1e-6
    e_h = np.array([0, 0, eps])
    d_paper = (paper_inverse_kinematics(G.home + e_h) - paper_inverse_kinematics(G.home - e_h)) / (
        2 * eps
    )
    d_ours = jacobian(G.home)[:, 2]
    assert d_paper[1] == pytest.approx(d_ours[1], rel=1e-3)
    e_p = np.array([0, eps, 0])
    dp_paper = (paper_inverse_kinematics(G.home + e_p) - paper_inverse_kinematics(G.home - e_p))[1]
    assert np.sign(dp_paper) == -np.sign(jacobian(G.home)[1, 1])
    # "printed" reading: eq. (33) takes sqrt of a length, not a length
    q_pr = paper_inverse_kinematics(G.home + [0, 0, 0.1], reading="printed")
    q_co = paper_inverse_kinematics(G.home + [0, 0, 0.1], reading="corrected")
    assert np.all(np.abs(q_pr) < 0.1 * np.abs(q_co) * 1e3)


def test_controllers_import_without_mujoco():
    code = (
        "import sys, controllers, controllers.kinematics, controllers.workspace;"
        "import pkgutil, importlib;"
        "[importlib.import_module('controllers.' + m.name) for m in "
        "pkgutil.iter_modules(controllers.__path__)];"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('mujoco', 'simpro_mj')];"
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
