"""``simpro-sim response --chain``: the whole cueing chain, vehicle -> driver's head.

The fit and the washout's linear prediction against a known linear case (the
washout on an ideal platform, computed here without MuJoCo), one co-simulated
point against the linearised chain, and the one-line errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.frames import pose_base_to_iso, static_specific_force
from controllers.frequency import CHAIN_CHANNELS, OMCT_RAD_S, chain_response
from controllers.washout import ClassicalWashout
from simpro_mj.analysis.chain_response import (
    PAIRS,
    chain_scenario,
    chain_summary,
    fit_columns,
    measure_chain_point,
    omct_periods_ms,
    plan_chain,
)
from simpro_mj.analysis.response import SineTask, measure
from simpro_mj.commands.main import main
from simpro_mj.config.cue_models import check_cueing
from simpro_mj.config.cue_params import washout_params
from simpro_mj.config.cueing import vehicle_input
from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError

#: cue_braking with the classical washout: the linear chain these tests compare with
CLASSICAL = ["setpoint.cueing.algorithm=classical_washout", "setpoint.cueing.parameters=null"]

DT = 0.001


def _db(h) -> float:
    return 20 * math.log10(abs(h))


def _ideal_columns(sc) -> dict:
    """The washout's set-points taken exactly by a rigid cabin with the head at P: head
    specific force from the tilt (exact rotation) plus the heave acceleration, and the
    angle rates, computed at the cueing period (central differences: no phase error,
    0.1 % of gain at 6.3 rad/s) and held on the 1 ms grid as the set-points are. (The
    derivatives of the 1 ms staircase itself are spikes whose 100 Hz content leaks
    into a one-period fit.)"""
    t, f, w, pose, info = vehicle_input(sc)
    e = info["every"]
    p = pose[::e]
    iso = pose_base_to_iso(p)
    dt = e * DT
    head_f = static_specific_force(p[:, 0], p[:, 1])
    head_f[:, 2] += np.gradient(np.gradient(iso[:, 2], dt), dt)
    head_w = np.zeros_like(head_f)
    head_w[:, 0] = np.gradient(iso[:, 0], dt)
    head_w[:, 1] = np.gradient(iso[:, 1], dt)
    head_f = np.repeat(head_f, e, axis=0)[: t.size]
    head_w = np.repeat(head_w, e, axis=0)[: t.size]
    cols = {"time_s": t}
    for k, a in enumerate("xyz"):
        cols[f"veh_f{a}_mps2"], cols[f"veh_w{a}_rad_s"] = f[:, k], w[:, k]
        cols[f"head_f{a}_mps2"], cols[f"head_w{a}_rad_s"] = head_f[:, k], head_w[:, k]
    return cols


@pytest.mark.parametrize("period_ms", [6283, 996])  # OMCT 1.0 and 6.31 rad/s
@pytest.mark.parametrize("channel", CHAIN_CHANNELS)
def test_fit_recovers_the_washout_on_an_ideal_platform(channel, period_ms):
    """Known linear case: on an ideal platform the chain is the washout alone. The fit
    of the discrete, nonlinear (asin, exact rotation) washout run recovers its linear
    prediction (discrete filters, 10 ms hold) within 0.05 dB and 0.5 deg on every OMCT
    pair, and the off-pair channels stay at least 40 dB below."""
    base = load_scenario("cue_braking.yaml", CLASSICAL).model_dump()  # the plan's dict
    amp = 0.3 if channel[0] == "f" else math.radians(1.0)
    sc = chain_scenario(base, channel, period_ms, amp, settle_s=10.0, periods=1)
    sc["duration_s"] += 0.1  # np.gradient's one-sided ends outside the fitted period
    sc["setpoint"]["cueing"] = check_cueing(sc["setpoint"]["cueing"])
    task = SineTask(sc, channel, period_ms, settle_s=10.0, periods=1)
    fit = fit_columns(_ideal_columns(sc), task)
    omega = 2000.0 * math.pi / period_ms
    wash = ClassicalWashout(washout_params(sc["setpoint"]["cueing"]))
    pred = chain_response(wash, [omega])[0]
    i = CHAIN_CHANNELS.index(channel)
    ref = complex(*fit.ref)
    assert abs(ref) == pytest.approx(amp, rel=1e-6)
    info = vehicle_input(sc)[4]
    assert not info["rate_limited"].any() and not info["softened"].any()  # small signal
    for o, out in enumerate(CHAIN_CHANNELS):
        h = complex(*fit.head[o]) / ref
        if (channel, out) in PAIRS:
            assert _db(h) == pytest.approx(_db(pred[o, i]), abs=0.05), out
            assert abs(math.degrees(np.angle(h / pred[o, i]))) < 0.5, out
        elif out != "fz":  # fz: the tilt's cos() gives only 2w, nothing at w
            assert abs(pred[o, i]) == 0.0
            assert abs(h) < 0.01 * max(abs(pred[:, i]).max(), 1e-9), out


def test_washout_prediction_known_values():
    """The washout alone at its limits: surge -> k_x at low frequency (tilt coordination:
    -g sin(-k_x f/g) = k_x f), roll rate -> the high-pass 1 above rot_omega, heave -> 0
    at low frequency (third-order high-pass)."""
    wash = ClassicalWashout()
    h = chain_response(wash, [0.01, 15.85])
    i = {c: k for k, c in enumerate(CHAIN_CHANNELS)}
    assert abs(h[0, i["fx"], i["fx"]]) == pytest.approx(0.5, rel=1e-3)
    assert abs(h[0, i["fy"], i["fy"]]) == pytest.approx(0.5, rel=1e-3)
    assert abs(h[1, i["wx"], i["wx"]]) == pytest.approx(1.0, abs=0.01)
    assert abs(h[0, i["fz"], i["fz"]]) < 1e-5
    # surge-to-pitch at low frequency: the tilt's rate, w k_x / g (rad/s per m/s^2)
    assert abs(h[0, i["wy"], i["fx"]]) == pytest.approx(0.01 * 0.5 / 9.80665, rel=1e-3)


@pytest.fixture(scope="module")
def cosim_pitch():
    sc = load_scenario("cue_braking.yaml", CLASSICAL).model_dump()  # the plan's dict
    plan = plan_chain(sc, periods_ms=[2513], channels=("wy",), settle_s=4.0, periods=1)
    return plan, measure(plan, jobs=1, fn=measure_chain_point, desc="chain response")


def test_cosimulated_chain_matches_the_linear_chain(cosim_pitch):
    """The co-simulated pitch channel at 2.5 rad/s (feed-forward scheme, nonlinear
    pneumatics) against the linearised chain: within 0.5 dB and 3 deg (they agree to
    0.1 dB and 0.5 deg on this machine). The platform adds to the pitch-to-surge
    leak: the head, 0.75 m above P on a mechanism that also moves P fore and aft,
    accelerates with the pitch: (g + 1.18 w^2) / g = +4.9 dB over the washout alone."""
    plan, results = cosim_pitch
    assert results[0].status == "ok", results[0]
    doc = chain_summary(plan, results)
    assert not doc.failed and doc.prediction_note is None
    rows = {r.test: r for r in doc.rows}
    assert set(rows) == {"pitch", "pitch-to-surge"}
    for r in rows.values():
        assert r.saturated_pct == 0.0 and r.rate_limited_pct == 0.0
        assert abs(r.gain_db - r.predicted_gain_db) < 0.5, r
        assert abs(r.phase_deg - r.predicted_phase_deg) < 3.0, r
    assert rows["pitch-to-surge"].platform_db > 3.0


def test_omct_periods():
    p = omct_periods_ms()
    assert len(p) == 12 and p[0] == 62832 and p[-1] == 396
    for w in OMCT_RAD_S:
        assert min(abs(q - 2000 * math.pi / w) for q in p) <= 0.5


def test_sine_vehicle_input_is_checked():
    ok = check_cueing({"sine": {"channel": "wx_rad_s", "amplitude": 0.1, "period_s": 2.0}})
    assert ok["sine"] == {"channel": "wx_rad_s", "amplitude": 0.1, "period_s": 2.0}
    for bad, match in [
        ({"channel": "wz_rad_s", "amplitude": 0.1, "period_s": 1}, r"sine.channel: 'wz_rad_s'"),
        ({"channel": "fx_mps2", "amplitude": 0, "period_s": 1}, r"sine.amplitude: 0"),
        ({"channel": "fx_mps2", "amplitude": 1, "period_s": 0.0005}, r"sine.period_s"),
        ({"channel": "fx_mps2", "amplitude": 1, "period_s": 1, "phase": 0}, r"sine.phase"),
    ]:
        with pytest.raises(UserInputError, match=match):
            check_cueing({"sine": bad})
    with pytest.raises(UserInputError, match="exactly one of"):
        check_cueing({"telemetry": "x.csv", "sine": {"channel": "fx_mps2"}})


@pytest.mark.parametrize(
    "args, field",
    [
        (["--chain", "--channels", "wz"], "--channels"),
        (["--chain", "--amplitude-mps2", "0"], "--amplitude-mps2"),
        (["--chain", "--amplitude-deg-s", "500"], "--amplitude-deg-s"),
        (["--chain", "--amplitude-deg", "1"], "--amplitude-deg"),
        (["--chain", "--axes", "roll"], "--axes"),
        (["--chain", "--freq-hz", "0.3"], "--freq-hz"),
        (["--chain", "--settle-s", "-1"], "--settle-s"),
        (["--amplitude-mps2", "0.3"], "--amplitude-mps2"),  # only with --chain
    ],
)
def test_bad_chain_input_is_one_line_exit_2(args, field, capsys, tmp_path):
    out = tmp_path / "r"
    code = main(["response", "cue_braking", "--out", str(out), "--quiet", *args])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error:")
    assert field in err
    assert not out.exists()
