"""Cueing a driver would accept: the washout's tilt limits and head offset, the metrics
that cannot hide a false cue, the telemetry mapping, the large-signal input."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from controllers.frames import GRAVITY
from controllers.geometry import HEAD_HEIGHT_PITCH
from controllers.washout import ClassicalWashout
from simpro_mj.analysis.cue_metrics import cue_floors, summary_columns
from simpro_mj.analysis.cue_signals import false_rotation, onset_block, onsets
from simpro_mj.analysis.cue_summary import print_cue_summary
from simpro_mj.config.cue_models import check_cueing
from simpro_mj.config.cueing import step_input, vehicle_input
from simpro_mj.config.scenario import load_scenario, resolve_scenario
from simpro_mj.config.telemetry import TelemetryError, read_telemetry
from simpro_mj.core.errors import UserInputError

H = HEAD_HEIGHT_PITCH  # the head above the pitch motion's axis (1.21 m, measured)


def _head_fx(pitch_iso: np.ndarray, dt: float) -> np.ndarray:
    """The head's specific force along x of an ISO pitch history (rigid cabin)."""
    acc = np.gradient(np.gradient(pitch_iso, dt), dt)
    return H * acc - GRAVITY * np.sin(pitch_iso)


def _braking_run(**params):
    law = ClassicalWashout(**params)
    n = 600
    f = np.zeros((n, 3))
    f[:, 2] = GRAVITY
    f[100:, 0] = -2.0  # a braking step at 1 s: a 5.8 deg tilt, inside the soft limit
    res = law.run(f, np.zeros((n, 3)))
    assert not res.softened.any()
    return law, res.tilt[:, 1]  # ISO pitch


def test_washout_tilt_acceleration_and_jolt_limits():
    """The second-order limit: rate <= tilt_rate_limit, acceleration <= tilt_accel_limit;
    with the head 1.21 m above the pitch axis, the head's wrong-way specific force at
    the onset stays at the jolt limit (0.17 m/s^2), where without it the tilt's
    acceleration throws the head forwards by h * accel."""
    dt = 0.01
    law, th = _braking_run(tilt_rate_limit=math.radians(8.0))
    p = law.params
    rate = np.diff(th) / dt
    assert np.abs(rate).max() <= p.tilt_rate_limit * (1 + 1e-9)
    assert np.abs(np.diff(rate) / dt).max() <= p.tilt_accel_limit * (1 + 1e-6)
    jolt = _head_fx(th, dt)[95:200].max()
    assert jolt <= p.jolt_limit + 0.02
    _, th0 = _braking_run(tilt_rate_limit=math.radians(8.0), head_height_pitch=0.0)
    jolt0 = _head_fx(th0, dt)[95:200].max()
    # without the limit: h times the 30 deg/s^2 acceleration limit, 0.63 m/s^2
    assert jolt0 == pytest.approx(H * math.radians(30.0), rel=0.1)
    # both settle at the same tilt, asin(k a / g)
    assert th[-1] == pytest.approx(th0[-1], abs=1e-6)
    assert th[-1] == pytest.approx(math.asin(0.5 * 2.0 / GRAVITY), abs=1e-3)


