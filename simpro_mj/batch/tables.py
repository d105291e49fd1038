"""A batch's tables: the stability limit per gain sweep, the Monte Carlo spread, and
the human summary :func:`print_report` prints.

Stability limit: see :mod:`simpro_mj.batch.stability`. Monte Carlo: per file and
grid combination, the median, 90th percentile and maximum of |steady-state
error| over the variants with status ``ok``, out of those that finished; the
variants the batch did not finish (``cancelled``, ``interrupted``) are counted
apart, never as failures.

Two answers per variant of a gain sweep, printed side by side: ``stable`` is the
error envelope's growth (:mod:`simpro_mj.batch.stability`: does a disturbance
grow? the small-signal question the linear analysis answers) and ``status`` the
run's verdict on its final window (:mod:`simpro_mj.analysis.verdict`: is the pose
still moving?). They differ where the loop is small-signal stable but holds a
bounded, large-signal limit cycle (saturation, the valves' dead zone, the seals'
friction): the row's ``stability_note`` says so, and the limit table gives both
limits (``stable <=`` by the growth, ``settled <=`` by the verdict).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from simpro_mj.batch.plan import GAIN_PATH, Job
from simpro_mj.batch.robustness import UNFINISHED, table_lines
from simpro_mj.batch.stability import Analytic
from simpro_mj.batch.summary import AXES, SMALL_SIGNAL_ONLY, Report, Row, verdict_note
from simpro_mj.config.models import as_scenario
from simpro_mj.config.sweep import format_value


@dataclass
class StabilityLimit:
    """One gain sweep group's stability limit, K K_I (1/s), analytic against simulated.

    ``stable`` and ``statuses`` per gain, the two answers of the module docstring:
    ``largest_stable`` / ``smallest_unstable`` by the error envelope's growth,
    ``largest_settled`` / ``smallest_unsettled`` by the verdict; ``simulated_limit``
    the growth's zero crossing interpolated between them (their midpoint when the
    growth rates do not bracket zero).
    """

    scenario: str
    group: dict[str, str]
    outer_type: str
    period_ms: float
    actuator_model: str
    gains: list[float]
    stable: list[bool]
    growth_rate_1_s: list[float | None]
    statuses: list[str]
    largest_stable: float | None
    smallest_unstable: float | None
    largest_settled: float | None
    smallest_unsettled: float | None
    simulated_limit: float | None
    analytic_limit: float | None
    analytic_limit_delay_model: float | None
    simulated_over_analytic: float | None
    note: str | None


@dataclass
class ErrorSpread:
    """|steady-state error| of a group's ok variants on one axis (``unit``: deg or mm)."""

    unit: str
    median: float | None
    p90: float | None
    max: float | None


@dataclass
class SpreadGroup:
    """One grid combination of a Monte Carlo file: ``n`` its ok variants, ``finished``
    those that finished, ``of`` all of them; ``axes`` the spread per axis."""

    group: str
    n: int
    finished: int
    of: int
    axes: dict[str, ErrorSpread]


@dataclass
class MonteCarloSpread:
    """A Monte Carlo file's spread per grid combination (:func:`monte_carlo_table`)."""

    scenario: str
    samples: int
    finished: int
    unfinished: int
    groups: list[SpreadGroup]


def number(value) -> float | None:
    """A swept value as a number: a number, or a list of equal numbers (a common K K_I
    of the per-axis gains); None otherwise."""
    if isinstance(value, bool):
        return None
    if isinstance(value, (int, float)):
        return float(value)
    numbers = isinstance(value, list) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
    )
    if numbers and value and len({float(v) for v in value}) == 1:
        return float(value[0])
    return None


