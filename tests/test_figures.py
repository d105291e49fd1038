"""Every figure simpro-sim draws: legends that name what is drawn, curves drawn faithfully.

The figures are drawn from synthetic data shaped like a run's log (a 20 s run
at 1 ms, a sweep's rows, a frequency response's table), so that no test here
simulates; :func:`simpro_mj.report.figures.legend_mismatches` is the check.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from simpro_mj.report import figures
from simpro_mj.report.figures import envelope, legend_mismatches


def _run_columns(n: int = 20001, seed: int = 0) -> dict[str, np.ndarray]:
    """A 20 s log at 1 ms with every column of a run (SI units)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    step = np.where(t >= 1.0, math.radians(3.0), 0.0)
    resp = step * (1.0 - np.exp(-np.clip(t - 1.0, 0.0, None) / 0.3))
    c = {"time_s": t}
    for axis, ref, out in (
        ("roll", np.zeros(n), 1e-4 * np.sin(t)),
        ("pitch", step, resp),
        ("heave", np.full(n, 1.265), 1.265 + 1e-4 * np.sin(t)),
    ):
        unit = "m" if axis == "heave" else "rad"
        c[f"{axis}_ref_{unit}"] = ref
        c[f"{axis}_{unit}"] = out
        c[f"{axis}_meas_{unit}"] = out + rng.normal(0.0, 1e-5, n)
        c[f"{axis}_cmd_{unit}"] = ref
    for i in (1, 2, 3):
        c[f"q{i}_ref_m"] = 0.25 + 0.02 * step * i
        c[f"q{i}_m"] = 0.25 + 0.02 * resp * i
        c[f"u{i}_v"] = 5.0 + 0.5 * np.sin(t * i)
        c[f"p{i}a_pa"] = 5.5e5 + 1e3 * np.sin(t)
        c[f"p{i}b_pa"] = 4.8e5 + 1e3 * np.cos(t)
    c["supply_pa"] = np.full(n, 7.013e5)
    return c


SCENARIO = {"name": "synthetic", "controller": {"mode": "task_space", "outer": {"type": "I"}}}


def test_envelope_keeps_every_extreme_and_the_time_order():
    t = np.arange(20001) * 1e-3
    rng = np.random.default_rng(1)
    y = np.cumsum(rng.normal(size=t.size))
    y[12345] = 1e3  # a one-sample spike
    tk, yk = envelope(t, y, buckets=500)
    assert tk.size < t.size / 4
    assert np.all(np.diff(tk) > 0)
    assert yk.max() == y.max() and yk.min() == y.min()
    # every bucket's extremes survive: the drawn band is the full curve's
    size = -(-t.size // 500)
    for start in range(0, t.size - size, size):
        block = y[start : start + size]
        kept = yk[(tk >= t[start]) & (tk <= t[start + size - 1])]
        assert kept.max() == block.max() and kept.min() == block.min()


def test_envelope_returns_short_or_non_finite_curves_whole():
    t = np.arange(100.0)
    assert envelope(t, t)[1].size == 100
    y = np.arange(20001.0)
    y[-1] = np.nan
    assert envelope(np.arange(20001.0), y)[1].size == 20001


def test_run_figures_legends_name_their_series():
    from simpro_mj.report.plots import RUN_FIGURES, run_figures

    figs = run_figures(_run_columns(), SCENARIO)
    assert set(figs) == set(RUN_FIGURES)
    for name, fig in figs.items():
        assert legend_mismatches(fig) == [], name


def test_valves_drawn_one_panel_each_in_the_leg_colours():
    from matplotlib.colors import to_rgba

    from simpro_mj.report.plots import run_figures

    fig = run_figures(_run_columns(), SCENARIO, only="valves")["valves"]
    assert len(fig.axes) == 3  # a valve never hides another
    for i, ax in enumerate(fig.axes, start=1):
        (line,) = [ln for ln in ax.lines if ln.get_label() == f"valve {i}"]
        assert to_rgba(line.get_color()) == to_rgba(figures.LEG_COLOURS[i])


def test_legend_mismatches_finds_a_promise_not_drawn():
    from matplotlib.figure import Figure

    fig = Figure()
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], label="drawn")
    ax.plot([], [], label="empty")
    ax.legend()
    ax.plot([0, 1], [1, 0], label="not listed")
    problems = legend_mismatches(fig)
    assert any("'empty'" in p and "without data" in p for p in problems)
    assert any("'not listed'" in p for p in problems)
    assert not any("'drawn'" in p for p in problems)