def test_onsets_delay_and_raw_wrong_sign():
    """Known answers: a head sensation crossing 0.25 s after the vehicle's is a 0.25 s
    onset delay; a raw head jolt of +0.4 against a braking onset is reported as 0.4 even
    when its perceived effect stays below the threshold."""
    dt = 0.001
    t = np.arange(0.0, 6.0, dt)
    veh = np.where(t >= 1.0, -np.minimum((t - 1.0) / 0.5, 1.0), 0.0)  # perceived, m/s^2
    head = np.where(t >= 1.25, -np.minimum((t - 1.25) / 0.5, 1.0), 0.0)
    raw_veh = veh * 4.0
    raw_head = head.copy()
    raw_head[(t > 1.05) & (t < 1.15)] = 0.4  # the jolt
    assert [(a, b) for a, b in onsets(veh, 0.17)] == [(int(round(1.085 / dt)) + 1, t.size)]
    out = onset_block(t, veh, head, raw_veh, raw_head, 0.17)
    assert out["onsets"] == 1 and out["onsets_missed"] == 0
    assert out["onset_delay_s"] == pytest.approx(0.25, abs=2e-3)
    assert out["onset_raw_wrong_sign_peak"] == pytest.approx(0.4)
    assert out["onset_raw_wrong_sign_s"] == pytest.approx(0.065, abs=2e-3)  # from 1.085 s
    assert not out["onset_raw_right_sign"]
    # no head cue at all: the onset is missed, no delay
    out = onset_block(t, veh, np.zeros_like(t), raw_veh, np.zeros_like(t), 0.17)
    assert out["onsets_missed"] == 1 and out["onset_delay_s"] is None
    # an after-effect (the sensation past the threshold while the stimulus is at rest)
    # is no onset
    out = onset_block(t, -veh, -veh, np.zeros_like(t), np.zeros_like(t), 0.17)
    assert out["onsets"] == 0


def test_false_rotation_is_the_excess_over_the_car():
    pv = np.array([0.10, 0.10, 0.10, -0.10, 0.0])
    ps = np.array([0.05, 0.15, -0.05, 0.10, 0.07])
    # weaker, same sense: not false; stronger: the excess; opposite or none: all of it
    assert false_rotation(pv, ps) == pytest.approx([-0.05, 0.05, 0.05, 0.10, 0.07])


def test_cue_summary_and_summary_columns():
    cue = {
        "algorithm": "mpc",
        "source": "x.csv",
        "channels": {
            "longitudinal_f": {
                "unit": "m/s^2",
                "correlation": 0.9,
                "mean_lag_s": 0.2,
                "onset_delay_s": 0.25,
                "onset_raw_wrong_sign_peak": 0.1,
                "false_cue_s": 0.0,
                "vehicle_peak": -4.0,
            },
            "lateral_f": {"unit": "m/s^2", "correlation": None, "vehicle_peak": 0.1},
            "pitch_rate": {"unit": "rad/s", "false_rotation_s": 0.3},
        },
        "workspace": {"box_fraction_max": {"pitch": 0.8}, "end_stop_margin_m": 0.16},
        "valves": {"saturated_fraction": 0.0},
        "solve_time": {"p50_ms": 1.0, "p99_ms": 20.0, "max_ms": 30.0, "solves": 200},
    }
    buf = io.StringIO()
    print_cue_summary(cue, file=buf)
    text = buf.getvalue()
    assert "cueing (mpc, x.csv)" in text and "p99 20.00 ms" in text
    assert "longitudinal_f   0.90    0.20     0.25       0.10     0.00" in text
    assert "ss error" not in text
    row = summary_columns(cue)
    assert row["cue_main_channel"] == "long" and row["cue_long_onset_s"] == 0.25
    assert row["cue_pitch_false_rot_s"] == 0.3 and row["cue_solve_p99_ms"] == 20.0
    # every floor met on the main channel (no onset counted: the onset floors not asked)
    assert row["cue_floors_met"] is True and row["cue_floors_missed"] == ""
    assert "floors (longitudinal_f): met" in text


def test_cue_floors_name_each_floor_missed():
    """A run is judged by the floors a driver would accept, each miss named with its
    value: the sway channel's 0.85 correlation, the 0.3 s onset, a missed onset, the
    0.5 s of felt false roll, the box and the 5 % of valve saturation."""
    cue = {
        "channels": {
            "longitudinal_f": {"correlation": 0.99, "vehicle_peak": 0.1},
            "lateral_f": {
                "correlation": 0.84,
                "mean_lag_s": 0.1,
                "onsets": 3,
                "onset_delay_s": 0.31,
                "onsets_missed": 1,
                "onset_raw_wrong_sign_peak": 0.05,
                "vehicle_peak": -2.5,
            },
            "roll_rate": {"false_rotation_s": 0.51},
            "pitch_rate": {"false_rotation_s": 0.0},
        },
        "workspace": {"box_fraction_max": {"roll": 1.01, "pitch": 0.2}, "end_stop_margin_m": 0.1},
        "valves": {"saturated_fraction": 0.06},
    }
    floors = cue_floors(cue)
    assert floors.channel == "lateral_f" and not floors.met
    assert floors.missed == [
        "lateral_f correlation 0.84 < 0.85",
        "lateral_f onset delay 0.31 s > 0.3 s",
        "lateral_f onsets missed 1",
        "felt false roll 0.51 s > 0.5 s",
        "roll box 1.01 > 1",
        "valve saturation 0.06 > 0.05",
    ]


