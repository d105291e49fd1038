"""A batch's tables agree with themselves: a stopped batch counts finished variants
only, and the growth criterion and the verdict stand side by side, with a note where
they differ (simpro_mj/batch/tables.py, simpro_mj/batch/summary.py)."""

from __future__ import annotations

import io
from pathlib import Path

from simpro_mj.batch.plan import GAIN_PATH, Job
from simpro_mj.batch.stability import Analytic
from simpro_mj.batch.summary import AxisRow, Report, Row, summary_csv_text, verdict_note
from simpro_mj.batch.tables import monte_carlo_table, print_report, stability_table

_SCENARIO = {
    "controller": {"outer": {"type": "I", "period_ms": 60}},
    "actuator": {"model": "linear"},
}


def _row(variant, status, stable, growth=None, reason=None, ss=0.01):
    row = Row(
        variant=variant,
        scenario="gain",
        status=status,
        file="gain.yaml",
        reason=reason,
        pitch=AxisRow(ss_err=ss),
        stable=stable,
        growth_rate_1_s=growth,
        analytic=Analytic(14.08, 33.3),
    )
    row.stability_note = verdict_note(row)
    return row


def _job(i, gain, mc=False, sample=None):
    return Job(
        index=i, file="gain.yaml", scenario_name="gain", variant=f"v{i}", folder=f"gain/v{i}",
        values={GAIN_PATH: gain}, sample=sample, seed=None, scenario=_SCENARIO,
        gain_sweep=not mc, grid_paths=() if mc else (GAIN_PATH,), mc=mc,
    )  # fmt: skip


def test_small_signal_stable_limit_cycle_is_noted_in_row_and_limit_table():
    # gains 4..12 settle, 13 and 14 hold a bounded cycle whose envelope does not grow,
    # 16 grows: the growth's limit lies between 14 and 16, the verdict's between 12 and 13
    gains = [4, 8, 12, 13, 14, 16]
    cycle = "roll limit cycle of 0.3 deg at 2.1 Hz"
    rows = [
        _row("v0", "ok", True, -1.0),
        _row("v1", "ok", True, -0.5),
        _row("v2", "ok", True, -0.1),
        _row("v3", "limit_cycle", True, 0.02, cycle),
        _row("v4", "limit_cycle", True, 0.05, cycle),
        _row("v5", "limit_cycle", False, 0.8, cycle),
    ]
    jobs = [_job(i, g) for i, g in enumerate(gains)]
    assert rows[3].stability_note.startswith("small-signal stable")
    assert cycle in rows[3].stability_note
    assert rows[0].stability_note is None and rows[5].stability_note is None
    (t,) = stability_table(rows, jobs)
    assert (t.largest_stable, t.smallest_unstable) == (14, 16)
    assert (t.largest_settled, t.smallest_unsettled) == (12, 13)
    assert "K K_I 13, 14: small-signal stable" in t.note
    assert "limit_cycle" in t.note
    report = Report(out=Path("out"), rows=rows, paths=[GAIN_PATH], files=[], stability=[t])
    text = io.StringIO()
    print_report(report, file=text)
    lines = text.getvalue().splitlines()
    marked = [ln for ln in lines if ln.startswith(("v3 ", "v4 "))]
    assert len(marked) == 2 and all(" yes* " in ln for ln in marked)
    assert not any(" yes " in ln and "limit_cycle" in ln for ln in lines)  # never unmarked
    assert "settled <=" in text.getvalue()
    csv_text = summary_csv_text(report)
    assert "stability_note" in csv_text.splitlines()[0]
    assert csv_text.count("small-signal stable") == 2


def test_stopped_monte_carlo_counts_finished_samples_only():
    statuses = ["ok"] * 3 + ["limit_cycle"] + ["cancelled"] * 5 + ["interrupted"]
    rows = [_row(f"s{i}", s, None, ss=0.01 * (i + 1)) for i, s in enumerate(statuses)]
    for r in rows[4:]:
        r.pitch = AxisRow()
    jobs = [_job(i, 3.0, mc=True, sample=i) for i in range(len(rows))]
    (m,) = monte_carlo_table(rows, jobs)
    assert (m.samples, m.finished, m.unfinished) == (10, 4, 6)
    (g,) = m.groups
    assert (g.n, g.finished, g.of) == (3, 4, 10)
    assert abs(g.axes["pitch"].max - 0.03) < 1e-12
    report = Report(out=Path("out"), rows=rows, paths=[], files=[], monte_carlo=[m])
    text = io.StringIO()
    print_report(report, file=text)
    out = text.getvalue()
    assert "n=3/4 " in out and "6 not finished, not counted" in out
    assert "cancelled 5" in out and "interrupted 1" in out
