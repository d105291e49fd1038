"""Stability analysis: Jury limits worked by hand, lifted inner loops, CLI contract."""

from __future__ import annotations

import json

import numpy as np
import pytest

from controllers.analysis.inner import companion, inner_summary, step_metrics, tf_step
from controllers.analysis.lifted import (
    closed_loops,
    lifted_inner,
    outer_closed_loop,
    real_inner_limit,
    reduced,
    spectral_radius,
)
from controllers.analysis.outer_delay import (
    closed_form_limit,
    outer_poles,
    outer_polynomials,
    root_locus,
    schur_stable,
    stability_limit,
)

T = 0.06


def _jury_table(coeffs) -> bool:
    """A Jury (Schur-Cohn) test written out by hand, an independent check of ``schur_stable``:
    ``|a_0| < |a_n|`` and the reduced ``(a_n P - a_0 P*) / z`` Schur, recursively."""
    a = np.trim_zeros(np.asarray(coeffs, dtype=float), "f")[::-1]
    while a.size > 1:
        n = a.size - 1
        if not abs(a[0]) < abs(a[n]):
            return False
        a = a[n] * a[1:] - a[0] * a[::-1][1:]
        a = a / np.max(np.abs(a))
    return True


def test_poles_agree_with_the_jury_table_on_random_polynomials():
    """The poles and the Jury table give the same verdict on 500 random real polynomials of
    degree 1-10 whose largest root is not within 1e-3 of the unit circle (nearer, both are
    decided by rounding)."""
    rng = np.random.default_rng(1)
    checked = 0
    for _ in range(500):
        n = int(rng.integers(1, 6))
        r = rng.uniform(0.1, 1.4, n) * np.exp(1j * rng.uniform(0, np.pi, n))
        roots = np.r_[r, r.conj()]
        if abs(np.abs(roots).max() - 1) < 1e-3:
            continue
        coeffs = np.real(np.poly(roots)) * rng.uniform(0.5, 3) * rng.choice([-1, 1])
        truth = np.abs(roots).max() < 1
        assert schur_stable(coeffs) == truth
        assert _jury_table(coeffs) == truth
        checked += 1
    assert checked > 400


def test_stability_margins_are_not_the_outer_limit():
    """Why stability_limit keeps its own crossing search: python-control's gain margin of
    B / A misses the z = -1 crossing of the PI law (eq. 24: 41.7 at T = 60 ms) and reports
    a spurious one at w = 0 for the I law (the integrator at z = 1). If a python-control
    release fixes both, this test fails and stability_limit can use it."""
    import warnings

    import control

    def margin(mode):
        a, b = outer_polynomials(mode, T, 1, 0.2)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            gm = control.stability_margins(control.tf(b, a, True))[0]
        return gm, stability_limit(a, b)

    gm_i, lim_i = margin("I")
    gm_pi, lim_pi = margin("PI")
    assert lim_i == pytest.approx(1 / T) and lim_pi == pytest.approx(2 / (0.8 * T))
    assert not (gm_i == pytest.approx(lim_i, rel=1e-6) and gm_pi == pytest.approx(lim_pi, rel=1e-6))


def test_root_locus_is_the_roots_of_A_plus_gB():
    """control.root_locus_map gives, per gain, the roots of A + g B (to 1e-9, any order)."""
    for mode, d in (("I", 1), ("PI", 1), ("I", 3), ("PI", 2)):
        a, b = outer_polynomials(mode, T, d, 0.2)
        gains = np.linspace(0.0, 60.0, 241)
        loc = root_locus(a, b, gains)
        assert loc.shape == (gains.size, a.size - 1)
        for g, row in zip(gains, loc, strict=True):
            want = np.sort_complex(np.roots(np.polyadd(a, g * b)))
            np.testing.assert_allclose(np.sort_complex(row), want, atol=1e-9)