def test_cue_floors_judge_every_channel_the_vehicle_drives():
    """Braking in a turn drives surge (4.8 m/s^2) and sway (2.9 m/s^2), both past the
    otoliths' 0.17 m/s^2: a late sway onset misses the floors though surge, the larger,
    meets them; a channel the car does not drive past the threshold is not judged."""
    good = {"correlation": 0.97, "mean_lag_s": 0.2, "onsets": 1, "onset_delay_s": 0.29}
    good["onset_raw_wrong_sign_peak"] = 0.1
    cue = {
        "channels": {
            "longitudinal_f": {**good, "vehicle_peak": -4.8, "threshold": 0.17},
            "lateral_f": {**good, "onset_delay_s": 0.57, "vehicle_peak": 2.9, "threshold": 0.17},
        }
    }
    floors = cue_floors(cue)
    assert floors.channel == "longitudinal_f"
    assert floors.channels == ["longitudinal_f", "lateral_f"]
    assert floors.missed == ["lateral_f onset delay 0.57 s > 0.3 s"]
    cue["channels"]["lateral_f"] = {"correlation": 0.1, "vehicle_peak": 0.16, "threshold": 0.17}
    floors = cue_floors(cue)
    assert floors.channels == ["longitudinal_f"] and floors.met and floors.missed == []


def test_batch_judges_a_cueing_run_by_its_floors_not_step_growth():
    """The batch summary row of a cueing run carries the cue floors and no step-response
    stability verdict (a moving set-point's error is no step's growing envelope)."""
    from simpro_mj.batch.plan import Job
    from simpro_mj.batch.stability import Stability
    from simpro_mj.batch.summary import summary_row

    cue = {
        "algorithm": "mpc",
        "channels": {
            "longitudinal_f": {"correlation": 0.9, "mean_lag_s": 0.2, "vehicle_peak": -4.0}
        },
    }
    result = {
        "status": "ok",
        "metrics": {"axes": {}, "metrics": {"cueing": cue}},
        "stability": Stability(stable=False, growth_rate_1_s=0.3, why="grows"),
    }
    job = Job(0, "x.yaml", "x", "v", "v", {}, None, 1, None)
    row = summary_row(job, result)
    assert row.stable is None and row.growth_rate_1_s is None
    assert row.cue["cue_floors_met"] is True


def _user_csv(path):
    """A user's log: other names, time in ms, acceleration in g without gravity."""
    t = np.arange(0.0, 3.0, 0.01)
    ax = np.where(t >= 1.0, -0.3, 0.0)  # g
    lines = ["t_ms,ax_g,ay_g,az_g,p_dps,q_dps,r_dps"]
    for ti, a in zip(t, ax, strict=True):
        lines.append(f"{ti * 1e3:g},{a:g},0,0,0,1.5,0")
    path.write_text("\n".join(lines) + "\n")
    return path


MAPPING = {
    "time_s": {"column": "t_ms", "scale": 1e-3},
    "fx_mps2": {"column": "ax_g", "scale": GRAVITY},
    "fy_mps2": {"column": "ay_g", "scale": GRAVITY},
    "fz_mps2": {"column": "az_g", "scale": GRAVITY, "offset": GRAVITY},
    "wx_rad_s": {"column": "p_dps", "scale": math.pi / 180},
    "wy_rad_s": {"column": "q_dps", "scale": math.pi / 180},
    "wz_rad_s": "r_dps",
}


