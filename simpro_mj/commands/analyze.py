"""``simpro-sim analyze``: stability analysis of the joint and task-space loops.

The numbers and plots are :mod:`simpro_mj.analysis.analyze`; parameters by
``--set KEY=VALUE`` (:class:`simpro_mj.analysis.analyze.AnalyzeParams`)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from simpro_mj.analysis.analyze import AnalyzeParams, compute, document
from simpro_mj.config.messages import from_sets
from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.progress import Phases, show_progress
from simpro_mj.report.analyze import plot, summary
from simpro_mj.report.folders import claim, install_figures

HELP = "stability analysis of the joint and task-space loops (root loci, Jury limits)"


def add_arguments(parser) -> None:
    parser.add_argument(
        "scenario",
        nargs="?",
        default="step_pitch.yaml",
        help="the scenario whose shipped loop is analysed first (default step_pitch.yaml); "
        "--set keys outside the analysis' own (outer, inner, feedforward, sweep) are the "
        "scenario's",
    )
    parser.add_argument(
        "--out",
        default=os.path.join("results", "analyze"),
        help="directory for the plots (default results/analyze)",
    )
    parser.add_argument("--no-plots", action="store_true", help="compute only, write no files")


def _split_sets(sets) -> tuple[list, list]:
    """``--set`` expressions for the analysis' tree (its top-level keys) and the scenario's;
    ``paper_units`` is both's."""
    own, scenario = [], []
    for expr in sets or ():
        top = expr.split("=", 1)[0].split(".", 1)[0].strip()
        if top in AnalyzeParams.model_fields:
            own.append(expr)
        if top not in AnalyzeParams.model_fields or top == "paper_units":
            scenario.append(expr)
    return own, scenario


def _say(line: str) -> None:
    sys.stderr.write(line + "\n")


def _scenario(name: str, sets: list, say) -> dict:
    """The resolved scenario with its design plants (identified when it asks)."""
    from simpro_mj.config.models import as_tree
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.identification.auto import with_identified

    return dict(as_tree(with_identified(load_scenario(name, sets), say)[0]))


def run(args) -> int:
    own, scenario_sets = _split_sets(args.sets)
    p = from_sets(AnalyzeParams, own)
    with Phases("analyze", ["loops and limits", "plots"], show_progress(args)) as phase:
        sc = _scenario(args.scenario, scenario_sets, None if args.quiet else _say)
        phase.start("loops and limits")
        if args.no_plots:
            res, files = compute(p, sc), []
        else:  # --out checked before the analysis; its figures installed as one folder
            with claim(Path(args.out), "analyze") as out:
                res = compute(p, sc)
                phase.start("plots")
                figures = install_figures(out, lambda tmp: plot(res, p, tmp), "analyze")
                files = [str(f) for f in figures]
    if args.json:
        emit_json(document(res, p, files))
    else:
        print(summary(res, files))
    return 0
