"""``simpro-sim identify``: the paper's actuator identification (Fig. 12) in simulation.

The experiment and the fit are :mod:`simpro_mj.identification.identify`."""

from __future__ import annotations

import json
from pathlib import Path

from simpro_mj.analysis.sanity import fit_warnings
from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.keys import apply_overrides
from simpro_mj.core.progress import Phases, show_progress
from simpro_mj.report.folders import claim, install_figures

HELP = "identify eq. (19) per actuator in simulation (Fig. 12: P loop + PRBS, least squares)"


def add_arguments(parser) -> None:
    parser.add_argument(
        "--out", default="results/identify", help="output directory (default results/identify)"
    )
    parser.add_argument(
        "--duration", type=float, default=None, help="excitation time per actuator, s (20)"
    )
    parser.add_argument(
        "--actuators",
        type=int,
        nargs="+",
        choices=(1, 2, 3),
        default=[1, 2, 3],
        help="which actuators (default 1 2 3)",
    )
    parser.add_argument("--no-plots", action="store_true", help="do not write the figure")
    parser.add_argument(
        "--preset",
        default=None,
        help="plant preset: a shipped name (paper, heavy_cabin) or a preset YAML path",
    )


def run(args) -> int:
    from simpro_mj.identification.settings import check_tree, default_tree

    tree = apply_overrides(default_tree(args.preset), args.sets)
    if args.duration is not None:
        tree["identify"]["duration_s"] = float(args.duration)
    ex = check_tree(tree)
    # the experiment loads MuJoCo and SciPy: after every input has been checked
    from simpro_mj.identification.identify import document, identify
    from simpro_mj.job.run import warn
    from simpro_mj.report.identify import plot, summary

    records: dict = {}
    legs = sorted(set(args.actuators))
    # --out checked before the experiment; its files installed as one folder
    with (
        Phases("identify", ["PRBS experiment and fit", "plot"], show_progress(args)) as phase,
        claim(Path(args.out), "identify") as out,
    ):
        phase.start("PRBS experiment and fit")
        results = identify(ex, legs=legs, records=records)
        doc = document(results, ex)
        doc["warnings"] = warnings = fit_warnings(doc["actuators"])

        def fill(tmp: Path) -> list:
            (tmp / "identify.json").write_text(json.dumps(doc, indent=2))
            if not args.no_plots:
                phase.start("plot")
                plot(results, records, tmp / "identify.png", ex.paper_units)
            return []

        install_figures(out, fill, "identify")
    warn(warnings, args.quiet or args.json)
    if args.json:
        emit_json(doc)
    else:
        print(summary(results, ex.paper_units, str(ex.preset)))
        print(
            f"wrote {out / 'identify.json'}"
            + ("" if args.no_plots else f", {out / 'identify.png'}")
        )
    return 0
