"""``simpro-sim run SCENARIO``: one co-simulation, results written to a folder."""

from __future__ import annotations

from pathlib import Path

HELP = "run a scenario (shipped name or YAML path) and write time series, metrics and plots"


def add_arguments(parser) -> None:
    parser.add_argument("scenario", help="shipped scenario name (e.g. step_pitch.yaml) or a path")
    parser.add_argument("--out", default=None, help="result folder (default results/<name>)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")


def execute(scenario: dict, out: Path, plots: bool = True):
    """Run a resolved scenario and write its result folder.

    Returns ``(result, document)`` where ``document`` is what ``metrics.json``
    holds, so ``--json`` prints exactly the file's content.
    """
    import json

    from .metrics import compute_metrics
    from .results import write_results
    from .sim import simulate

    res = simulate(scenario)
    metrics = compute_metrics(res.columns, scenario)
    metrics["status"] = res.status
    metrics["reason"] = res.reason
    metrics["sensor_floor"] = res.sensor_floor
    write_results(out, res.columns, metrics, scenario, {"sim": res.sim, "plots": plots})
    return res, json.loads((out / "metrics.json").read_text(encoding="utf-8"))


def run(args) -> int:
    from .results import print_summary
    from .scenario import load_scenario

    scenario = load_scenario(args.scenario, args.sets)
    out = Path(args.out) if args.out else Path("results") / scenario["name"]
    res, metrics = execute(scenario, out, plots=not args.no_plots)
    if args.json:
        from .cli import emit_json

        emit_json(metrics)
    else:
        print_summary(metrics, out)
        if res.status != "ok":
            print(f"DIVERGED: {res.reason}")
    return 0 if res.status == "ok" else 1