def test_companion_is_control_tf2ss():
    """The realisation kept by hand (it runs in every preflight) is python-control's tf2ss,
    entry for entry, on the paper's plants (eqs. 34-35) and a proper transfer function."""
    import control

    from controllers.design import paper_plant

    cases = [(p.num, p.den) for p in map(paper_plant, ("actuator1", "actuator2"))]
    cases.append(([2.0, 3.0, 1.0], [1.0, 4.0, 5.0]))
    for num, den in cases:
        ref = control.tf2ss(num, den)
        for g, w in zip(companion(num, den), (ref.A, ref.B, ref.C, ref.D), strict=True):
            np.testing.assert_array_equal(g, w)


def _step_metrics_by_hand(t, y, yf, settle=0.02):
    """Step metrics written out by hand, an independent check of control.step_info."""
    out = {"final": yf}
    try:
        t10 = t[np.nonzero(y >= 0.1 * yf)[0][0]]
        t90 = t[np.nonzero(y >= 0.9 * yf)[0][0]]
        out["rise_time_s"] = float(t90 - t10)
    except IndexError:
        out["rise_time_s"] = float("nan")
    out["overshoot_pct"] = float(max(0.0, (y.max() - yf) / abs(yf) * 100.0))
    outside = np.nonzero(np.abs(y - yf) > settle * abs(yf))[0]
    if not outside.size:
        out["settling_time_s"] = float(t[0])
    elif outside[-1] + 1 < t.size:
        out["settling_time_s"] = float(t[outside[-1] + 1])
    else:
        out["settling_time_s"] = float("nan")
    return out


@pytest.mark.parametrize(
    "num, den, t_end",
    [
        ([16.0], [1, 4.0, 16.0], 6.0),  # zeta 0.5: overshoot 16.3 %
        ([1.0], [1, 1.0], 8.0),  # first order: no overshoot
        ([100.0], [1, 2.0, 100.0], 3.0),  # zeta 0.1, not settled within 3 s
        ([1.0], [1, 0.1], 3.0),  # reaches 26 %: no rise time
    ],
)
def test_step_info_equals_the_hand_written_metrics(num, den, t_end):
    """step_metrics (control.step_info) equals the hand-written definitions exactly on
    the sample grid (same samples picked: 10/90 % crossings, last exit from the 2 % band)."""
    t = np.arange(0, t_end, 1e-3)
    y = tf_step(num, den, t)
    got = step_metrics(t, y, final=num[0] / den[-1])
    want = _step_metrics_by_hand(t, y, num[0] / den[-1])
    assert got.keys() == want.keys()
    for k in want:
        np.testing.assert_allclose(got[k], want[k], rtol=1e-12, atol=0, equal_nan=True, err_msg=k)


def test_I_limit_by_hand_jury():
    """z^2 - z + gT: |a0| < 1 -> gT < 1; P(1) = gT > 0; P(-1) = 2 + gT > 0."""
    hand = 1.0 / T  # 16.67, the paper says 20
    a, b = outer_polynomials("I", T)
    np.testing.assert_allclose(np.polyadd(a, 3.0 * b), [1, -1, 3.0 * T])
    assert stability_limit(a, b) == pytest.approx(hand, rel=1e-9)
    assert closed_form_limit("I", T) == pytest.approx(hand)
    assert max(abs(outer_poles("I", hand * 0.999, T))) < 1
    assert max(abs(outer_poles("I", hand * 1.001, T))) > 1
    assert max(abs(outer_poles("I", 20.0, T))) > 1  # the paper's limit is already unstable
    # at K K_I = 3 the poles are real (overdamped, as the paper says): 1 - 4 gT > 0
    assert np.all(np.abs(outer_poles("I", 3.0, T).imag) < 1e-12)


def test_PI_limit_by_hand_jury():
    """z^2 + (gT - 1) z + c gT: c gT < 1 and P(-1) = 2 - gT + c gT > 0."""
    c = 0.2
    hand = min(1 / (c * T), 2 / ((1 - c) * T))  # min(83.3, 41.7)
    a, b = outer_polynomials("PI", T, pi_zero=c)
    np.testing.assert_allclose(np.polyadd(a, 20 * b), [1, 20 * T - 1, c * 20 * T])
    assert stability_limit(a, b) == pytest.approx(hand, rel=1e-9)
    assert hand == pytest.approx(41.667, abs=1e-3)
    # at the limit a root sits at z = -1 (P(-1) = 0)
    assert np.min(np.abs(outer_poles("PI", hand, T) + 1)) < 1e-9
    assert max(abs(outer_poles("PI", 50.0, T))) > 1  # the paper's 50 is unstable


