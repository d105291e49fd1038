"""``simpro-sim validate-ik``: the paper's Fig. 11 with MuJoCo in place of ADAMS.

The validation is :mod:`simpro_mj.analysis.validate_ik`."""

from __future__ import annotations

from pathlib import Path

from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.progress import Phases, show_progress
from simpro_mj.report.folders import claim, install_figures

HELP = "validate the vector-loop IK against the MuJoCo closed chain (paper Fig. 11)"


def add_arguments(parser) -> None:
    parser.add_argument("--out", default="results/validate-ik", help="folder for the plot")
    parser.add_argument("--no-plots", action="store_true", help="skip the plot")


def run(args) -> int:
    # the validation loads MuJoCo: after argparse has checked the options
    from simpro_mj.analysis.validate_ik import IkParams, plot, summary, validate
    from simpro_mj.config.messages import from_sets

    p = from_sets(IkParams, args.sets)
    with Phases("validate-ik", ["IK against MuJoCo", "plot"], show_progress(args)) as phase:
        phase.start("IK against MuJoCo")
        if args.no_plots:
            res, plot_path = validate(p), None
        else:  # --out checked before the validation; the figure installed as one folder
            with claim(Path(args.out), "validate-ik") as out:
                res = validate(p)
                phase.start("plot")
                (plot_path,) = install_figures(out, lambda tmp: [plot(res, tmp)], "validate-ik")
    doc = {**res.to_json(), "plot": str(plot_path) if plot_path else None}
    if args.json:
        emit_json(doc)
    else:
        print(summary(res))
        if plot_path:
            print(f"  plot: {plot_path}")
    return 0
