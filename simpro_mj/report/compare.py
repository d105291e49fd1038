"""Joint-only vs task-space control on the same plant and seed (paper Fig. 15 a/b).

:func:`compare` runs a scenario in both modes into one folder, :func:`table` is the
comparison ``simpro-sim compare`` prints and writes to ``comparison.txt``.
"""

from __future__ import annotations

import math
from pathlib import Path

from simpro_mj.config.models import Scenario
from simpro_mj.job.run import Run, warn
from simpro_mj.report.runner import execute

#: The two runs of a comparison, in order.
MODES = ("joint_only", "task_space")


def compare(
    scenario: Scenario,
    out: Path,
    plots: bool = True,
    *,
    quiet: bool = False,
    progress: bool = False,
) -> dict:
    """Run both modes into ``out/joint_only`` and ``out/task_space``; returns both metrics.

    The preflight checks (:mod:`simpro_mj.analysis.preflight`) run first, before either
    run, on the task-space variant (the one with an outer loop); their
    warnings are printed once unless ``quiet`` and recorded in both folders.
    The plant is compiled once for the three (the modes differ only in control).
    An interrupted run stops the comparison (``results`` then holds fewer
    than two modes).
    """
    first = Run(_in_mode(scenario, "task_space"))
    warnings, _ = first.preflight()  # raises for a payload the cylinders cannot hold
    warn(warnings, quiet)
    results, metrics = {}, {}
    for mode in MODES:
        res, met = execute(_in_mode(scenario, mode), out / mode, plots=plots, quiet=True,
                           model=first.model, progress=progress, label=mode)  # fmt: skip
        results[mode], metrics[mode] = res, met
        if res.status == "interrupted":
            return {"metrics": metrics, "results": results}
    if plots:
        # matplotlib is loaded only when figures are drawn
        from simpro_mj.report.plots import plot_compare

        both = results["joint_only"].columns, results["task_space"].columns
        plot_compare(*both, scenario.model_dump(), out)
    return {"metrics": metrics, "results": results}


def _in_mode(scenario: Scenario, mode: str) -> Scenario:
    """A copy of ``scenario`` under ``controller.mode`` ``mode`` (a choice that no rule
    across fields reads)."""
    out = scenario.model_copy(deep=True)
    out.controller.mode = mode  # type: ignore[assignment]
    return out


def table(metrics: dict) -> str:
    """The step figures of both modes side by side (deg, mm, s, %)."""
    rows = ["axis   metric                 joint_only    task_space"]
    deg = 180.0 / math.pi
    units = {"roll": ("deg", deg), "pitch": ("deg", deg), "heave": ("mm", 1e3)}
    for axis, (unit, scale) in units.items():
        for key, label, s in (
            ("steady_state_error", f"ss error [{unit}]", scale),
            ("rise_time_s", "rise time [s]", 1.0),
            ("settling_time_s", "settling [s]", 1.0),
            ("overshoot_pct", "overshoot [%]", 1.0),
        ):
            vals = []
            for mode in MODES:
                v = metrics[mode]["axes"][axis].get(key)
                vals.append("-" if v is None else f"{v * s:.4g}")
            rows.append(f"{axis:6s} {label:22s} {vals[0]:>10s}    {vals[1]:>10s}")
    return "\n".join(rows)