def test_two_sample_delay_limit_by_hand():
    """z^3 - z^2 + gT (T = 30 ms, q(k) = q_d(k-2)): Jury 1 - (gT)^2 > |gT * (-1) - 0|."""
    t30 = 0.03
    hand = (np.sqrt(5) - 1) / 2 / t30
    a, b = outer_polynomials("I", t30, delay=2)
    assert stability_limit(a, b) == pytest.approx(hand, rel=1e-9)
    assert closed_form_limit("I", t30, delay=2) == pytest.approx(hand)


@pytest.mark.parametrize("mode, gain", [("I", 3.0), ("PI", 20.0)])
def test_lifted_pure_delay_reproduces_delay_model(mode, gain):
    f, _, _ = outer_closed_loop(mode, gain, T, lifted_inner(T, legs=[(0.0, 1.0, 1.0)]))
    ev = np.linalg.eigvals(f)
    want = outer_poles(mode, gain, T)
    ev = ev[np.abs(ev) > 1e-12]  # the PI realisation adds a pole at 0
    np.testing.assert_allclose(np.sort_complex(ev), np.sort_complex(want), atol=1e-12)
    assert real_inner_limit(mode, T, legs=[(0.0, 1.0, 1.0)]) == pytest.approx(
        stability_limit(*outer_polynomials(mode, T)), rel=1e-6
    )


@pytest.mark.parametrize("mode, c", [("I", 0.2), ("PI", 0.2), ("PI", 0.0)])
@pytest.mark.parametrize("period", [0.02, 0.06, 0.1])
def test_the_limits_block_scan_is_the_one_gain_at_a_time_scan(mode, c, period):
    """The scan solves its gains' closed loops a block at a time: the same matrices, the
    same spectral radii and the same limit as one gain at a time (the paper's joint
    loops behind the shipped ramps, the IK Jacobian at home; PI with c = 0 is the
    shipped I law's backward integrator). Equal to the bit on the machine that wrote
    this; elsewhere a stacked ``matmul`` may run another kernel than a 2-D one, so the
    matrices are compared at 1e-12 of their largest entry: each entry sums a few dozen
    products of numbers near 1, whose rounding is 1e-16 relative."""
    from controllers.geometry import geometry_from_rig
    from controllers.kinematics import jacobian

    geo = geometry_from_rig(None)
    jac = jacobian(geo.home, geo)
    ramps = ("ramp", (0.06, 0.03, 0.03))
    lifted = reduced(lifted_inner(period, setpoint_filter=ramps))
    grid = np.geomspace(1e-3, 200.0, 200)
    stacked = closed_loops(mode, grid, period, lifted, jac, c)
    one = np.stack([outer_closed_loop(mode, g, period, lifted, jac, c)[0] for g in grid])
    np.testing.assert_allclose(stacked, one, rtol=0.0, atol=1e-12 * np.abs(one).max())
    rho = np.array([spectral_radius(f) for f in one])
    first = int(np.argmax(rho >= 1.0))
    assert rho[first] >= 1.0 > rho[first - 1]  # a crossing inside the grid
    lim = real_inner_limit(mode, period, jac=jac, setpoint_filter=ramps, pi_zero=c)
    assert grid[first - 1] < lim <= grid[first]
    assert spectral_radius(outer_closed_loop(mode, lim, period, lifted, jac, c)[0]) == (
        pytest.approx(1.0, abs=1e-8)
    )


def test_real_inner_loop_lowers_limit_unless_inner_is_fast():
    """The zeta~1, wn~6.7 rad/s joint loop reaches < 50 % of a step in 60 ms: not a delay."""
    delay_lim = 1 / T
    slow = real_inner_limit("I", T, variant="corrected", actuators=("actuator2",))
    assert slow < 0.7 * delay_lim
    wn = 160.0
    spec = {"zeta": 0.7, "wn": wn, "p1": 7.6 * wn, "p2": 5.67 * wn}
    fast = real_inner_limit("I", T, variant="redesigned", actuators=("actuator2",), spec=spec)
    assert fast == pytest.approx(delay_lim, rel=0.01)


