"""The MPC cueing law: a QP on the perceived error, causal, inside the platform's reach."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.frames import GRAVITY
from controllers.mpc_cueing import ModelPredictiveCueing, MpcParamError, MpcParams

DT = 0.01


def _braking(n: int, start: float = 1.0, decel: float = 4.0):
    """The vehicle at rest, then braking at ``decel`` from ``start`` (a 0.3 s ramp)."""
    t = DT * np.arange(n)
    f = np.zeros((n, 3))
    f[:, 2] = GRAVITY
    f[:, 0] = -decel * np.clip((t - start) / 0.3, 0.0, 1.0)
    return t, f, np.zeros((n, 3))


def _head_fx(pose: np.ndarray, h: float = 0.75) -> np.ndarray:
    """The head's specific force along x of a pitch set-point (ISO pitch = -B pitch)."""
    th = -pose[:, 1]
    return h * np.gradient(np.gradient(th, DT), DT) - GRAVITY * np.sin(th)


def test_braking_tilts_nose_down_within_the_reach():
    law = ModelPredictiveCueing()
    p = law.params
    t, f, w = _braking(600)
    res = law.run(f, w, DT)
    th = -res.pose[:, 1]
    # a sustained 4 m/s^2 braking asks gain_x * 4 = 1.2 m/s^2: a nose-down tilt near
    # asin(1.2 / g) = 7.0 deg, and the head feels the braking (f_x < 0)
    assert math.degrees(th[-1]) == pytest.approx(math.degrees(math.asin(1.2 / GRAVITY)), abs=2.0)
    assert _head_fx(res.pose)[-100:].mean() < -0.8
    lim = p.box_fraction * min(-law.box["pitch"][0], law.box["pitch"][1])
    assert np.abs(th).max() <= lim + 1e-3
    assert np.abs(np.gradient(th, DT)).max() <= p.tilt_rate_max * 1.02
    # roll and heave stay home, nothing asked of them
    assert np.abs(res.pose[:, 0]).max() < 1e-4
    assert all(s == "solved" for s in res.status)
    st = res.solve_time_stats()
    assert st["solves"] == 100 and st["p50_ms"] <= st["p99_ms"] <= st["max_ms"]


def test_no_look_ahead_unless_asked():
    """Each solve uses the input up to its time: a future change leaves the past alone;
    ``preview`` makes the law react that much earlier."""
    t, f, w = _braking(400, start=2.0)
    base = ModelPredictiveCueing().run(f, w, DT).pose
    f2 = f.copy()
    f2[300:, 0] = 0.0  # the braking ends at 3 s instead
    other = ModelPredictiveCueing().run(f2, w, DT).pose
    assert np.array_equal(base[:300], other[:300])
    assert np.abs(base[300:] - other[300:]).max() > 1e-3
    ahead = ModelPredictiveCueing(preview=0.3).run(f, w, DT).pose
    assert np.abs(ahead[:200, 1]).max() > 1e-4  # moves before the braking starts
    assert np.abs(base[:200, 1]).max() < 1e-12


def test_head_offset_in_the_model_reduces_the_wrong_way_jolt():
    """With the head 0.75 m above the pivot in the model, the plan keeps the head's
    wrong-way specific force at the onset smaller than a plan that ignores it."""
    t, f, w = _braking(400)
    jolt = {}
    for h in (0.0, 0.75):
        pose = ModelPredictiveCueing(head_height=h).run(f, w, DT).pose
        jolt[h] = _head_fx(pose)[90:200].max()  # the real head is 0.75 m up
    assert jolt[0.75] < jolt[0.0]


def test_parameters_checked():
    with pytest.raises(MpcParamError, match="horizon"):
        MpcParams(horizon=1)
    with pytest.raises(MpcParamError, match="unknown mpc parameter 'gain'"):
        MpcParams().replace(gain=1.0)
    with pytest.raises(ValueError, match="divide the period"):
        ModelPredictiveCueing().run(np.zeros((5, 3)), np.zeros((5, 3)), 0.007)


def test_lead_evaluates_the_plan_later_and_stays_causal():
    """``lead`` moves the set-point ahead along the plan (the braking tilt starts about
    ``lead`` earlier) and, without preview, still leaves the past untouched by a change
    of the future input."""
    t, f, w = _braking(400, start=2.0)
    base = ModelPredictiveCueing().run(f, w, DT).pose
    led = ModelPredictiveCueing(lead=0.1).run(f, w, DT).pose
    th0, th1 = -base[:, 1], -led[:, 1]
    level = 0.5 * th0[-1]
    cross0 = int(np.argmax(th0 > level))
    cross1 = int(np.argmax(th1 > level))
    assert (cross0 - cross1) * DT == pytest.approx(0.1, abs=0.03)
    f2 = f.copy()
    f2[300:, 0] = 0.0
    other = ModelPredictiveCueing(lead=0.1).run(f2, w, DT).pose
    assert np.array_equal(led[:300], other[:300])


def test_stream_is_the_run_sample_by_sample():
    """A live session's stream (a QP every period, the plan every 10 ms) gives the run's
    set-points exactly; it refuses a preview it cannot have."""
    t, f, w = _braking(300)
    ran = ModelPredictiveCueing(lead=0.1).run(f, w, DT).pose
    st = ModelPredictiveCueing(lead=0.1).stream(DT)
    streamed = np.array([st.step(f[i], w[i]) for i in range(t.size)])
    assert np.array_equal(ran, streamed)
    with pytest.raises(ValueError, match="preview must be 0"):
        ModelPredictiveCueing(preview=0.5).stream(DT)