def stability_table(rows: list[Row], jobs: list[Job]) -> list[StabilityLimit]:
    """Analytic vs simulated stability limit per gain sweep group (module docstring)."""

    groups: dict[tuple, list[tuple[float, Row, Job]]] = {}
    for row, job in zip(rows, jobs, strict=True):
        if not job.gain_sweep or job.mc or row.stable is None:
            continue
        g = number(job.values.get(GAIN_PATH))
        if g is None:
            continue
        others = tuple((p, format_value(job.values[p])) for p in job.grid_paths if p != GAIN_PATH)
        groups.setdefault((job.scenario_name, others), []).append((g, row, job))
    table = []
    for (sname, others), members in groups.items():
        members.sort(key=lambda m: m[0])
        gains = [m[0] for m in members]
        stable = [bool(m[1].stable) for m in members]
        statuses = [m[1].status for m in members]
        unstable_at = [g for g, s in zip(gains, stable, strict=True) if not s]
        hi = min(unstable_at) if unstable_at else None
        below = [m for m in members if m[1].stable and (hi is None or m[0] < hi)]
        lo_m = below[-1] if below else None
        lo = lo_m[0] if lo_m else None
        estimate = None
        if lo is not None and hi is not None:
            assert lo_m is not None  # lo is its gain
            hi_m = next(m for m in members if m[0] == hi)
            s_lo, s_hi = lo_m[1].growth_rate_1_s, hi_m[1].growth_rate_1_s
            if s_lo is not None and s_hi is not None and s_lo < 0 < s_hi:
                estimate = lo + (hi - lo) * (-s_lo) / (s_hi - s_lo)
            else:
                estimate = 0.5 * (lo + hi)
        first = members[0][2].scenario
        assert first is not None  # a planned variant's
        outer, actuator = (sc := as_scenario(first)).controller.outer, sc.actuator.model
        ana = members[0][1].analytic or Analytic()
        note = []
        if actuator != "linear":
            note.append("nonlinear pneumatics: the analysis assumes eq. (19) plants")
        if any(s and g > hi for g, s in zip(gains, stable, strict=True) if hi is not None):
            note.append("not monotonic: a stable gain above an unstable one")
        unsettled_at = [g for g, st in zip(gains, statuses, strict=True) if st != "ok"]
        settled_hi = min(unsettled_at) if unsettled_at else None
        settled = [g for g, st in zip(gains, statuses, strict=True) if st == "ok"]
        settled_lo = max((g for g in settled if settled_hi is None or g < settled_hi), default=None)
        cycling = [
            (g, st)
            for g, s, st in zip(gains, stable, statuses, strict=True)
            if s and st in SMALL_SIGNAL_ONLY
        ]
        if cycling:
            kinds = sorted({st for _, st in cycling})
            note.append(
                f"K K_I {', '.join(f'{g:g}' for g, _ in cycling)}: small-signal stable (the error "
                f"envelope does not grow) but the verdict is {' / '.join(kinds)} (a bounded "
                "large-signal oscillation or drift): stable <= is the growth's limit, settled "
                "<= the verdict's"
            )
        table.append(
            StabilityLimit(
                scenario=sname,
                group={p: v for p, v in others},
                outer_type=outer.type,
                period_ms=outer.period_ms,
                actuator_model=actuator,
                gains=gains,
                stable=stable,
                growth_rate_1_s=[m[1].growth_rate_1_s for m in members],
                statuses=statuses,
                largest_stable=lo,
                smallest_unstable=hi,
                largest_settled=settled_lo,
                smallest_unsettled=settled_hi,
                simulated_limit=estimate,
                analytic_limit=ana.limit,
                analytic_limit_delay_model=ana.limit_delay_model,
                simulated_over_analytic=(estimate / ana.limit) if estimate and ana.limit else None,
                note="; ".join(note) or None,
            )
        )
    return table


def monte_carlo_table(rows: list[Row], jobs: list[Job]) -> list[MonteCarloSpread]:
    """Distribution of |steady-state error| per Monte Carlo file and grid combination.

    Per axis the median, 90th percentile and maximum over the variants with
    status ``ok`` (deg, deg, mm as in the summary columns). Per group ``n`` those
    variants, ``finished`` the variants that finished, ``of`` all its variants;
    per file ``finished`` and ``unfinished`` (module docstring).
    """

    samples: dict[str, int] = {}
    files: dict[str, dict[str, list[Row]]] = {}
    for row, job in zip(rows, jobs, strict=True):
        if not job.mc:
            continue
        sname = job.scenario_name
        samples[sname] = max(samples.get(sname, 0), (job.sample or 0) + 1)
        group = ", ".join(
            f"{p.split('.')[-1]}={format_value(job.values[p])}" for p in job.grid_paths
        )
        files.setdefault(sname, {}).setdefault(group or "all", []).append(row)
    out = []
    for sname, members_of in files.items():
        groups = []
        for name, members in members_of.items():
            ok = [r for r in members if r.status == "ok"]
            axes = {}
            for i, (axis, unit, _) in enumerate(AXES):
                v = np.abs([e for r in ok if (e := r.axes[i].ss_err) is not None])
                axes[axis] = ErrorSpread(
                    unit=unit,
                    median=float(np.median(v)) if v.size else None,
                    p90=float(np.percentile(v, 90)) if v.size else None,
                    max=float(v.max()) if v.size else None,
                )
            finished = sum(r.status not in UNFINISHED for r in members)
            groups.append(SpreadGroup(name, len(ok), finished, len(members), axes))
        finished = sum(g.finished for g in groups)
        total = sum(g.of for g in groups)
        out.append(MonteCarloSpread(sname, samples[sname], finished, total - finished, groups))
    return out


