"""A braking in a turn from a vehicle model the shipped drives are not made with
(CommonRoad's single-track model), through the shipped braking-in-a-turn law, the loop's
model and a rigid cabin: how the chain does on a drive it was not tuned on."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("vehiclemodels")  # the optional extra [vehicle]

from simpro_mj.analysis.omct import model_chain_metrics  # noqa: E402
from simpro_mj.config.scenario import load_scenario  # noqa: E402
from simpro_mj.config.single_track import braking_turn_single_track  # noqa: E402


@pytest.fixture(scope="module")
def drive():
    return braking_turn_single_track(duration_s=8.0)


def _block(**changes):
    cue = load_scenario("cue_braking_turn").setpoint.cueing.model_dump()
    return {"algorithm": cue["algorithm"], "parameters": {**cue["parameters"], **changes}}


def test_the_single_track_drive_brakes_in_a_left_turn(drive):
    """60 km/h, 3 m/s^2 into a left turn from 1 s, 6 m/s^2 of braking from 2.5 s: the head
    is pressed left (f_y > 0) and forwards (f_x < 0), the body neither rolls nor pitches."""
    k = int(round(3.2 * 200))
    assert drive.f[k, 0] == pytest.approx(-6.0, abs=0.3)
    assert 2.0 < drive.f[k, 1] < 4.0
    assert np.all(drive.w[:, :2] == 0.0) and np.all(drive.f[:, 2] == pytest.approx(9.81))
    assert drive.w[k, 2] > 0.1  # yawing left


@pytest.mark.slow
def test_the_shipped_law_on_a_drive_it_was_not_tuned_on(drive):
    """Both channels in shape (correlation >= 0.8), no raw wrong-way jolt past the
    otoliths' threshold (0.17 m/s^2) at any onset, both within 0.5 s. This car does not
    pitch, so the felt-pitch limit lets the tilt that carries the braking come and go
    only at a rate the canals barely feel: with the surge planned 0.17 s ahead as the
    sway and the felt pitch within 0.8 thresholds the surge lags more than 0.5 s; the
    shipped surge lead (0.5 s) and 0.9 thresholds bring it under 0.45 s (see docs/cueing.md; through
    the loop's model); with the limit off it lags less than 0.3 s."""
    m = model_chain_metrics(_block(), drive.t, drive.f, drive.w)["channels"]
    for ch in ("longitudinal_f", "lateral_f"):
        assert m[ch]["correlation"] >= 0.8
        assert (m[ch]["onset_raw_wrong_sign_peak"] or 0.0) <= 0.17
        assert m[ch]["mean_lag_s"] <= 0.5
    assert m["longitudinal_f"]["mean_lag_s"] < 0.45
    tight = _block(lead_x_s=0.0, rotation_limit_pitch=0.8)
    slow = model_chain_metrics(tight, drive.t, drive.f, drive.w)["channels"]
    assert 0.5 < slow["longitudinal_f"]["mean_lag_s"] < 0.7
    free = model_chain_metrics(_block(rotation_limit_pitch=0.0), drive.t, drive.f, drive.w)
    assert free["channels"]["longitudinal_f"]["mean_lag_s"] < 0.3
