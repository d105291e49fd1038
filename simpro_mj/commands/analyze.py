"""``simpro-sim analyze``: stability analysis of the joint and task-space loops.

The numbers and plots are :mod:`simpro_mj.analysis.analyze`; parameters by
``--set KEY=VALUE`` (see :data:`simpro_mj.analysis.analyze.DEFAULTS`)."""

from __future__ import annotations

import os
from pathlib import Path

from simpro_mj.analysis.analyze import DEFAULTS, compute, document
from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.keys import apply_overrides
from simpro_mj.core.progress import Phases, show_progress
from simpro_mj.report.analyze import plot, summary
from simpro_mj.report.folders import claim, install_figures

HELP = "stability analysis of the joint and task-space loops (root loci, Jury limits)"


def add_arguments(parser) -> None:
    parser.add_argument(
        "--out",
        default=os.path.join("results", "analyze"),
        help="directory for the plots (default results/analyze)",
    )
    parser.add_argument("--no-plots", action="store_true", help="compute only, write no files")


def run(args) -> int:
    p = apply_overrides(DEFAULTS, args.sets)
    with Phases("analyze", ["loops and limits", "plots"], show_progress(args)) as phase:
        phase.start("loops and limits")
        if args.no_plots:
            res, files = compute(p), []
        else:  # --out checked before the analysis; its figures installed as one folder
            with claim(Path(args.out), "analyze") as out:
                res = compute(p)
                phase.start("plots")
                figures = install_figures(out, lambda tmp: plot(res, p, tmp), "analyze")
                files = [str(f) for f in figures]
    if args.json:
        emit_json(document(res, p, files))
    else:
        print(summary(res, files))
    return 0