def test_compare_figure_legend():
    from simpro_mj.report.plots import compare_figure

    fig = compare_figure(_run_columns(), _run_columns(seed=1), SCENARIO)
    assert legend_mismatches(fig) == []


def _cue_columns() -> dict[str, np.ndarray]:
    c = _run_columns(n=6001)
    t = c["time_s"]
    for side, gain in (("veh", 1.0), ("head", 0.6)):
        for k, a in enumerate("xyz"):
            base = 9.80665 if a == "z" else 0.0
            c[f"{side}_f{a}_mps2"] = base + gain * np.sin(0.5 * t + k)
            c[f"{side}_w{a}_rad_s"] = 0.02 * gain * np.sin(0.7 * t + k)
    return c


def test_cueing_figures_legends_name_their_series():
    from simpro_mj.report.plots import cueing_figures

    figs = cueing_figures(_cue_columns(), SCENARIO)
    assert set(figs) == {"cueing", "cue_pose"}
    for name, fig in figs.items():
        assert legend_mismatches(fig) == [], name


def _response(with_prediction: bool = True):
    from simpro_mj.analysis.response_summary import (
        Bode,
        PoseResponse,
        PredictedCurve,
        ResponseRow,
    )

    freq = [0.2, 0.5, 1.0, 2.0]
    rows = []
    for a in ("pitch", "heave"):
        for o in ("roll", "pitch", "heave"):
            for sig in ("true", "measured"):
                for f in freq:
                    g = -3.0 * f if o == a else -40.0
                    rows.append(ResponseRow(
                        input_axis=a, output_axis=o, signal=sig, frequency_hz=f,
                        omega_rad_s=2 * np.pi * f, period_ms=round(1000 / f), amplitude=0.5,
                        gain=10 ** (g / 20), gain_db=g, phase_deg=-60.0 * f,
                        diff_db=0.1 if with_prediction else None,
                        diff_deg=2.0 if with_prediction else None,
                    ))  # fmt: skip
    dense = np.geomspace(0.2, 2.0, 50)
    curve = Bode(gain_db=(-3.0 * dense).tolist(), phase_deg=(-60.0 * dense).tolist())
    curves = {a: PredictedCurve(dense.tolist(), curve, curve) for a in ("pitch", "heave")}
    return PoseResponse(rows=rows, predicted_curves=curves if with_prediction else {})


@pytest.mark.parametrize("with_prediction", [True, False])
def test_bode_figures_draw_the_prediction_as_a_curve(with_prediction):
    from simpro_mj.report.response import bode_figures

    figs = bode_figures(
        _response(with_prediction), ["pitch", "heave"], "synthetic (task_space, I law)"
    )
    for name, fig in figs.items():
        assert legend_mismatches(fig) == [], name
    gain = figs["bode"].axes[0]
    predicted = [ln for ln in gain.lines if ln.get_label() == "predicted, true pose"]
    assert bool(predicted) == with_prediction
    if with_prediction:  # the dense curve, not a line through the four measured points
        assert len(predicted[0].get_xdata()) == 50
    assert "I law" in figs["bode"]._suptitle.get_text()
    assert "PI" not in figs["bode"]._suptitle.get_text()


def test_log_ticks_label_a_short_axis_without_overlap():
    from matplotlib.figure import Figure

    from simpro_mj.report.figures import log_ticks

    fig = Figure()
    ax = fig.add_subplot()
    ax.semilogx([0.2, 2.0], [0, 1])
    log_ticks(ax)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).draw()
    labels = [t.get_text() for t in ax.get_xticklabels(minor=True) + ax.get_xticklabels()]
    shown = [s for s in labels if s]
    assert set(shown) >= {"0.2", "0.5", "1", "2"}
    assert all("10" not in s or s == "10" for s in shown)  # no "3x10^-1"