def test_telemetry_column_mapping_with_units(tmp_path):
    csv = _user_csv(tmp_path / "log.csv")
    tel = read_telemetry(csv, columns=MAPPING)
    assert tel.t[-1] == pytest.approx(2.99)
    assert tel.f[-1, 0] == pytest.approx(-0.3 * GRAVITY)
    assert tel.f[0, 2] == pytest.approx(GRAVITY)
    assert tel.w[0, 1] == pytest.approx(math.radians(1.5))
    sc = resolve_scenario(
        {
            "name": "mapped",
            "duration_s": 2.9,
            "setpoint": {"cueing": {"telemetry": str(csv), "columns": MAPPING}},
        }
    )
    assert sc["setpoint"]["cueing"]["columns"]["wz_rad_s"] == {
        "column": "r_dps",
        "scale": 1.0,
        "offset": 0.0,
    }
    _, f, _, _, _ = vehicle_input(sc)
    assert f[-1, 0] == pytest.approx(-0.3 * GRAVITY)
    # a run as long as the file allows: the error names that length on the 1 ms grid
    with pytest.raises(UserInputError, match=r"duration_s: 3.5 s .*allowed: <= 2.990$"):
        vehicle_input({**sc, "duration_s": 3.5})
    # a wrong column: one line naming it, the mapped key and the file's header
    bad = {**MAPPING, "fx_mps2": {"column": "accel_x", "scale": GRAVITY}}
    with pytest.raises(TelemetryError) as info:
        read_telemetry(csv, columns=bad)
    msg = str(info.value)
    assert "missing column accel_x (mapped to fx_mps2" in msg and "t_ms, ax_g" in msg
    assert "\n" not in msg
    # without a mapping: the missing standard column and the way out
    with pytest.raises(TelemetryError, match="missing column time_s .* or a mapping"):
        read_telemetry(csv)
    with pytest.raises(UserInputError, match=r"columns: fz_mps2.scale: 0; allowed"):
        check_cueing({"telemetry": "x.csv", "columns": {"fz_mps2": {"column": "a", "scale": 0}}})


def test_large_signal_step_and_ramp_inputs():
    t = np.arange(0.0, 8.0, 0.001)
    f, w = step_input(
        {"channel": "fx_mps2", "amplitude": -4.0, "start_s": 1.0, "ramp_s": 0.0, "end_s": 6.0}, t
    )
    assert f[999, 0] == 0.0 and f[1000, 0] == -4.0 and f[6000, 0] == 0.0
    assert np.all(f[:, 2] == GRAVITY) and not w.any()
    f, _ = step_input(
        {"channel": "fx_mps2", "amplitude": -5.0, "start_s": 1.0, "ramp_s": 2.0, "end_s": None}, t
    )
    assert f[2000, 0] == pytest.approx(-2.5) and f[-1, 0] == -5.0
    # the shipped large-signal scenario: the MPC's plan stays inside its pitch limit
    sc = load_scenario("cue_step_fx.yaml")
    _, _, _, pose, info = vehicle_input(sc)
    lo, hi = info["box"]["pitch"]
    assert lo < pose[:, 1].min() < 0.7 * lo  # nose down, 70-100 % of the box
    assert info["solve_time"]["not_solved"] == 0


def test_task_space_on_a_moving_cue_is_warned_with_numbers():
    """The pose loop alone lags a 0.5 Hz cue by about half a second where the
    feed-forward scheme lags it by a tenth; the warning gives both."""
    import re

    from simpro_mj.analysis.preflight import cueing_mode_warnings

    sc = load_scenario("cue_lane_change.yaml", ["controller.mode=task_space"])
    (msg,) = cueing_mode_warnings(sc)
    task_space = float(re.search(r"([0-9.]+) s of delay", msg)[1])
    feedforward = float(re.search(r"dB, ([0-9.]+) s\)", msg)[1])
    assert "controller.mode = task_space" in msg and "use controller.mode = feedforward" in msg
    assert task_space > 0.3 > 0.15 > feedforward
    assert cueing_mode_warnings(load_scenario("cue_lane_change.yaml")) == []
