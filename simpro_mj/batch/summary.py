"""A batch's summary: one row per variant, the report, ``summary.csv`` and ``summary.json``.

summary.csv columns: ``variant``, ``scenario``, ``folder`` (relative to
OUT), one column per swept path (the value as declared, or as drawn),
``sample`` (Monte Carlo), ``seed``, ``status``, ``reason``, per axis
``<axis>_ss_err_<u>`` (signed mean error over the final window),
``<axis>_rms_err_<u>``, ``<axis>_max_err_<u>``, ``<axis>_rise_s``,
``<axis>_settling_s``, ``<axis>_overshoot_pct`` with ``u`` = deg (roll,
pitch) or mm (heave), then ``stable``, ``growth_rate_1_s``, ``stability_note``
(why a run is unstable, or, beside a ``stable`` run whose verdict is
``limit_cycle`` or ``not_settled``, that it is small-signal stable and
large-signal not: :mod:`simpro_mj.batch.tables`), for sweeps of
``controller.outer.gains`` ``analytic_limit``, ``analytic_limit_delay_model``
and ``analytic_growth_rate_1_s``, and last ``realtime_factor`` (the only
wall-clock column).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from simpro_mj.analysis.cue_metrics import SUMMARY_COLUMNS, summary_columns
from simpro_mj.analysis.verdict import FINISHED_STATUSES
from simpro_mj.batch.plan import Job
from simpro_mj.batch.stability import Analytic, Stability, analytic
from simpro_mj.config.sweep import format_value
from simpro_mj.report.results import jsonable

if TYPE_CHECKING:
    from simpro_mj.batch.robustness import RobustnessTable
    from simpro_mj.batch.tables import MonteCarloSpread, StabilityLimit

#: Variant statuses.
STATUSES = (*FINISHED_STATUSES, "interrupted", "failed", "invalid", "cancelled")

#: (axis, unit of its columns, SI to that unit)
AXES = (("roll", "deg", 180.0 / math.pi), ("pitch", "deg", 180.0 / math.pi), ("heave", "mm", 1e3))
#: (column suffix, metrics.json key, scaled to the axis unit?)
_METRICS = (
    ("ss_err", "steady_state_error", True),
    ("rms_err", "rms_error", True),
    ("max_err", "max_abs_error", True),
    ("rise_s", "rise_time_s", False),
    ("settling_s", "settling_time_s", False),
    ("overshoot_pct", "overshoot_pct", False),
)


def metric_columns() -> list[str]:
    """Per-axis metric column names of summary.csv (units in the names)."""
    return [f"{axis}_{suffix}_{unit}" if scaled else f"{axis}_{suffix}"
            for axis, unit, _ in AXES for suffix, _, scaled in _METRICS]  # fmt: skip


class AxisRow(NamedTuple):
    """One axis's step metrics in the summary's units: the errors in deg (roll, pitch)
    or mm (heave), the times in s, the overshoot in %; None where none was measured."""

    ss_err: float | None = None
    rms_err: float | None = None
    max_err: float | None = None
    rise_s: float | None = None
    settling_s: float | None = None
    overshoot_pct: float | None = None


@dataclass
class Row:
    """One variant's row of the summary (module docstring: its columns).

    ``analytic`` only on a gain sweep's rows (:func:`simpro_mj.batch.stability.analytic`);
    ``cue`` the cueing run's :data:`SUMMARY_COLUMNS`, empty for a step run.
    """

    variant: str
    scenario: str
    status: str
    folder: str = ""
    file: str = ""
    values: dict[str, Any] = field(default_factory=dict)
    sample: int | None = None
    seed: int | None = None
    reason: str | None = None
    skipped: bool = False
    roll: AxisRow = AxisRow()
    pitch: AxisRow = AxisRow()
    heave: AxisRow = AxisRow()
    stable: bool | None = None
    growth_rate_1_s: float | None = None
    stability_note: str | None = None
    analytic: Analytic | None = None
    realtime_factor: float | None = None
    wall_s: float | None = None
    cpu_s: float | None = None
    cue: dict[str, Any] = field(default_factory=dict)

    @property
    def axes(self) -> tuple[AxisRow, AxisRow, AxisRow]:
        """(roll, pitch, heave), in the order of :data:`AXES`."""
        return self.roll, self.pitch, self.heave

    def to_json(self) -> dict:
        """The row as ``summary.json`` writes it: one key per column."""
        out = {k: getattr(self, k) for k in _HEAD}
        out.update(zip(metric_columns(), (v for m in self.axes for v in m), strict=True))
        out.update(stable=self.stable, growth_rate_1_s=self.growth_rate_1_s)
        out.update(stability_note=self.stability_note)
        if self.analytic is not None:
            out.update({f"analytic_{k}": v for k, v in self.analytic._asdict().items()})
        out.update(realtime_factor=self.realtime_factor, wall_s=self.wall_s, cpu_s=self.cpu_s)
        return out | self.cue


#: The row's leading columns, in ``summary.json``'s order.
_HEAD = ("variant", "scenario", "folder", "file", "values", "sample", "seed", "status",
         "reason", "skipped")  # fmt: skip


def _sim_rt(doc: Mapping) -> float | None:
    sim = doc.get("sim") or {}
    rt = sim.get("realtime_factor")
    if rt is None:
        rt = (sim.get("wall_clock") or {}).get("realtime_factor")
    return rt


#: Verdicts a run can have while its error envelope does not grow (:mod:`simpro_mj.batch.tables`).
SMALL_SIGNAL_ONLY = ("limit_cycle", "not_settled")


def verdict_note(row: Row) -> str | None:
    """The note of a row whose two answers differ (:mod:`simpro_mj.batch.tables`), else None."""
    if row.stable is True and row.status in SMALL_SIGNAL_ONLY:
        why = f": {row.reason}" if row.reason else ""
        return (
            "small-signal stable (the error envelope does not grow), large-signal "
            f"{row.status} (the verdict{why})"
        )
    return None


def summary_row(job: Job, result: Mapping | None, skipped: bool = False) -> Row:
    """One summary row (SI converted to the column units)."""
    folder = job.folder if job.scenario is not None else ""
    row = Row(job.variant, job.scenario_name, "invalid" if job.error else "cancelled", folder,
              job.file, dict(job.values), job.sample, job.seed, job.error, skipped)  # fmt: skip
    if job.gain_sweep:
        row.analytic = Analytic() if job.scenario is None else analytic(job.scenario)
    if result is None:
        return row
    row.status = result.get("status", "failed")
    row.reason = result.get("reason")
    row.wall_s, row.cpu_s = result.get("wall_s"), result.get("cpu_s")
    doc = result.get("metrics")
    if doc:
        axes = doc.get("axes") or {}
        row.roll, row.pitch, row.heave = (
            AxisRow(*(_scaled((axes.get(axis) or {}).get(key), scale if scaled else 1.0)
                      for _, key, scaled in _METRICS))
            for axis, _, scale in AXES
        )  # fmt: skip
        row.realtime_factor = _sim_rt(doc)
        cue = doc.get("cueing") or (doc.get("metrics") or {}).get("cueing")
        if cue:
            row.cue = summary_columns(cue)
    stab: Stability | None = result.get("stability")
    if stab and not row.cue:
        # a cueing run is judged by the cue floors (cue_floors_met), not by the growth of
        # a step response's error: its set-point moves all along
        row.stable, row.growth_rate_1_s = stab.stable, stab.growth_rate_1_s
        row.stability_note = stab.why or verdict_note(row)
    return row


def _scaled(v: Any, scale: float) -> float | None:
    return None if v is None else float(v) * scale


@dataclass
class Report:
    """What a batch did: rows in expansion order, the stability table, files written."""

    out: Path
    rows: list[Row]
    paths: list[str]
    files: list[dict]
    stability: list[StabilityLimit] = field(default_factory=list)
    monte_carlo: list[MonteCarloSpread] = field(default_factory=list)
    #: the floors met over payload x friction (simpro_mj.batch.robustness)
    robustness: list[RobustnessTable] = field(default_factory=list)
    plots: list[str] = field(default_factory=list)
    skipped: int = 0
    wall_s: float = 0.0
    #: why the batch stopped before its end (a signal, no Dask workers), else None
    stopped: str | None = None
    #: the lines the variants' runs said (text -> how many variants), printed once
    notices: dict = field(default_factory=dict)

    @property
    def counts(self) -> dict:
        c = {s: 0 for s in STATUSES}
        for r in self.rows:
            c[r.status] = c.get(r.status, 0) + 1
        return c

    @property
    def all_ok(self) -> bool:
        return bool(self.rows) and all(r.status == "ok" for r in self.rows)

    def document(self) -> dict:

        return jsonable(
            {
                "out": str(self.out),
                "summary_csv": str(self.out / "summary.csv"),
                "counts": self.counts,
                "skipped": self.skipped,
                "wall_s": self.wall_s,
                "stopped": self.stopped,
                "notices": self.notices,
                "cpu_s": sum(r.cpu_s or 0.0 for r in self.rows),
                "swept_paths": self.paths,
                "files": self.files,
                "stability": self.stability,
                "monte_carlo": self.monte_carlo,
                "robustness": self.robustness,
                "plots": self.plots,
                "variants": self.rows,
            }
        )


def _cell(v: Any) -> str:

    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, (list, tuple, dict)):
        return format_value(v)
    return str(v)


def csv_columns(report: Report) -> list[str]:
    """summary.csv's columns for this batch (module docstring)."""
    cols = ["variant", "scenario", "folder", *report.paths]
    if any(r.sample is not None for r in report.rows):
        cols.append("sample")
    cols += ["seed", "status", "reason", *metric_columns(), "stable", "growth_rate_1_s"]
    cols.append("stability_note")
    if any(r.analytic is not None for r in report.rows):
        cols += ["analytic_limit", "analytic_limit_delay_model", "analytic_growth_rate_1_s"]
    if any("cue_long_corr" in r.cue for r in report.rows):  # cueing runs
        cols += list(SUMMARY_COLUMNS)
    cols.append("realtime_factor")
    return cols


def summary_csv_text(report: Report) -> str:
    cols = csv_columns(report)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in report.rows:
        flat = r.to_json()
        w.writerow([_cell(r.values.get(c) if c in report.paths else flat.get(c)) for c in cols])
    return buf.getvalue()


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def write_summary(report: Report) -> None:
    """Write ``summary.csv`` and ``summary.json`` into the batch folder (atomically)."""
    report.out.mkdir(parents=True, exist_ok=True)
    _atomic_write(report.out / "summary.csv", summary_csv_text(report))
    text = json.dumps(report.document(), indent=2, allow_nan=False)
    _atomic_write(report.out / "summary.json", text + "\n")
