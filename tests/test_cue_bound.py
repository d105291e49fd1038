"""The cueing bound and the strength of a cue: gain beside correlation, and the best a
roll-pitch-heave platform can give with the whole drive known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.cue_bound import cue_bound
from controllers.frames import GRAVITY
from controllers.vestibular import VestibularModel
from simpro_mj.analysis.cue_metrics import cue_floors
from simpro_mj.analysis.cue_signals import bound_share, strength


def test_strength_tells_a_weak_cue_of_the_right_shape():
    """A cue of the car's shape at a tenth of its size: correlation 1, gain 0.1 (least
    squares and RMS ratio alike); late by 0.3 s it keeps its gain at the mean lag."""
    dt = 0.01
    t = np.arange(0.0, 20.0, dt)
    pv = np.sin(2 * np.pi * 0.2 * t) * np.exp(-(((t - 10.0) / 4.0) ** 2))
    out = strength(pv, 0.1 * pv, 0.0, dt)
    assert out["gain"] == pytest.approx(0.1, rel=1e-9)
    assert out["gain_rms"] == pytest.approx(0.1, rel=1e-9)
    late = np.r_[np.zeros(30), 0.1 * pv[:-30]]
    assert strength(pv, late, 0.3, dt)["gain"] == pytest.approx(0.1, rel=1e-6)
    # read at no shift it would look weaker: 0.1 cos(w 0.3 s) for a sine of 0.2 Hz
    weaker = 0.1 * math.cos(2 * math.pi * 0.2 * 0.3)
    assert strength(pv, late, 0.0, dt)["gain"] == pytest.approx(weaker, rel=0.01)


def test_gain_share_floor_names_a_cue_weaker_than_the_platform_can_give():
    ch = {"correlation": 0.99, "mean_lag_s": 0.1, "vehicle_peak": -4.0, "threshold": 0.17}
    weak = dict(ch, gain=0.065, rms_error=1.2, vehicle_rms=1.3)
    weak.update(bound_share(weak, {"gain": 0.30, "rms_error": 0.9}))
    assert weak["gain_share"] == pytest.approx(0.065 / 0.30)
    assert weak["error_share"] == pytest.approx(0.1 / 0.4)
    # a channel where even the bound removes little of the error has no error share
    assert bound_share(weak, {"gain": 0.30, "rms_error": 1.25})["error_share"] is None
    floors = cue_floors({"channels": {"longitudinal_f": weak}})
    assert floors.missed == ["longitudinal_f gain 0.07 is 0.22 of the bound's < 0.8"]
    strong = dict(weak, gain=0.27)
    strong.update(bound_share(strong, {"gain": 0.30, "rms_error": 0.9}))
    assert cue_floors({"channels": {"longitudinal_f": strong}}).met


def _braking(decel: float, dt: float = 0.01, n: int = 1200):
    """A car braking at ``decel`` from 2 s to 8 s (a 1 s ramp), at rest otherwise."""
    t = dt * np.arange(n)
    ramp = np.clip(t - 2.0, 0.0, 1.0) - np.clip(t - 8.0, 0.0, 1.0)
    f = np.zeros((n, 3))
    f[:, 0] = -decel * ramp
    f[:, 2] = GRAVITY
    return f, np.zeros((n, 3))


def test_bound_reproduces_a_braking_the_box_can_tilt_for():
    """A 0.5 m/s^2 braking needs asin(0.5 / g) = 2.9 deg of pitch, inside the box (the
    MPC's pitch limit): the bound gives the driver most of it, in shape; a 5 m/s^2
    braking would need 31 deg: the box caps the gain at about g sin(limit) / 5."""
    dt = 0.01
    model = VestibularModel()
    gains = []
    for decel in (0.5, 5.0):
        f, w = _braking(decel, dt)
        b = cue_bound(f, w, dt)
        assert all(s == "solved" for s in b.status)
        # the plan keeps to the box (tolerance: the solver's 1e-5)
        assert np.all(np.abs(b.pose_iso) <= np.asarray(b.limits) * (1 + 1e-3))
        pv = model.perceive(f, w, dt).f[:, 0]
        ps = model.perceive(b.f, b.w, dt).f[:, 0]
        assert np.corrcoef(pv, ps)[0, 1] > 0.9
        gains.append(strength(pv, ps, 0.0, dt)["gain"])
    limit = cue_bound(*_braking(5.0, dt), dt).limits[1]
    assert gains[0] > 0.7
    assert gains[1] < 1.3 * GRAVITY * math.sin(limit) / 5.0
    assert gains[1] < gains[0]
