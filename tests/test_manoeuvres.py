"""Manoeuvres from the CommonRoad multi-body vehicle: signs and magnitudes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simpro_mj.commands.main import main
from simpro_mj.config.manoeuvres import ManoeuvreError, ManoeuvreSpec, generate, lane_change_path
from simpro_mj.config.telemetry import read_telemetry

pytest.importorskip("vehiclemodels")


def test_braking_presses_forward_and_dives_the_nose():
    tel = generate(ManoeuvreSpec("braking", 100.0, duration_s=2.5, rate_hz=100.0))
    t = tel.t
    hard = (t > 1.6) & (t < 2.5)
    # -5 m/s^2 commanded: the head feels about that, backwards (pressed into the belt)
    assert tel.f[hard, 0].mean() == pytest.approx(-5.0, abs=0.6)
    # the nose dives at the onset: ISO pitch rate > 0 (nose down)
    onset = (t > 1.0) & (t < 1.6)
    assert tel.w[onset, 1].max() > math.radians(2.0)
    assert tel.w[onset, 1].max() > -tel.w[onset, 1].min()
    assert abs(tel.f[t < 0.9, 0]).max() < 0.1  # straight at constant speed before
    assert tel.extra["speed_mps"][-1] < 100 / 3.6 - 5.0


def test_lane_change_turns_left_first_and_presses_the_driver_right():
    tel = generate(ManoeuvreSpec("lane_change", 80.0, duration_s=3.0, rate_hz=100.0))
    t = tel.t
    first = (t > 1.3) & (t < 2.3)  # the first half-wave to the left (x 15..45 m)
    k = np.argmax(np.where(first, tel.f[:, 1], -np.inf))
    assert tel.f[k, 1] > 2.0  # left turn: the seat pushes left, the driver feels pressed right
    assert tel.w[k, 2] > 0  # yaw rate to the left
    # the body rolls outwards (right side down, ISO roll > 0) as the turn builds
    roll = np.cumsum(tel.w[:, 0]) * (t[1] - t[0])
    assert roll[k] > math.radians(0.5)
    y, length, offset = lane_change_path(1.61)
    # half lane 1 (1.1 w + 0.25) + 1 m + half lane 3 (w + 1), w = 1.61 m
    assert offset == pytest.approx(1.0105 + 1.0 + 1.305) and length == 125.0
    assert tel.extra["y_m"][-1] > 0.5  # moving into the offset lane


def test_braking_in_a_turn_presses_forward_and_right():
    """The left turn from 1 s (3 m/s^2 at 60 km/h), braking at 6 m/s^2 from 2.5 s:
    the seat pushes the driver left while the belt holds them, the speed falls by
    about the 6 m/s^2 over the braking."""
    tel = generate(
        ManoeuvreSpec("braking_turn", 60.0, deceleration_mps2=6.0, duration_s=5.0, rate_hz=100.0)
    )
    t, v = tel.t, tel.extra["speed_mps"]
    turning = (t > 1.8) & (t < 2.4)  # in the turn, before the braking
    assert tel.f[turning, 1].mean() == pytest.approx(3.0, abs=0.6)
    assert tel.w[turning, 2].mean() > 0  # yaw to the left
    braking = (t > 3.0) & (t < 4.4)
    assert tel.f[braking, 0].mean() == pytest.approx(-6.0, abs=0.7)
    assert abs(tel.f[t < 0.9, 0]).max() < 0.1  # straight at constant speed before
    drop = v[np.searchsorted(t, 2.5)] - v[np.searchsorted(t, 4.5)]
    assert drop == pytest.approx(6.0 * 1.8, abs=1.5)  # 2 s less the ramps' 0.2 s


def test_bump_lifts_then_drops_the_head():
    tel = generate(ManoeuvreSpec("bump", 40.0, bump_height_m=0.05))
    fz = tel.f[:, 2] - 9.81
    assert fz.max() > 1.0 and fz.min() < -1.0
    assert np.argmax(fz) < np.argmin(fz)  # up first
    assert abs(fz[-10:]).max() < 0.05


def test_bad_specs_are_one_line_errors():
    with pytest.raises(ManoeuvreError, match=r"manoeuvre: 'drift'; allowed"):
        ManoeuvreSpec("drift", 50.0).check()
    with pytest.raises(ManoeuvreError, match="vehicle: 'tesla'"):
        ManoeuvreSpec("braking", 50.0, vehicle="tesla").check()
    with pytest.raises(ManoeuvreError, match="speed_kmh"):
        ManoeuvreSpec("braking", 500.0).check()


def test_manoeuvre_command_writes_a_telemetry_file(tmp_path, capsys):
    out = tmp_path / "b.csv"
    cmd = ["manoeuvre", "bump", "--out", str(out)]
    assert main([*cmd, "--set", "speed_kmh=30"]) == 0, capsys.readouterr().err
    tel = read_telemetry(out)
    assert tel.t[-1] > 3.0 and abs(tel.f[0, 2] - 9.81) < 1e-6
    capsys.readouterr()
    assert main(cmd) == 2
    err = capsys.readouterr().err
    assert "exists" in err and err.count("\n") == 1


def test_the_tyre_offsets_relay_is_a_roll_limit_cycle():
    """CommonRoad's lateral tyre offsets (p_hy1, p_vy1) switch with the camber's sign, a
    relay of about 0.1 F_z per tyre: driven straight at 60 km/h the body rolls through
    0.46 deg peak to peak at 1.6 Hz and the head feels 1.05 m/s^2 of sway peak to peak.
    With the offsets at 0 (the default) the car driven straight holds still."""
    runs = {
        mode: generate(ManoeuvreSpec("slalom", 60.0, duration_s=1.0, tyre_offsets=mode))
        for mode in ("commonroad", "none")
    }
    relay, still = runs["commonroad"], runs["none"]
    assert np.ptp(relay.f[:, 1]) == pytest.approx(1.05, abs=0.15)
    assert np.ptp(relay.w[:, 0]) > math.radians(3.0)  # +-2.4 deg/s of roll rate
    assert np.ptp(still.f[:, 1]) < 0.01 and np.ptp(still.w[:, 0]) < math.radians(0.01)
    with pytest.raises(ManoeuvreError, match=r"tyre_offsets: 'mf'; allowed: \['none'"):
        ManoeuvreSpec("slalom", 60.0, tyre_offsets="mf").check()
