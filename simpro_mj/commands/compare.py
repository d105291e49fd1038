"""``simpro-sim compare SCENARIO``: joint-only vs task-space control (paper Fig. 15 a/b)."""

from __future__ import annotations

import copy
import sys
from pathlib import Path

HELP = "run a scenario with joint-only and with task-space control on the same plant and seed"


def add_arguments(parser) -> None:
    parser.add_argument("scenario", help="shipped scenario name or a path")
    parser.add_argument(
        "--out", default=None, help="result folder (default results/<name>-compare)"
    )
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    from simpro_mj.commands.render import add_video_flag

    add_video_flag(parser)


def compare(scenario: dict, out: Path, plots: bool = True, *, quiet: bool = False) -> dict:
    """Run both modes into ``out/joint_only`` and ``out/task_space``; returns both metrics.

    The preflight checks (:mod:`simpro_mj.analysis.preflight`) run once, before either
    run, on the task-space variant (the one with an outer loop); their
    warnings are printed once unless ``quiet`` and recorded in both folders.
    An interrupted run stops the comparison (``results`` then holds fewer
    than two modes).
    """
    from simpro_mj.analysis.preflight import preflight
    from simpro_mj.report.runner import execute, warn

    task = copy.deepcopy(scenario)
    task["controller"]["mode"] = "task_space"
    warnings, _ = preflight(task)  # raises for a payload the cylinders cannot hold
    warn(warnings, quiet)
    results, metrics = {}, {}
    for mode in ("joint_only", "task_space"):
        sc = copy.deepcopy(scenario)
        sc["controller"]["mode"] = mode
        res, met = execute(sc, out / mode, plots=plots, quiet=True)
        results[mode], metrics[mode] = res, met
        if res.status == "interrupted":
            return {"metrics": metrics, "results": results}
    if plots:
        from simpro_mj.report.plots import plot_compare

        plot_compare(results["joint_only"].columns, results["task_space"].columns, scenario, out)
    return {"metrics": metrics, "results": results}


def _table(metrics: dict) -> str:
    rows = ["axis   metric                 joint_only    task_space"]
    units = {
        "roll": ("deg", 57.29577951308232),
        "pitch": ("deg", 57.29577951308232),
        "heave": ("mm", 1e3),
    }
    for axis, (unit, scale) in units.items():
        for key, label, s in (
            ("steady_state_error", f"ss error [{unit}]", scale),
            ("rise_time_s", "rise time [s]", 1.0),
            ("settling_time_s", "settling [s]", 1.0),
            ("overshoot_pct", "overshoot [%]", 1.0),
        ):
            vals = []
            for mode in ("joint_only", "task_space"):
                v = metrics[mode]["axes"][axis].get(key)
                vals.append("-" if v is None else f"{v * s:.4g}")
            rows.append(f"{axis:6s} {label:22s} {vals[0]:>10s}    {vals[1]:>10s}")
    return "\n".join(rows)


def run(args) -> int:
    import json

    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.report.results import claim, write_marker
    from simpro_mj.report.runner import EXIT_INTERRUPTED, interrupted_message, sigterm_as_interrupt

    scenario = load_scenario(args.scenario, args.sets)
    if args.video:
        from simpro_mj.report.render import require_video

        require_video()  # the install hint before the run, not after it
    out = Path(args.out) if args.out else Path("results") / f"{scenario['name']}-compare"
    with claim(out, "compare", inputs=[args.scenario]), sigterm_as_interrupt():
        out.mkdir(parents=True, exist_ok=True)
        write_marker(out, "compare")
        both = compare(scenario, out, plots=not args.no_plots)
    metrics = both["metrics"]
    for mode, res in both["results"].items():
        if res.status == "interrupted":
            msg = interrupted_message(res, out / mode)
            sys.stderr.write(f"error: {mode}: {msg}; no comparison written\n")
            return EXIT_INTERRUPTED
    table = _table(metrics)
    (out / "comparison.txt").write_text(table + "\n")
    (out / "comparison.json").write_text(json.dumps(metrics, indent=2, default=float))
    if args.json:
        from simpro_mj.core.jsonout import emit_json

        emit_json(metrics)
    else:
        print(table)
        for mode, met in metrics.items():
            if met["status"] != "ok":
                print(f"{mode} DIVERGED: {met['reason']}")
        print(f"results: {out}")
    if args.video:  # both runs side by side
        from simpro_mj.commands.render import video_after_run

        video_after_run(out, quiet=args.json)
    return 0 if all(m["status"] == "ok" for m in metrics.values()) else 1
