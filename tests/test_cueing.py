"""The cueing chain in scenarios: telemetry files, the cueing block, the head sensors."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from controllers.frames import GRAVITY
from controllers.geometry import H0
from simpro_mj.analysis.cue_metrics import cue_metrics
from simpro_mj.analysis.cue_signals import mean_lag, shift_correlations
from simpro_mj.config.cue_models import check_cueing
from simpro_mj.config.cueing import CUE_COLUMNS, vehicle_input
from simpro_mj.config.scenario import load_scenario, resolve_scenario
from simpro_mj.config.telemetry import (
    TELEMETRY_COLUMNS,
    Telemetry,
    TelemetryError,
    read_telemetry,
    write_telemetry,
)
from simpro_mj.core.errors import UserInputError

HEADER = ",".join(TELEMETRY_COLUMNS)


def _braking_csv(path, a=3.0, duration=8.0, dt=0.01, onset=0.5):
    t = np.arange(0.0, duration + dt / 2, dt)
    f = np.zeros((t.size, 3))
    f[:, 2] = GRAVITY
    f[t >= onset, 0] = -a
    write_telemetry(path, Telemetry(t=t, f=f, w=np.zeros_like(f)), comment="test braking")
    return path


def _scenario(csv, duration=8.0, **params):
    return resolve_scenario(
        {
            "name": "cue_test",
            "duration_s": duration,
            "setpoint": {"cueing": {"telemetry": str(csv), "parameters": params}},
        }
    )


# ------------------------------------------------------------------ telemetry format


def test_telemetry_round_trip_and_extra_columns(tmp_path):
    p = _braking_csv(tmp_path / "b.csv")
    text = p.read_text()
    assert text.startswith("# test braking\n" + HEADER)
    tel = read_telemetry(p)
    assert tel.t[0] == 0.0 and tel.t[-1] == pytest.approx(8.0)
    assert tel.f[-1, 0] == -3.0 and tel.f[0, 2] == pytest.approx(GRAVITY)
    # unknown columns are ignored, column order is free
    q = tmp_path / "c.csv"
    q.write_text(
        "speed_mps,"
        + ",".join(reversed(TELEMETRY_COLUMNS))
        + "\n1,0,0,0,9.8,0,0,5\n1,0,0,0,9.8,0,0,5.05\n"
    )
    tel = read_telemetry(q)
    assert tel.t.tolist() == [0.0, pytest.approx(0.05)] and tel.f[0].tolist() == [0, 0, 9.8]


@pytest.mark.parametrize(
    "body, match",
    [
        (
            "time_s,fx_mps2,fy_mps2,fz_mps2,wx_rad_s,wy_rad_s\n0,0,0,9.8,0,0\n",
            r"missing column wz_rad_s \(header, row 1\)",
        ),
        (HEADER + "\n0,0,0,9.8,0,0,0\n0.01,0,nan,9.8,0,0,0\n", r"column fy_mps2 row 3: nan"),
        (
            HEADER + "\n0,0,0,9.8,0,0,0\n0.01,0,x,9.8,0,0,0\n",
            r"column fy_mps2 row 3: 'x' is not a number",
        ),
        (
            HEADER + "\n0,0,0,9.8,0,0,0\n0.02,0,0,9.8,0,0,0\n0.01,0,0,9.8,0,0,0\n",
            r"column time_s row 4: .*strictly increasing",
        ),
        (HEADER + "\n0,0,0,9.8,0,0,0\n0,0,0,9.8,0,0,0\n", r"column time_s row 3"),
        (
            HEADER + "\n# c\n0,0,0,9.8,0,0,0\n0.5,0,0,9.8,0,0,0\n",
            r"column time_s row 4: gap of 0.5 s",
        ),
        (HEADER + "\ninf,0,0,9.8,0,0,0\n1,0,0,9.8,0,0,0\n", r"column time_s row 2: inf"),
        (HEADER + "\n0,0,0,9.8,0,0,0\n", r"1 data rows"),
        ("", r"empty"),
    ],
)
def test_bad_telemetry_is_one_line_naming_column_and_row(tmp_path, body, match):
    p = tmp_path / "bad.csv"
    p.write_text(body)
    with pytest.raises(TelemetryError, match=match) as info:
        read_telemetry(p)
    assert "\n" not in str(info.value) and isinstance(info.value, UserInputError)


def test_bad_telemetry_through_the_cli_exits_2_with_one_line(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text(HEADER + "\n0,0,0,9.8,0,0,0\n0.01,0,0,9.8,0,0\n")
    scen = tmp_path / "s.yaml"
    scen.write_text(f"duration_s: 0.01\nsetpoint:\n  cueing: {{telemetry: {bad.name}}}\n")
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "simpro_mj.commands.main",
            "run",
            str(scen),
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "row 3: 6 fields; allowed: 7" in r.stderr
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------ the cueing block


def test_cueing_block_is_spelled_out_and_checked(tmp_path):
    csv = _braking_csv(tmp_path / "b.csv")
    sc = _scenario(csv, gain_x=0.4)
    cue = sc["setpoint"]["cueing"]
    assert cue["algorithm"] == "classical_washout" and cue["manoeuvre"] is None
    assert cue["parameters"]["gain_x"] == 0.4
    assert cue["parameters"]["tilt_rate_limit_deg_s"] == pytest.approx(3.0)
    # scenarios without a cueing block do not gain the key (their hash is unchanged)
    assert "cueing" not in load_scenario("step_pitch.yaml").model_dump()["setpoint"]
    for bad, match in [
        ({}, "exactly one of telemetry"),
        ({"telemetry": "x.csv", "manoeuvre": {"type": "bump", "speed_kmh": 30}}, "exactly one"),
        (
            {"telemetry": "x.csv", "algorithm": "lqr"},
            r"algorithm: 'lqr'; allowed: \['classical_washout', 'mpc'\]",
        ),
        (
            {"telemetry": "x.csv", "algorithm": "mpc", "parameters": {"tilt_rate_limit_deg_s": 3}},
            r"unknown key at setpoint.cueing.parameters.tilt_rate_limit_deg_s",
        ),
        (
            {"telemetry": "x.csv", "algorithm": "mpc", "parameters": {"horizon": 1}},
            r"parameters: mpc parameter horizon=1: allowed a whole number 2..200",
        ),
        ({"telemetry": "x.csv", "columns": {"fx": "a"}}, r"columns: column 'fx' unknown"),
        (
            {"telemetry": "x.csv", "parameters": {"gain_q": 1}},
            r"unknown key at setpoint.cueing.parameters.gain_q",
        ),
        ({"telemetry": "x.csv", "parameters": {"tilt_rate_limit_deg_s": -3}}, "tilt_rate_limit"),
        ({"manoeuvre": {"type": "drift", "speed_kmh": 30}}, r"manoeuvre.type: 'drift'"),
        ({"manoeuvre": {"type": "braking", "speed_kmh": 900}}, r"manoeuvre.speed_kmh: 900"),
    ]:
        with pytest.raises(UserInputError, match=match):
            check_cueing(bad)
    with pytest.raises(UserInputError, match="telemetry: 'nope.csv' not found"):
        _scenario("nope.csv")
    with pytest.raises(UserInputError, match="duration_s: 9 s is longer than the vehicle input"):
        _scenario(csv, duration=9.0)


def test_shipped_cue_scenarios_load():
    for name in ("cue_braking.yaml", "cue_lane_change.yaml", "cue_slalom.yaml", "cue_bump.yaml"):
        sc = load_scenario(name)
        t, f, w, pose, info = vehicle_input(sc)
        assert t[-1] == pytest.approx(sc.duration_s) and f.shape == (t.size, 3)
        # starts driving straight: gravity tilted by the body's static pitch (0.07 deg,
        # 0.012 m/s^2) and nothing sideways (the tyres' offsets at 0: docs/paper-notes.md)
        assert np.abs(f[0] - [0, 0, GRAVITY]).max() < 0.02
        assert not f.flags.writeable


# ------------------------------------------------------------------ the whole chain


@pytest.fixture(scope="module")
def braking_run(tmp_path_factory):
    from simpro_mj.sim.build import Build

    csv = _braking_csv(tmp_path_factory.mktemp("cue") / "b.csv")
    sc = _scenario(csv)
    return sc, Build(sc).simulation().run()


def test_head_sensors_feel_gravity_then_the_braking_cue(braking_run):
    sc, res = braking_run
    c = res.columns
    assert res.status == "ok"
    for name in CUE_COLUMNS:
        assert name in c and np.all(np.isfinite(c[name]))
    # the logged accelerometer is the head's acceleration minus gravity, in the
    # head's ISO axes: check it against the head site replayed from the logged
    # qpos (second differences; the sensor's value is one step old, sim.py)
    import mujoco

    from simpro_mj.plant.model import load_model

    m = load_model(sc["plant"])
    d = mujoco.MjData(m)
    rows = np.arange(100, 3000, 7)
    pos, rot = [], []
    for r in np.concatenate([rows - 2, rows - 1, rows]):
        d.qpos[:] = res.qpos[r]
        mujoco.mj_kinematics(m, d)
        pos.append(d.site("head").xpos.copy())
        rot.append(d.site("head").xmat.reshape(3, 3).copy())
    n = rows.size
    pos = np.array(pos).reshape(3, n, 3)
    acc = (pos[2] - 2 * pos[1] + pos[0]) / 1e-3**2  # at the middle row, r - 1
    g = -np.asarray(m.opt.gravity)  # (0, 0, +9.81)
    expect = np.einsum("nji,nj->ni", np.array(rot).reshape(3, n, 3, 3)[1], acc + g)
    got = np.stack([c[f"head_f{a}_mps2"][rows] for a in "xyz"], -1)
    assert np.abs(got - expect).max() < 0.02
    # at rest (the first 10 ms, before the loops move the platform from its
    # assembly pose to the set-point) the head feels +g on its z (ISO up)
    assert c["head_fz_mps2"][1:10].mean() == pytest.approx(GRAVITY, abs=0.02)
    # sustained braking (vehicle f_x = -3 m/s^2): the cabin pitched nose down
    # (base pitch < 0) and the driver's head feels f_x < 0: pressed into the belt
    end = slice(-500, None)
    assert c["pitch_rad"][end].mean() < -math.radians(7.0)
    assert c["head_fx_mps2"][end].mean() < -1.2
    # the specific force at the head is gravity through the measured attitude
    th = -c["pitch_rad"][end].mean()
    assert c["head_fx_mps2"][end].mean() == pytest.approx(-GRAVITY * math.sin(th), abs=0.03)
    assert np.abs(c["heave_m"] - H0).max() < 0.01


def test_cue_metrics_of_the_braking(braking_run):
    sc, res = braking_run
    m = cue_metrics(res.columns, sc)
    ch = m["channels"]["longitudinal_f"]
    # the task-space I loop (K K_I = 1) lags the washout by ~1 s: weak but right-signed
    assert ch["correlation"] > 0.2
    assert ch["vehicle_peak"] < 0 and ch["simulator_peak"] < 0  # same sign
    assert ch["onset_right_sign"] and ch["onset_false_cue_s"] == 0.0
    assert m["channels"]["lateral_f"]["false_cue_s"] == 0.0
    assert m["workspace"]["end_stop_margin_m"] > 0.05
    assert 0.0 <= m["valves"]["saturated_fraction"] <= 0.05
    assert 0.5 < m["workspace"]["box_fraction_max"]["pitch"] < 1.0


def _columns(t, veh_fx, head_fx):
    n = t.size
    c = {"time_s": t}
    for name in CUE_COLUMNS:
        c[name] = np.zeros(n)
    c["veh_fz_mps2"] = c["head_fz_mps2"] = np.full(n, GRAVITY)
    c["veh_fx_mps2"], c["head_fx_mps2"] = veh_fx, head_fx
    for i in (1, 2, 3):
        c[f"q{i}_m"] = np.full(n, 0.25)
        c[f"u{i}_v"] = np.full(n, 5.0)
    c["roll_rad"], c["pitch_rad"], c["heave_m"] = np.zeros(n), np.zeros(n), np.full(n, H0)
    return c


def test_cue_metrics_known_answers(braking_run):
    sc, _ = braking_run  # for the workspace box
    t = np.arange(0.0, 20.0, 0.001)
    pulse = -2.0 * np.exp(-(((t - 5.0) / 1.0) ** 2))
    # the same motion on both sides: correlation 1, no error, no lag, no false cue
    ch = cue_metrics(_columns(t, pulse, pulse), sc)["channels"]["longitudinal_f"]
    assert ch["correlation"] == pytest.approx(1.0) and ch["rms_error"] < 1e-12
    assert ch["mean_lag_s"] == 0.0 and ch["peak_lag_s"] == 0.0 and ch["false_cue_s"] == 0.0
    assert ch["onset_right_sign"]
    # delayed by 0.5 s: both lags 0.5 s
    late = np.interp(t - 0.5, t, pulse)
    ch = cue_metrics(_columns(t, pulse, late), sc)["channels"]["longitudinal_f"]
    assert ch["mean_lag_s"] == pytest.approx(0.5, abs=0.011)
    assert ch["peak_lag_s"] == pytest.approx(0.5, abs=0.002)
    assert ch["mean_lag_lower_bound"] is False
    # the wrong sign: every moment the simulator is felt is a false cue
    ch = cue_metrics(_columns(t, pulse, -pulse), sc)["channels"]["longitudinal_f"]
    assert ch["correlation"] == pytest.approx(-1.0)
    assert ch["false_cue_s"] == pytest.approx(ch["simulator_above_threshold_s"])
    assert ch["false_cue_s"] > 1.0
    assert not ch["onset_right_sign"]


def test_sweep_variants_get_the_preset_like_a_run():
    # a sweep's variants resolve as `simpro-sim run` does: plant preset between the
    # defaults and the file (not the bare defaults' 250 kg cabin)
    from simpro_mj.config.variants import load_sweep

    # the sweep runs 11.5 s, the length of the shortest recording it plays
    run = load_scenario("cue_braking.yaml", ["duration_s=11.5"]).model_dump()
    sw = load_sweep("sweep_cueing.yaml")
    (v,) = [
        x
        for x in sw.variants
        if x.values
        == {
            "setpoint.cueing.telemetry": "braking_100kmh.csv",
            "setpoint.cueing": {
                "algorithm": "mpc",
                "parameters": {
                    "preview_s": 1.0,
                    "lead_s": 0.17,
                    "lead_x_s": 0.5,
                    "rotation_limit_pitch": 0.9,
                },
            },
        }
    ]
    diff = {k for k in run if run[k] != v.scenario[k]}
    assert diff == {"name", "description"}
    assert len(sw.variants) == 12 and all(x.error is None for x in sw.variants)


def _direct_r(a, b, k):
    x, y = a[: a.size - k], b[k:]
    return float(np.corrcoef(x, y)[0, 1])


def test_shift_correlations_are_pearson_over_the_overlap():
    """The FFT form equals Pearson's r computed shift by shift (to 1e-9)."""
    rng = np.random.default_rng(3)
    a = np.cumsum(rng.normal(size=3000))
    b = np.roll(a, 400) + rng.normal(scale=5.0, size=3000) + 7.0
    r = shift_correlations(a, b, 1500)
    for k in (0, 1, 17, 400, 999, 1500):
        assert r[k] == pytest.approx(_direct_r(a, b, k), abs=1e-9)
    assert int(np.argmax(r)) == pytest.approx(400, abs=3)