@pytest.mark.parametrize("times", [(0.06, 0.03, 0.03), (0.09, 0.06, 0.02)])
@pytest.mark.parametrize("mode", ["I", "PI"])
def test_reduced_lifted_loop_keeps_the_closed_loops_eigenvalues(mode, times):
    """The ramp filters' shift registers (rows of Phi that are zero) folded into the held
    input: the closed loop keeps its eigenvalues, so its spectral radius and limit.

    Compared above modulus 0.6 only: the full loop's nilpotent block (up to 59 states)
    comes out of LAPACK as a ring of radius eps^(1/59) ~ 0.54 instead of zeros."""
    from controllers.analysis.lifted import reduced

    full = lifted_inner(T, setpoint_filter=("ramp", times))
    small = reduced(full)
    folded = sum(min(round(t / 1e-3) - 1, round(T / 1e-3)) for t in times)
    assert small[0].shape[0] == full[0].shape[0] - folded + 3
    for gain in (0.5, 3.0, 12.0, 40.0):
        big, few = (
            np.linalg.eigvals(outer_closed_loop(mode, gain, T, lifted)[0])
            for lifted in (full, small)
        )
        big, few = big[np.abs(big) > 0.6], few[np.abs(few) > 0.6]
        assert big.size == few.size > 0
        assert np.max(np.min(np.abs(big[:, None] - few[None, :]), axis=1)) < 1e-9
        assert np.max(np.abs(few)) == pytest.approx(np.max(np.abs(big)), abs=1e-12)


def test_step_metrics_second_order():
    zeta, wn = 0.5, 4.0
    t = np.arange(0, 6, 1e-3)
    y = tf_step([wn**2], [1, 2 * zeta * wn, wn**2], t)
    m = step_metrics(t, y, final=1.0)
    assert m["overshoot_pct"] == pytest.approx(
        100 * np.exp(-np.pi * zeta / np.sqrt(1 - zeta**2)), abs=0.05
    )
    # 2 % settling of the envelope ~ 4 / (zeta wn) = 2 s (the last crossing is earlier)
    assert 1.0 < m["settling_time_s"] < 2.1


def test_inner_summary_corrected_cancels_plant():
    s = inner_summary("actuator2", "corrected", t_end=1.0)
    poles = s.closed_loop_poles
    plant = np.roots([1, 7.276, 1349])
    for p in plant:
        assert np.min(np.abs(poles - p)) < 1e-9  # the cancelled mode stays in the loop


@pytest.fixture(scope="module")
def analyzed(tmp_path_factory):
    """``analyze --json --out DIR`` with the defaults, run once for the tests that read
    it: ``(exit code, the JSON document, DIR)``."""
    import contextlib
    import io

    from simpro_mj.commands.main import main

    folder = tmp_path_factory.mktemp("analyze")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main(["analyze", "--json", "--out", str(folder)])
    return rc, json.loads(out.getvalue()), folder


def test_cli_json_contract(analyzed):
    rc, d, tmp_path = analyzed
    assert rc == 0
    assert d["outer"]["I"]["stability_limit"] == pytest.approx(1 / T)
    assert d["outer"]["PI"]["stability_limit"] == pytest.approx(2 / (0.8 * T))
    for act in ("actuator1", "actuator2"):
        for var in ("printed", "corrected"):
            poles = np.array(d["inner"][act][var]["closed_loop_poles"])
            assert poles.shape == (6, 2)
            assert np.all(poles[:, 0] < 0)
    assert {p.split("/")[-1] for p in d["plots"]} >= {"root_locus_I.png", "root_locus_PI.png"}
    for p in d["plots"]:
        assert (tmp_path / p.split("/")[-1]).stat().st_size > 1000