def test_chain_figure_draws_washout_and_linear_chain_as_curves():
    from simpro_mj.analysis.chain_response import ChainCurve, ChainRow, ChainSummary
    from simpro_mj.analysis.response_summary import Bode
    from simpro_mj.report.response import chain_figure

    omega = [1.0, 2.5, 6.3]
    rows = [
        ChainRow(test="pitch", input="wy", output="wy", unit="deg/s per deg/s",
                 frequency_hz=w / (2 * np.pi), omega_rad_s=w, period_ms=round(2000 * np.pi / w),
                 amplitude=1.0, gain=0.89, gain_db=-1.0, phase_deg=-10.0 * w)
        for w in omega
    ]  # fmt: skip
    dense = np.geomspace(1.0, 6.3, 40).tolist()
    curve = Bode(gain_db=[-1.0] * 40, phase_deg=[-10.0 * w for w in dense])
    summary = ChainSummary(rows=rows, curves={"pitch": ChainCurve(dense, curve, curve)})
    fig = chain_figure(summary, "synthetic (feedforward, I correction)")
    assert legend_mismatches(fig) == []
    (washout,) = [ln for ln in fig.axes[0].lines if ln.get_label() == "washout alone"]
    assert len(washout.get_xdata()) == 40


def _sweep_rows(tmp_path, same_setpoint: bool):
    """Four variants of a gain sweep with their time series on disk."""
    from simpro_mj.batch.stability import Analytic
    from simpro_mj.batch.summary import AxisRow, Row
    from simpro_mj.report.results import write_timeseries

    rows = []
    for k, gain in enumerate((4.0, 8.0, 12.0, 16.0)):
        c = _run_columns(n=3001, seed=k)
        if not same_setpoint:
            c["pitch_ref_rad"] = c["pitch_ref_rad"] * (k + 1)
        folder = f"sweep/gains={gain:g}"
        (tmp_path / folder).mkdir(parents=True)
        write_timeseries(tmp_path / folder / "timeseries.csv", c)
        unstable = gain > 12
        rows.append(Row(
            variant=f"gains={gain:g}", scenario="sweep", folder=folder, status="ok",
            stable=not unstable, values={"controller.outer.gains": gain},
            roll=AxisRow(rms_err=0.01 * gain), pitch=AxisRow(rms_err=0.02 * gain),
            heave=AxisRow(rms_err=0.1 * gain), growth_rate_1_s=gain - 12.0,
            analytic=Analytic(growth_rate_1_s=gain - 11.8),
            cue={"cue_long_corr": 0.5 + 0.01 * k, "cue_pitch_box_frac": 0.9,
                 "cue_valve_sat_frac": 0.01 * k},
        ))  # fmt: skip
    info = {"scenario": "sweep", "folder": "sweep", "grid_paths": ["controller.outer.gains"],
            "monte_carlo": False}  # fmt: skip
    return rows, info


@pytest.mark.parametrize("same_setpoint", [True, False])
def test_sweep_responses_draw_each_variants_setpoint(tmp_path, same_setpoint):
    from simpro_mj.batch.plots import responses_figure

    rows, info = _sweep_rows(tmp_path, same_setpoint)
    fig = responses_figure(rows, info, tmp_path)
    assert legend_mismatches(fig) == []
    pitch = fig.axes[1]
    dashed = [ln for ln in pitch.lines if ln.get_linestyle() == "--"]
    # the stable variants' set-points (3 differ) or the one they share
    assert len(dashed) == (1 if same_setpoint else 3)
    top = max(float(np.max(ln.get_ydata())) for ln in dashed)
    assert top == pytest.approx(3.0 * (1 if same_setpoint else 3), rel=1e-6)


@pytest.mark.parametrize("with_limits", [True, False])
def test_metric_vs_param_lists_only_what_it_draws(tmp_path, with_limits):
    from simpro_mj.batch.plots import metric_vs_param_figure
    from simpro_mj.batch.tables import StabilityLimit

    rows, info = _sweep_rows(tmp_path, True)
    stability = []
    if with_limits:
        stability = [
            StabilityLimit(
                scenario=info["scenario"],
                group={},
                outer_type="I",
                period_ms=60.0,
                actuator_model="nonlinear",
                gains=[],
                stable=[],
                growth_rate_1_s=[],
                statuses=[],
                largest_stable=12.0,
                smallest_unstable=16.0,
                largest_settled=12.0,
                smallest_unsettled=16.0,
                simulated_limit=12.5,
                analytic_limit=11.8,
                analytic_limit_delay_model=None,
                simulated_over_analytic=12.5 / 11.8,
                note=None,
            )
        ]
    fig = metric_vs_param_figure(rows, info, stability)
    assert legend_mismatches(fig) == []
    labels = {t.get_text() for t in fig.axes[0].get_legend().get_texts()}
    assert ("analytic limit" in labels) == with_limits
    assert "unstable or not ok" in labels  # gains 16 is unstable: ringed
    assert "red ring" not in fig._suptitle.get_text()


