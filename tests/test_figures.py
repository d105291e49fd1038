"""Every figure simpro-sim draws: legends that name what is drawn, curves drawn faithfully.

The figures are drawn from synthetic data shaped like a run's log (a 20 s run
at 1 ms, a sweep's rows, a frequency response's table), so that no test here
simulates; :func:`simpro_mj.report.figures.legend_mismatches` is the check.
"""

from __future__ import annotations

import math

import numpy as np

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