def _num(v: Any, digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}g}"


def print_report(report: Report, file=None) -> None:
    """The human summary: a line per variant, the stability table, counts, paths."""
    file = sys.stdout if file is None else file
    header = (
        f"{'variant':<34} {'status':<11} {'stable':<6} {'roll ss':>9} {'pitch ss':>9} "
        f"{'heave ss':>9} {'growth':>7} {'rt x':>6}"
    )
    last = None
    for r in report.rows:
        if r.scenario != last:
            print(f"\n{r.scenario}  ({r.file})", file=file)
            print(header + "\n" + "-" * len(header), file=file)
            last = r.scenario
        stable = "-" if r.stable is None else ("yes" if r.stable else "NO")
        differ = verdict_note(r) is not None
        stable += "*" if differ else ""
        print(
            f"{r.variant:<34} {r.status:<11} {stable:<6} "
            f"{_num(r.roll.ss_err, 3):>9} {_num(r.pitch.ss_err, 3):>9} "
            f"{_num(r.heave.ss_err, 3):>9} {_num(r.growth_rate_1_s, 2):>7} "
            f"{_num(r.realtime_factor, 3):>6}",
            file=file,
        )
        if r.status != "ok" and r.reason:
            print(f"    {r.status}: {r.reason}", file=file)
        if differ:
            print(
                "    * small-signal stable (the error envelope does not grow), "
                f"large-signal {r.status}",
                file=file,
            )
        if r.cue.get("cue_floors_met") is not None:
            floors = "met" if r.cue["cue_floors_met"] else "missed: " + r.cue["cue_floors_missed"]
            print(f"    cue floors {floors}", file=file)
    print(
        "(ss: steady-state error, deg, deg, mm; growth: error envelope, 1/s; "
        "rt x: realtime factor; stable: the error envelope does not grow (small signal), "
        "status: the verdict on the final window (large signal); a cueing run's stability "
        "is judged by the cue floors)",
        file=file,
    )
    for m in report.monte_carlo:
        unfinished = f"; {m.unfinished} not finished, not counted" if m.unfinished else ""
        print(
            f"\nMonte Carlo {m.scenario}, |steady-state error| of the ok variants "
            f"(n: ok of the finished; {m.samples} samples drawn{unfinished}) "
            "(median / 90th percentile / max):",
            file=file,
        )
        for g in m.groups:
            cells = []
            for axis, unit, _ in AXES:
                st = g.axes[axis]
                cells.append(
                    f"{axis} {_num(st.median, 3)} / {_num(st.p90, 3)} / {_num(st.max, 3)} {unit}"
                )
            n = f"{g.n}/{g.finished}"
            print(f"  {g.group:<24} n={n:<7} " + "; ".join(cells), file=file)
    for table in report.robustness:
        print("\n".join(table_lines(table)), file=file)
    if report.stability:
        print(
            "\nstability limit, K K_I (1/s): stable/unstable by the error envelope's growth "
            "(small signal, what the analysis predicts), settled/unsettled by the verdict:",
            file=file,
        )
        print(
            f"{'scenario':<20} {'group':<26} {'analytic':>9} {'delay mdl':>9} "
            f"{'stable <=':>9} {'unstable >=':>11} {'simulated':>9} {'sim/ana':>7} "
            f"{'settled <=':>10} {'unsettled >=':>12}",
            file=file,
        )
        for s in report.stability:
            group = ",".join(f"{k.split('.')[-1]}={v}" for k, v in s.group.items()) or "-"
            print(
                f"{s.scenario:<20} {group:<26} {_num(s.analytic_limit):>9} "
                f"{_num(s.analytic_limit_delay_model):>9} {_num(s.largest_stable):>9} "
                f"{_num(s.smallest_unstable):>11} {_num(s.simulated_limit):>9} "
                f"{_num(s.simulated_over_analytic, 3):>7} "
                f"{_num(s.largest_settled):>10} {_num(s.smallest_unsettled):>12}",
                file=file,
            )
            if s.note:
                print(f"    note: {s.note}", file=file)
    for text, count in report.notices.items():
        print(f"\n{text} ({count} variant{'s' if count != 1 else ''})", file=file)
    c = report.counts
    counts = ", ".join(f"{k} {v}" for k, v in c.items() if v)
    extra = f", {report.skipped} skipped (complete)" if report.skipped else ""
    print(f"\n{len(report.rows)} variants: {counts}{extra}; {report.wall_s:.1f} s", file=file)
    print(f"summary: {report.out / 'summary.csv'}", file=file)
    for pth in report.plots:
        print(f"plot: {pth}", file=file)
