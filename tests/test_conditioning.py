"""Input conditioning: a biased vertical force comes back to g, vibration is cut at the stated
corner, a platform-band cue passes, and the sample-by-sample and whole-record runs agree."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.conditioning import InputConditioner
from controllers.frames import GRAVITY

DT = 0.01


def _amplitude(y, t, hz):
    """Amplitude of the ``hz`` component of ``y`` (a whole number of periods)."""
    c = np.exp(-2j * math.pi * hz * t)
    return 2.0 * abs(np.mean(y * c))


def test_a_biased_noisy_feed_is_brought_to_g_without_its_vibration():
    """fz = 9.6 (a -0.21 m/s^2 bias) + 2 m/s^2 at 30 Hz + a 0.5 m/s^2 cue at 1 Hz on fx.
    After 5 tau the bias is left at exp(-5) (< 1.5e-3 m/s^2); the second-order 10 Hz
    low-pass leaves (10/30)^2 of the vibration (about 0.11, Tustin: less); the 1 Hz cue
    passes within 1 %."""
    cond = InputConditioner(DT, bias_tau_s=10.0, vibration_hz=10.0)
    t = np.arange(0, 60.0, DT)
    fz = 9.6 + 2.0 * np.sin(2 * math.pi * 30.0 * t)
    fx = 0.5 * np.sin(2 * math.pi * 1.0 * t)
    f = np.column_stack([fx, np.zeros_like(t), fz])
    out, _ = cond.run(f, np.zeros((t.size, 3)))
    tail = t >= 50.0
    bias = (9.6 - GRAVITY) * math.exp(-5.0)
    assert abs(out[tail, 2].mean() - GRAVITY) < abs(bias) + 1e-3
    assert _amplitude(out[tail, 2], t[tail], 30.0) < 2.0 * 0.12
    assert _amplitude(out[tail, 0], t[tail], 1.0) == pytest.approx(0.5, rel=0.01)
    # without conditioning the bias stays whole
    raw = InputConditioner(DT, bias_tau_s=0.0, vibration_hz=0.0).run(f, np.zeros((t.size, 3)))[0]
    assert raw[tail, 2].mean() == pytest.approx(9.6, abs=1e-9)


def test_step_and_run_agree_and_rest_stays_rest():
    rng = np.random.default_rng(3)
    f = np.column_stack(
        [rng.normal(0, 1, 500), rng.normal(0, 1, 500), GRAVITY + rng.normal(0, 1, 500)]
    )
    w = rng.normal(0, 0.1, (500, 3))
    a, b = InputConditioner(DT), InputConditioner(DT)
    fr, wr = a.run(f, w)
    steps = [b.step(fi, wi) for fi, wi in zip(f, w, strict=True)]
    assert np.allclose(fr, [s[0] for s in steps], atol=1e-12)
    assert np.allclose(wr, [s[1] for s in steps], atol=1e-12)
    c = InputConditioner(DT)
    for _ in range(100):
        fo, wo = c.step((0.0, 0.0, GRAVITY), (0.0, 0.0, 0.0))
    assert fo == (0.0, 0.0, GRAVITY) and wo == (0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    "kw", [{"bias_tau_s": -1.0}, {"vibration_hz": 50.0}, {"vibration_hz": math.nan}]
)
def test_bad_settings_are_refused(kw):
    with pytest.raises(ValueError, match="allowed"):
        InputConditioner(DT, **kw)
