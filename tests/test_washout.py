"""Classical washout: frames, signs, known answers, workspace."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.frames import (
    GRAVITY,
    base_to_vehicle,
    pose_base_to_iso,
    pose_iso_to_base,
    static_specific_force,
)
from controllers.geometry import H0, nominal_geometry
from controllers.kinematics import reachable, rotation
from controllers.washout import ClassicalWashout, WashoutParamError, WashoutParams
from controllers.workspace import inscribed_box, soft_limit

DT = WashoutParams().period


def _constant(n, f=(0.0, 0.0, 0.0), w=(0.0, 0.0, 0.0), at=0):
    """Rest (1 g up) with a step of ``f`` (added) and ``w`` from sample ``at``."""
    fa = np.zeros((n, 3))
    fa[:, 2] = GRAVITY
    wa = np.zeros((n, 3))
    fa[at:] += np.asarray(f)
    wa[at:] += np.asarray(w)
    return fa, wa


# ------------------------------------------------------------------ frames


def test_base_frame_x_points_back_and_pitch_lowers_the_rear():
    g = nominal_geometry()
    # paper section 2.1: legs 2 and 3 (x = +896 mm) are at the back, B1 (x = -840) in front
    assert g.platform_points[1, 0] > 0 > g.platform_points[0, 0]
    # eq. (8): a positive base pitch lowers the back (+x): the nose goes up
    back = rotation(0.0, math.radians(5.0)) @ np.array([1.0, 0.0, 0.0])
    assert back[2] < 0
    # so a positive ISO pitch (nose down) is a negative base pitch
    assert pose_iso_to_base(0.0, math.radians(5.0), 0.0)[1] == pytest.approx(-math.radians(5.0))
    # base y points right: a positive base roll (about x back) lowers the left side
    left_in_base = base_to_vehicle([0.0, 1.0, 0.0])  # vehicle +y (left) in base axes
    assert (rotation(math.radians(5.0), 0.0) @ left_in_base)[2] < 0


def test_pose_conversions_round_trip():
    x = np.array([[0.1, -0.05, 0.02], [-0.2, 0.03, -0.04]])
    base = pose_iso_to_base(x[:, 0], x[:, 1], x[:, 2])
    assert np.allclose(base[:, 2], H0 + x[:, 2])
    assert np.allclose(pose_base_to_iso(base), x)


def test_static_specific_force_is_gravity_seen_from_the_tilted_head():
    f = static_specific_force(0.0, 0.0)
    assert np.allclose(f, [0.0, 0.0, GRAVITY])
    th = math.radians(7.0)
    # nose down by th (base pitch -th): the otoliths feel f_x = -g sin th, like braking
    f = static_specific_force(0.0, -th)
    assert f[0] == pytest.approx(-GRAVITY * math.sin(th))
    assert f[2] == pytest.approx(GRAVITY * math.cos(th))
    # right side down by th (ISO roll +th, base roll -th): f_y = +g sin th, like a left turn
    f = static_specific_force(-th, 0.0)
    assert f[1] == pytest.approx(GRAVITY * math.sin(th))


# ------------------------------------------------------------------ signs


def test_braking_presses_the_driver_forward_into_the_belt():
    n = 1500
    f, w = _constant(n, f=(-4.0, 0.0, 0.0), at=10)
    res = ClassicalWashout().run(f, w)
    f_head = static_specific_force(res.pose[:, 0], res.pose[:, 1])
    assert res.pose[-1, 1] < 0  # base pitch negative: nose down
    assert np.all(f_head[11:, 0] < 0)  # the belt pushes back: pressed forwards
    assert np.all(np.abs(f_head[:, 1]) < 1e-12)


def test_left_turn_presses_the_driver_to_the_right():
    n = 1500
    f, w = _constant(n, f=(0.0, 3.0, 0.0), at=10)
    res = ClassicalWashout().run(f, w)
    f_head = static_specific_force(res.pose[:, 0], res.pose[:, 1])
    assert res.pose[-1, 0] < 0  # base roll negative: ISO roll positive, right side down
    assert np.all(f_head[11:, 1] > 0)  # the seat pushes left: pressed to the right
    assert np.all(np.abs(res.pose[:, 1]) < 1e-12)


# ------------------------------------------------------------------ known answers


@pytest.mark.parametrize("k, a", [(0.5, 2.0), (0.8, 1.5), (0.3, 3.0)])
def test_sustained_acceleration_settles_at_asin_k_a_over_g_within_the_rate_limit(k, a):
    p = WashoutParams(gain_x=k)
    n = int(12.0 / DT)
    f, w = _constant(n, f=(-a, 0.0, 0.0), at=1)
    res = ClassicalWashout(p).run(f, w)
    target = math.asin(k * a / GRAVITY)
    assert target < 0.8 * math.radians(9.1)  # inside the soft limit's knee: no softening
    assert -res.pose[-1, 1] == pytest.approx(target, abs=1e-9)
    assert np.allclose(static_specific_force(*res.pose[-1, :2])[0], -k * a, atol=1e-9)
    rate = np.abs(np.diff(res.pose[:, 1])) / DT
    assert rate.max() <= p.tilt_rate_limit * (1 + 1e-9)
    # 99 % reached no sooner than the rate limit allows, and no later than the
    # critically damped low-pass's 1 % settling ((1 + x) e^-x = 0.01: x = 6.6) after it
    reach = res.t[int(np.argmax(-res.pose[:, 1] >= 0.99 * target))]
    t_min = 0.99 * target / p.tilt_rate_limit
    assert t_min <= reach <= t_min + 6.7 / p.tilt_omega
    assert res.rate_limited.any() and not res.softened.any()


def test_heave_returns_to_neutral_after_a_step_in_vertical_specific_force():
    n = int(30.0 / DT)
    f, w = _constant(n, f=(0.0, 0.0, 1.0), at=1)
    res = ClassicalWashout().run(f, w)
    z = res.pose[:, 2] - H0
    assert z.max() > 0.02  # up first: f_z above 1 g is an upward acceleration
    assert z[np.argmax(z) :].min() > -0.5 * z.max()  # then back, without a large overshoot
    assert abs(z[-1]) < 1e-4  # neutral within 0.1 mm after 30 s
    assert np.all(np.abs(res.pose[:, :2]) < 1e-12)


def test_rotation_channel_plays_the_onset_and_washes_out():
    n = int(30.0 / DT)
    wr = math.radians(5.0)
    f, w = _constant(n, w=(wr, 0.0, 0.0), at=1)
    w[int(1.0 / DT) :, 0] = 0.0  # a 1 s roll at 5 deg/s: the vehicle rolls 5 deg right
    res = ClassicalWashout().run(f, w)
    roll_iso = -res.pose[:, 0]
    assert roll_iso.max() == pytest.approx(math.radians(5.0), rel=0.25)
    assert abs(roll_iso[-1]) < math.radians(0.01)


def test_step_and_run_agree_and_reset_repeats():
    n = 400
    rng = np.random.default_rng(1)
    f, w = _constant(n)
    f += rng.normal(0, 1.0, (n, 3))
    w += rng.normal(0, 0.05, (n, 3))
    wo = ClassicalWashout()
    a = wo.run(f, w).pose
    wo.reset()
    b = np.array([wo.step(f[i], w[i]) for i in range(n)])
    assert np.array_equal(a, b)


# ------------------------------------------------------------------ workspace


def test_inscribed_box_is_reachable_everywhere_and_set_points_stay_inside():
    box = ClassicalWashout().box
    assert box == inscribed_box(heave_fraction=0.25, margin=0.01)
    g = nominal_geometry()
    grid = np.stack(
        np.meshgrid(*[np.linspace(*box[k], 9) for k in ("roll", "pitch", "heave")], indexing="ij"),
        axis=-1,
    ).reshape(-1, 3)
    assert reachable(grid, g, 0.01).all()
    # a violent input (2 g lateral, 2 g longitudinal, +-1 g heave, fast rolls)
    n = int(20.0 / DT)
    t = np.arange(n) * DT
    f = np.stack(
        [
            2 * GRAVITY * np.sign(np.sin(t)),
            2 * GRAVITY * np.sign(np.cos(0.7 * t)),
            GRAVITY * (1 + np.sin(3 * t)),
        ],
        axis=-1,
    )
    w = np.stack([np.sin(2 * t), np.cos(2 * t), 0 * t], axis=-1)
    res = ClassicalWashout(gain_x=1.0, gain_y=1.0, gain_z=1.0, tilt_limit=math.radians(40)).run(
        f, w
    )
    for k, name in enumerate(("roll", "pitch", "heave")):
        lo, hi = box[name]
        assert lo <= res.pose[:, k].min() and res.pose[:, k].max() <= hi  # tanh(big) == 1.0
    assert reachable(res.pose, g, 0.01).all()
    assert res.softened.any()


def test_soft_limit_is_smooth_monotonic_and_identity_below_the_knee():
    x = np.linspace(-3.0, 3.0, 6001)
    y = soft_limit(x, 0.0, -1.0, 2.0, knee=0.8)
    assert np.all(np.diff(y) > 0)
    assert y.min() > -1.0 and y.max() < 2.0
    inside = (x >= -0.8) & (x <= 1.6)
    assert np.array_equal(y[inside], x[inside])
    slope = np.diff(y) / np.diff(x)
    assert np.max(np.abs(np.diff(slope))) < 5e-3  # no kink anywhere (a clip jumps by 1)


# ------------------------------------------------------------------ parameters


def test_parameters_are_checked_and_unknown_names_refused():
    with pytest.raises(WashoutParamError, match="tilt_rate_limit"):
        WashoutParams(tilt_rate_limit=-1.0)
    with pytest.raises(WashoutParamError, match="rot_order"):
        WashoutParams(rot_order=3)
    with pytest.raises(WashoutParamError, match="allowed: .*gain_x"):
        ClassicalWashout(gain_q=1.0)
    with pytest.raises(ValueError, match="not finite"):
        ClassicalWashout().step([math.nan, 0, 9.8], [0, 0, 0])
    assert isinstance(WashoutParamError("x"), ValueError)
