"""Valve dither (``controller.inner.dither_v``): the signal, and what it does to a
loop whose seals stick.

The heavy cabin's seals (250 N breakaway, 150 N running) made to stick: the loops
it ships hunt in a stick-slip cycle (``docs/paper-notes.md`` 3.7); a 2 V, 25 Hz
square wave on the valves lets them settle.
"""

from __future__ import annotations

import numpy as np
import pytest

from controllers.dither import dither_signal


def test_the_dither_is_a_square_wave_of_the_period_asked():
    w = dither_signal(100, 1e-3, 2.0, 0.04)
    assert w.shape == (100, 3)
    np.testing.assert_array_equal(w[:20, 0], 2.0)
    np.testing.assert_array_equal(w[20:40, 1], -2.0)
    np.testing.assert_array_equal(w[40:60, 2], 2.0)
    assert w[:80].mean() == 0.0  # whole periods: no mean shift of the valves
    with pytest.raises(ValueError, match="even number"):
        dither_signal(10, 1e-3, 1.0, 0.005)


def test_a_bad_period_is_one_line_naming_the_key():
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.core.errors import UserInputError

    with pytest.raises(UserInputError, match=r"controller\.inner\.dither_period_ms.*even"):
        load_scenario("step_pitch", ["controller.inner.dither_period_ms=5"])


@pytest.mark.slow
def test_dither_settles_the_cabin_whose_seals_stick():
    """step_pitch (its 20 s) on the cabin with seals that stick and the preset's
    loops: without dither the pose hunts (a limit cycle), with +-2 V at 25 Hz it
    settles, overshoot within 10 %. At 10 s the dithered pitch still creeps by
    0.03 deg over the last 2 s, above the verdict's 0.02 deg: the run's own length
    is what the floors are judged on."""
    import simpro_mj as s

    base = {
        "plant.preset": "heavy_cabin",
        "actuator.pneumatics.cylinder.friction_model": "stick",
        "controller.inner.identify": "preset",
    }
    hunting = s.run("step_pitch", base)
    assert hunting.status == "limit_cycle"
    calm = s.run("step_pitch", {**base, "controller.inner.dither_v": 2.0})
    assert calm.status == "ok"
    assert calm.metrics["axes"]["pitch"]["overshoot_pct"] < 10.0
