"""Vestibular models reproduce their published step responses and thresholds.

Reference: the closed-form step responses of the published transfer
functions (partial fractions worked out here, not from the implementation),
against the discretised models.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.filters import DiscreteFilter, FilterError
from controllers.frames import GRAVITY
from controllers.vestibular import (
    CANAL_PER_AXIS_ALTERNATIVE,
    CANAL_THRESHOLDS,
    OTOLITH_THRESHOLDS,
    CanalModel,
    OtolithModel,
    VestibularModel,
)

DT = 0.001


def _step_motion(n, f_step=None, w_step=None, at=0):
    f = np.zeros((n, 3))
    f[:, 2] = GRAVITY
    w = np.zeros((n, 3))
    if f_step is not None:
        f[at:] += f_step
    if w_step is not None:
        w[at:] += w_step
    return f, w


def test_published_parameters():
    o, c = OtolithModel(), CanalModel()
    assert (o.gain, o.tau_a, o.tau_l, o.tau_s) == (0.4, 13.2, 5.33, 0.66)  # Young & Meiry 1968
    assert (c.tau_a, c.tau_l, c.tau_s, c.tau_n) == (80.0, 5.73, 0.005, 0.06)  # Zacharias 1978
    assert OTOLITH_THRESHOLDS == (0.17, 0.17, 0.28)
    assert np.allclose(np.degrees(CANAL_THRESHOLDS), (3.0, 3.6, 2.6))


def test_otolith_step_response_matches_closed_form():
    # y(t)/(K a) = 1 + cL exp(-t/tl) + cS exp(-t/ts),
    # cL = -(tl - ta)/(tl - ts), cS = -(ta - ts)/(tl - ts)   (residues of G(s)/s)
    ta, tl, ts, k = 13.2, 5.33, 0.66, 0.4
    n = 40_000
    a = 1.0
    f, w = _step_motion(n, f_step=[a, 0, 0], at=1)
    p = VestibularModel().perceive(f, w, DT)
    t = (np.arange(n) - 1) * DT
    cl = -(tl - ta) / (tl - ts)
    cs = -(ta - ts) / (tl - ts)
    ref = k * a * (1 + cl * np.exp(-t / tl) + cs * np.exp(-t / ts))
    ref[t < 0] = 0.0
    # Tustin's error on a step: half a sample of shift, O(dt / ts) ~ 1.5e-3 of the peak
    assert np.max(np.abs(p.f[:, 0] - ref)) < 2e-3
    # the published shape: rises to a peak of ~0.82 a near 1.8 s, adapts to K a = 0.4 a
    i = int(np.argmax(p.f[:, 0]))
    assert 0.80 < p.f[i, 0] < 0.84 and 1.5 < t[i] < 2.2
    assert p.f[-1, 0] == pytest.approx(0.4 * a + cl * 0.4 * a * math.exp(-t[-1] / tl), rel=1e-3)
    # gravity on z at rest is adapted away: no z sensation, no y sensation
    assert np.max(np.abs(p.f[:, 1:])) < 1e-12


def test_canal_step_response_matches_closed_form():
    # without the 5 ms and 60 ms terms: y/w0 = (ta exp(-t/tl) - tl exp(-t/ta)) / (ta - tl)
    ta, tl = 80.0, 5.73
    n = 60_000
    w0 = math.radians(10.0)
    canal = CanalModel(tau_s=1e-9, tau_n=0.0)
    f, w = _step_motion(n, w_step=[w0, 0, 0], at=1)
    p = VestibularModel(canal=canal).perceive(f, w, DT)
    t = (np.arange(n) - 1) * DT
    ref = w0 * (ta * np.exp(-t / tl) - tl * np.exp(-t / ta)) / (ta - tl)
    ref[t < 0] = 0.0
    assert np.max(np.abs(p.w[2:, 0] - ref[2:])) < 1e-3 * w0
    # post-rotatory decay: 1/e of the step after about tau_l (5.73 s), a little
    # sooner (5.1 s) because the 80 s adaptation subtracts its slow tail
    k = 2 + int(np.argmax(p.w[2:, 0] < w0 / math.e))
    assert t[k] == pytest.approx(5.1, abs=0.1)
    # sensation reverses after ~ tl ta/(ta - tl) ln(ta/tl) = 16.3 s
    z = int(np.argmax(p.w[:, 0] < 0))
    assert t[z] == pytest.approx(tl * ta / (ta - tl) * math.log(ta / tl), abs=0.05)


def test_canal_with_published_lead_and_lag_is_the_same_after_the_transient():
    n = 20_000
    w0 = math.radians(10.0)
    f, w = _step_motion(n, w_step=[0, w0, 0], at=1)
    full = VestibularModel().perceive(f, w, DT)
    bare = VestibularModel(canal=CanalModel(tau_s=1e-9, tau_n=0.0)).perceive(f, w, DT)
    # tau_n / tau_s = 12: the neural lead's spike at the onset, gone within ~5 tau_s
    assert full.w[2, 1] > 5 * w0
    late = slice(200, None)
    assert np.max(np.abs(full.w[late, 1] - bare.w[late, 1])) < 0.011 * w0


def test_per_axis_canal_alternative():
    """The per-axis set (tau_l roll 6.1, pitch 5.3, yaw 10.2 s; tau_s 0.1 s, tau_a 30 s,
    no lead): each axis follows its own closed-form step response. With
    a, b, c = 1/tau_a, 1/tau_l, 1/tau_s the step response of
    tau_a tau_l s^2 / ((tau_a s + 1)(tau_l s + 1)(tau_s s + 1)) is
    c (-a e^{-at} / ((b-a)(c-a)) - b e^{-bt} / ((a-b)(c-b)) - c e^{-ct} / ((a-c)(b-c)))."""
    model = VestibularModel(canal=CanalModel(**CANAL_PER_AXIS_ALTERNATIVE))
    n = 30_000
    w0 = math.radians(10.0)
    f, w = _step_motion(n, w_step=[w0, w0, w0], at=1)
    p = model.perceive(f, w, DT)
    t = (np.arange(n) - 1) * DT
    a, c = 1 / 30.0, 1 / 0.1
    for axis, tl in enumerate((6.1, 5.3, 10.2)):
        b = 1 / tl
        ref = c * (
            -a * np.exp(-a * t) / ((b - a) * (c - a))
            - b * np.exp(-b * t) / ((a - b) * (c - b))
            - c * np.exp(-c * t) / ((a - c) * (b - c))
        )
        err = np.abs(p.w[2:, axis] - w0 * ref[2:])
        # Tustin's half-sample offset on the 0.1 s rise: dt / (2 tau_s) = 0.5 % at most
        assert err.max() < 0.006 * w0
        assert err[t[2:] > 1.0].max() < 1e-4 * w0  # then the decay itself, exactly
    # the yaw sensation outlasts the roll and pitch ones
    at = int(round(8.0 / DT))
    assert p.w[at, 2] > p.w[at, 0] > p.w[at, 1] > 0
    with pytest.raises(ValueError, match="tau_l"):
        CanalModel(tau_l=(6.1, 5.3))
    with pytest.raises(ValueError, match="tau_l"):
        CanalModel(tau_l=(6.1, -5.3, 10.2))


def test_thresholds_detect_steps_at_and_below_them():
    n = 8000
    model = VestibularModel()
    # an otolith step peaks at 0.82 of itself: 1.3 x threshold is felt, 1.1 x is not
    for axis, thr in enumerate(OTOLITH_THRESHOLDS):
        step = np.zeros(3)
        step[axis] = 1.3 * thr
        f, w = _step_motion(n, f_step=step, at=10)
        above_f, _ = model.perceive(f, w, DT).above()
        assert above_f[:, axis].any()
        step[axis] = 1.1 * thr
        f, w = _step_motion(n, f_step=step, at=10)
        assert not model.perceive(f, w, DT).above()[0].any()
    # a tilt at the 3 deg/s of tilt coordination stays under the roll threshold
    # once the onset transient (the neural lead) has passed
    for axis, thr in enumerate(CANAL_THRESHOLDS):
        wstep = np.zeros(3)
        wstep[axis] = 0.95 * thr
        f, w = _step_motion(n, w_step=wstep, at=10)
        above = model.perceive(f, w, DT).above()[1][:, axis]
        assert not above[100:].any() and above[10:40].any()  # lead spike only


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError, match="tau_l"):
        OtolithModel(tau_l=-1.0)
    with pytest.raises(ValueError, match="tau_n"):
        CanalModel(tau_n=float("nan"))
    with pytest.raises(ValueError, match="thresholds"):
        CanalModel(thresholds=(1.0, 2.0))
    with pytest.raises(FilterError):
        DiscreteFilter([1.0, 0.0, 0.0], [1.0, 1.0], 0.01)  # improper
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        VestibularModel().perceive(np.zeros((4, 2)), np.zeros((4, 2)), DT)


def test_filter_step_and_run_agree():
    flt = DiscreteFilter(*OtolithModel().tf(), 0.01)
    u = np.sin(np.arange(500) * 0.05) + 0.3
    flt.reset(0.3)
    ys = [flt.step(x) for x in u]
    flt.reset(0.3)
    yr = flt.run(u)
    assert np.max(np.abs(np.array(ys) - yr)) < 1e-13
    assert flt.dc_gain == pytest.approx(0.4)