def test_cli_set_and_bad_set(capsys):
    from simpro_mj.commands.main import main

    rc = main(["analyze", "--json", "--no-plots", "--set", "outer.period_s=0.03"])
    d = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert d["outer"]["I"]["stability_limit"] == pytest.approx(1 / 0.03)
    assert main(["analyze", "--no-plots", "--set", "outer.period_s=0.0305"]) == 2
    assert "outer.period_s" in capsys.readouterr().err
    assert main(["analyze", "--no-plots", "--set", "inner.varaint=printed"]) == 2
    assert "inner.varaint" in capsys.readouterr().err


def test_analyze_reports_the_shipped_loop_first_and_says_which(analyzed, capsys):
    """The scenario's own loop (backward Euler, ramps 60/30/30 ms, corrected joint
    loops on the identified plant of preset paper: limit 11.84; on eqs. 34-35 14.08)
    comes before Fig. 7 as printed (forward Euler, no filter: 9.46 on eqs. 34-35)."""
    from simpro_mj.commands.main import main

    rc, d, _ = analyzed
    assert rc == 0
    assert list(d)[0] == "shipped"
    sh = d["shipped"]
    assert sh["loop"]["scenario"] == "step_pitch"
    assert sh["loop"]["law"].startswith("I law by backward Euler")
    assert sh["loop"]["setpoint_filter"] == "ramp 60/30/30 ms"
    assert sh["actuator"]["stability_limit"] == pytest.approx(11.84, abs=0.01)
    assert sh["paper"]["stability_limit"] == pytest.approx(14.08, abs=0.01)
    assert sh["actuator"]["stable_at_gains"] and sh["actuator"]["spectral_radius_at_gains"] < 1
    # the printed loop, analysed after it, is another loop with a lower limit
    assert d["outer"]["real_inner"]["I"]["stability_limit"] == pytest.approx(9.46, abs=0.01)
    # a scenario key goes to the scenario, an analysis key to the analysis
    sets = ["controller.outer.integrator=forward", "controller.setpoint_filter.type=none"]
    rc = main(["analyze", "--no-plots", *(a for s in sets for a in ("--set", s))])
    text = capsys.readouterr().out
    assert rc == 0
    first = text.splitlines()[0]
    assert "forward Euler" in first and "none set-point filter" in first
    assert "limit K K_I < 9.46" in text.splitlines()[2]  # on eqs. (34)-(35): Fig. 7's loop
    from simpro_mj.commands.analyze import _split_sets

    own, scenario = _split_sets(["outer.gain=2", "plant.preset=heavy_cabin", "paper_units=metres"])
    assert own == ["outer.gain=2", "paper_units=metres"]
    assert scenario == ["plant.preset=heavy_cabin", "paper_units=metres"]
    assert main(["analyze", "--no-plots", "--set", "controller.outer.integrater=forward"]) == 2
    assert "controller.outer.integrater" in capsys.readouterr().err


def test_a_loops_limits_are_cached_on_disk_and_recomputed_when_damaged(tmp_path, monkeypatch):
    """The scan runs once per loop: a later process reads its two limits back; a
    damaged file, or another number the analysis reads, is computed afresh."""
    from simpro_mj.analysis import stability as st
    from simpro_mj.config.scenario import load_scenario

    monkeypatch.setenv("SIMPRO_CACHE_DIR", str(tmp_path))
    s = load_scenario("step_pitch")
    st._analysed.cache_clear()
    first = st.outer_loop(s)
    assert first["limit"] == pytest.approx(11.84, abs=0.01)  # the nonlinear plant's limit
    (entry,) = (tmp_path / "stability").glob("*.json")
    real_scan = real_inner_limit

    def no_scan(*args, **kwargs):
        raise AssertionError("the limit was scanned again")

    st._analysed.cache_clear()  # a new process: memory empty, the file there
    monkeypatch.setattr(st, "real_inner_limit", no_scan)
    assert st.outer_loop(s) == first
    entry.write_text('{"key": ')
    st._analysed.cache_clear()
    monkeypatch.setattr(st, "real_inner_limit", real_scan)
    assert st.outer_loop(s) == first
    assert json.loads(entry.read_text())["limit"] == first["limit"]
    other = load_scenario("step_pitch", ["controller.outer.period_ms=30"])
    assert st.outer_loop(other)["limit"] != first["limit"]
    assert len(list((tmp_path / "stability").glob("*.json"))) == 2