def test_cue_tradeoff_writes_the_saturation_it_sizes(tmp_path):
    from simpro_mj.batch.plots import cue_tradeoff_figure

    rows, info = _sweep_rows(tmp_path, True)
    fig = cue_tradeoff_figure(rows, info)
    assert legend_mismatches(fig) == []
    notes = [t.get_text() for t in fig.axes[0].texts]
    assert any("sat 3.0 %" in n for n in notes)  # the saturation is written, not only sized


def _captured(monkeypatch) -> list:
    """Every figure saved while the test runs (the commands' pyplot figures)."""
    from matplotlib.figure import Figure

    saved = []
    original = Figure.savefig

    def savefig(self, *args, **kwargs):
        saved.append(self)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return saved


def test_analyze_figures_legends_name_their_series(tmp_path, monkeypatch):
    from simpro_mj.analysis.analyze import AnalyzeParams, compute
    from simpro_mj.config.messages import from_sets
    from simpro_mj.report.analyze import plot

    p = from_sets(AnalyzeParams)
    saved = _captured(monkeypatch)
    files = plot(compute(p), p, tmp_path)
    assert len(saved) == len(files) >= 3
    for fig in saved:
        assert legend_mismatches(fig) == [], fig.axes[0].get_title()


def test_validate_ik_figure_legend_names_its_series(tmp_path, monkeypatch):
    from simpro_mj.analysis.validate_ik import IkParams, plot, validate
    from simpro_mj.config.messages import from_sets

    saved = _captured(monkeypatch)
    # the same series as the 60 s default draws (the legends name them, not their length)
    plot(validate(from_sets(IkParams, ["trajectory.duration_s=5"])), tmp_path)
    assert len(saved) == 1
    assert legend_mismatches(saved[0]) == []


def test_identify_figure_legends_name_their_series(tmp_path, monkeypatch):
    from simpro_mj.identification.identify import default_tree, identify
    from simpro_mj.report.identify import plot

    tree = default_tree(None)
    tree["identify"]["duration_s"] = 2.0
    records: dict = {}
    results = identify(tree, legs=[1], records=records)
    saved = _captured(monkeypatch)
    plot(results, records, tmp_path / "identify.png", tree["paper_units"])
    assert len(saved) == 1
    assert legend_mismatches(saved[0]) == []


def test_sweep_responses_of_many_variants_coloured_by_gain(tmp_path):
    """More variants than a legend can name: colour is the gain (a colour bar), the line
    style the rest of the grid (in the legend); heave is drawn from the home height."""
    from simpro_mj.batch.plots import responses_figure
    from simpro_mj.batch.summary import Row
    from simpro_mj.report.results import write_timeseries

    rows = []
    for law in ("I", "PI"):
        for k, gain in enumerate(np.linspace(4.0, 24.0, 16).tolist()):
            c = _run_columns(n=3001, seed=k)
            c["heave_m"] = c["heave_m"] - 3.3e-3 * np.exp(-c["time_s"] / 0.3)  # start-up
            folder = f"sweep/type={law}_gains={gain:g}"
            (tmp_path / folder).mkdir(parents=True)
            write_timeseries(tmp_path / folder / "timeseries.csv", c)
            rows.append(Row(variant=f"type={law}_gains={gain:g}", scenario="sweep",
                            folder=folder, status="ok", stable=gain < 14.0,
                            values={"controller.outer.type": law,
                                    "controller.outer.gains": float(gain)}))  # fmt: skip
    info = {"scenario": "sweep", "folder": "sweep", "monte_carlo": False,
            "grid_paths": ["controller.outer.type", "controller.outer.gains"]}  # fmt: skip
    fig = responses_figure(rows, info, tmp_path)
    assert legend_mismatches(fig) == []
    labels = {t.get_text() for t in fig.axes[0].get_legend().get_texts()}
    assert {"type=I", "type=PI", "set-point (all variants)", "unstable or not ok"} <= labels
    assert not any("gains=" in lab for lab in labels)  # the gain is on the colour bar
    bars = [ax for ax in fig.axes if "gains" in ax.get_ylabel()]
    assert len(bars) == 1
    heave = fig.axes[2]
    assert heave.get_ylabel() == "heave from home [mm]"
    first = [ln.get_ydata()[0] for ln in heave.lines if ln.get_linestyle() != "--"]
    assert np.allclose(first, -3.3, atol=0.01)  # from home: the start-up offset shows
    fig.savefig(tmp_path / "responses.png", dpi=80)