def test_mean_lag_beyond_the_first_window():
    """The mean lag does not saturate at a 2 s window (which would give 2.0 for any
    longer lag): a pulse delayed by 3.5 s in a 20 s record gives 3.5 s; a lag longer
    than half the record gives the half as a lower bound, flagged."""
    dt = 0.001
    t = np.arange(0.0, 20.0, dt)
    pulse = -2.0 * np.exp(-(((t - 5.0) / 1.0) ** 2))
    for delay in (0.5, 1.99, 3.5):
        late = np.interp(t - delay, t, pulse)
        lag, bound = mean_lag(pulse, late, dt)
        assert lag == pytest.approx(delay, abs=0.011) and bound is False, delay
    # twice widened (2 -> 4 -> 8 s): a broad cue 6 s late
    broad = np.exp(-(((t - 5.0) / 2.5) ** 2))
    lag, bound = mean_lag(broad, np.interp(t - 6.0, t, broad), dt)
    assert lag == pytest.approx(6.0, abs=0.011) and bound is False
    # 6 s record, a smooth step at 1 s delayed by 4 s: r grows up to half the record
    t6 = np.arange(0.0, 6.0, dt)
    s6 = np.tanh((t6 - 1.0) / 0.5)
    lag, bound = mean_lag(s6, np.interp(t6 - 4.0, t6, s6, left=s6[0]), dt)
    assert bound is True and lag == pytest.approx(3.0, abs=0.011)
    assert mean_lag(pulse, np.zeros_like(pulse), dt) == (None, False)
