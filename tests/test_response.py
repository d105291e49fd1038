"""``simpro-sim response``: the sine fit, the linear prediction against the co-simulation,
and the one-line errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.design import PLANTS, corrected_design
from controllers.frequency import (
    OMCT_RAD_S,
    LoopModel,
    bandwidth_3db,
    equivalent_delay,
    fit_sine,
    predict,
)
from controllers.geometry import nominal_geometry
from controllers.kinematics import jacobian
from simpro_mj.analysis.response import check_periods, default_periods_ms, measure, plan_response
from simpro_mj.analysis.response_summary import loop_model, summary
from simpro_mj.commands.main import main
from simpro_mj.config.scenario import load_scenario

ACTS = ("actuator1", "actuator2", "actuator3")


def _db(h):
    return 20 * math.log10(abs(h))


def test_omct_frequencies():
    # ICAO 9625 OMCT: 12 frequencies, 0.1 to 15.85 rad/s, five per decade
    w = np.array(OMCT_RAD_S)
    assert w.size == 12
    assert w[0] == pytest.approx(0.1) and w[-1] == pytest.approx(15.85, rel=1e-3)
    assert np.allclose(np.diff(np.log10(w)), 0.2)
    # on the 1 ms grid every OMCT period moves by less than 0.5 ms (0.4 % at 15.85 rad/s)
    periods = default_periods_ms()
    assert 1000 in periods and 2000 in periods  # 1 Hz, 0.5 Hz for the summary
    for wk in w:
        assert min(abs(p - 2000 * math.pi / wk) for p in periods) <= 0.5


def test_fit_recovers_a_known_linear_system():
    """A discrete second-order lag with 50 ms of delay, driven by a sine from rest: the
    fit over whole settled periods gives its frequency response within 0.1 dB and 1 deg,
    with an offset and a drift added to the output."""
    import control as ct

    dt = 1e-3
    wn, zeta = 2 * math.pi * 1.5, 0.4
    g = ct.c2d(ct.tf([wn**2], [1, 2 * zeta * wn, wn**2]), dt, "zoh")
    g = g * ct.tf([1], [1] + [0] * 50, dt)  # z^-50
    for f in (0.5, 1.0, 2.0):
        w = 2 * math.pi * f
        t = np.arange(int(round((6 + 3 / f) / dt))) * dt
        u = 0.01 * np.sin(w * t)
        y = ct.forced_response(g, T=t, U=u).outputs + 0.3 + 0.02 * t
        k0 = int(round(6 / dt))
        h = fit_sine(t[k0:], y[k0:], w) / fit_sine(t[k0:], u[k0:], w)
        exact = complex(g(np.exp(1j * w * dt)))
        assert abs(_db(h) - _db(exact)) < 0.1
        assert abs(math.degrees(np.angle(h / exact))) < 1.0


def test_summary_figures_of_known_responses():
    f = np.geomspace(0.05, 5, 60)
    tau = 0.1
    h = np.exp(-2j * np.pi * f * tau)  # a pure delay: unit gain, no -3 dB point
    assert bandwidth_3db(f, h) is None
    assert equivalent_delay(f, h) == pytest.approx(tau, rel=1e-9)
    h1 = 1 / (1 + 1j * f / 0.8)  # first order, corner 0.8 Hz
    assert bandwidth_3db(f, h1) == pytest.approx(0.8, rel=0.02)


def _paper_model(mode, **kw):
    return LoopModel(
        plants=[PLANTS[a] for a in ACTS],
        designs=[corrected_design(a) for a in ACTS],
        jac=jacobian(nominal_geometry().home),
        mode=mode,
        **kw,
    )


@pytest.mark.parametrize("mode", ["joint_only", "I", "PI"])
def test_prediction_tracks_at_low_frequency(mode):
    # the joint loops (type 2) and the outer integrator both give unit gain at DC
    r = predict(_paper_model(mode, gains=3.0, imu_alpha=0.1, imu_every=5), [1e-3])
    assert np.allclose(r["true"][0], np.eye(3), atol=2e-3)


def _simulate_linear_loop(mode, w, gains=3.0, period_steps=60, dt=1e-3, axis=1, model_tau=0.0):
    """Time-domain run of the linear multirate loop, written out independently of
    :func:`predict`: the joint loops of :func:`controllers.analysis.lifted.inner_discrete_loop`
    at 1 ms, ``q_d = J x``, the outer law every ``period_steps`` steps (output
    ``x_c[k]`` then integrate, as :class:`controllers.task_space.TaskSpaceController`)."""
    from controllers.analysis.lifted import inner_discrete_loop

    legs = [inner_discrete_loop(corrected_design(a), PLANTS[a], dt) for a in ACTS]
    jac = jacobian(nominal_geometry().home)
    jinv = np.linalg.inv(jac)
    n = int(round((8.0 + 2 * 2 * math.pi / w) / dt))
    xs = [np.zeros(a.shape[0]) for a, _, _ in legs]
    xc, corr, ref_model = np.zeros(3), np.zeros(3), np.zeros(3)
    beta = 1 - math.exp(-dt / model_tau) if model_tau > 0 else 1.0
    t = np.arange(n) * dt
    r = np.zeros((n, 3))
    r[:, axis] = 0.01 * np.sin(w * t)
    y = np.zeros((n, 3))
    g = gains * period_steps * dt
    for k in range(n):
        q = np.array([(c @ x).item() for (_, _, c), x in zip(legs, xs, strict=True)])
        y[k] = jinv @ q
        if mode == "joint_only":
            x_cmd = r[k]
        elif k % period_steps == 0:
            if mode == "I":
                x_cmd = xc.copy()
                xc = xc + g * (r[k] - y[k])
            else:  # feedforward: the correction is integrated at the outer rate
                x_cmd_corr = corr.copy()
                corr = corr + g * ((ref_model if model_tau > 0 else r[k]) - y[k])
        if mode == "feedforward":
            x_cmd = r[k] + x_cmd_corr
            ref_model = ref_model + beta * (r[k] - ref_model)
        qd = jac @ x_cmd
        xs = [
            a @ x + (b * qd[i]).ravel()
            for i, ((a, b, _), x) in enumerate(zip(legs, xs, strict=True))
        ]
    k0 = int(round(8.0 / dt))
    return fit_sine(t[k0:], y[k0:], w) / fit_sine(t[k0:], r[k0:, axis], w)


@pytest.mark.parametrize(
    "mode, model_tau", [("joint_only", 0.0), ("I", 0.0), ("feedforward", 0.0), ("feedforward", 0.1)]
)
def test_prediction_matches_a_time_domain_run_of_the_linear_loop(mode, model_tau):
    """The sampled-data formula (lifted inner loops, staircase hold, Jacobian mixing,
    the feed-forward scheme's reference model) against the loop stepped in time:
    0.05 dB and 0.5 deg, cross axes included."""
    w = 2 * math.pi * 0.8
    h_sim = _simulate_linear_loop(mode, w, model_tau=model_tau)
    h = predict(_paper_model(mode, gains=3.0, model_tau=model_tau), [w])["true"][0][:, 1]
    assert abs(_db(h_sim[1]) - _db(h[1])) < 0.05
    assert abs(math.degrees(np.angle(h_sim[1] / h[1]))) < 0.5
    assert np.allclose(h_sim, h, atol=2e-3 * abs(h[1]))


@pytest.fixture(scope="module")
def linear_pitch():
    """The linear actuator option (eq. 19 on every slide), I law at K K_I = 3: one
    frequency measured on pitch, with the cross axes."""
    sc = load_scenario(
        "step_pitch", ["actuator.model=linear", "controller.outer.gains=[3.0, 3.0, 3.0]"]
    ).model_dump()  # the plan's dict
    # 0.1 deg: at 1 Hz near the loop's resonance, 0.5 deg puts the valves at their rails
    plan = plan_response(
        sc, periods_ms=[1000], amplitudes={"pitch": 0.1}, axes=("pitch",), settle_s=2.0, periods=1
    )
    results = measure(plan, jobs=1)
    return sc, plan, results


def test_linear_actuator_measured_matches_prediction(linear_pitch):
    sc, plan, results = linear_pitch
    assert results[0].status == "ok"
    doc = summary(plan, results, loop_model(sc))
    assert not doc.failed
    diag = [r for r in doc.rows if r.output_axis == "pitch" and r.input_axis == "pitch"]
    assert {r.signal for r in diag} == {"true", "measured"}
    for r in diag:
        assert r.saturated_pct == 0.0  # linear: no valve at a rail
        # the linear model is what the prediction describes: 0.5 dB and 3 deg
        assert abs(r.diff_db) < 0.5, r
        assert abs(r.diff_deg) < 3.0, r
        # and the loop is far from trivial there: the I loop lags by > 90 deg at 1 Hz
        assert r.phase_deg < -90.0


def test_bad_frequencies():
    for bad in ([0.3], [-1.0], [0.0], [float("nan")], [100.0], [0.5, 0.5]):
        with pytest.raises(Exception) as info:
            check_periods(bad)
        assert "--freq-hz" in str(info.value)
    assert check_periods([1.0, 0.5, 4.0]) == [2000, 1000, 250]


@pytest.mark.parametrize(
    "args, field",
    [
        (["--freq-hz", "0.3"], "--freq-hz"),  # 3333.33 ms: not on the 1 ms grid
        (["--freq-hz", "0"], "--freq-hz"),
        (["--freq-hz", "x"], "--freq-hz"),
        (["--amplitude-deg", "40"], "--amplitude-deg"),  # beyond the workspace
        (["--amplitude-mm", "400"], "--amplitude-mm"),
        (["--amplitude-mm", "0"], "--amplitude-mm"),
        (["--periods", "0"], "--periods"),
        (["--settle-s", "0.0005"], "--settle-s"),
        (["--axes", "yaw"], "--axes"),
    ],
)
def test_bad_input_is_one_line_exit_2(args, field, capsys, tmp_path):
    out = tmp_path / "r"
    code = main(["response", "step_pitch", "--out", str(out), "--quiet", *args])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error:")
    assert field in err
    assert not out.exists()  # refused before anything ran


def test_response_imports_no_command_module():
    """docs/architecture.md: commands only wire; the executors live in simpro_mj.sim.executors,
    not in the batch command, and the response command imports no other command."""
    from test_imports import import_graph

    graph = import_graph()
    for name in (
        "simpro_mj.commands.response",
        "simpro_mj.analysis.response",
        "simpro_mj.analysis.chain_response",
        "simpro_mj.sim.executors",
    ):
        bad = {m for m in graph[name] if m.startswith(("simpro_mj.commands.", "simpro_mj.batch"))}
        assert bad == set(), (name, bad)
    assert "simpro_mj.sim.executors" in graph["simpro_mj.analysis.response"]  # not vacuous
