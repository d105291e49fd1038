"""``simpro-sim batch PATH...``: many runs, sweeps, Monte Carlo, in parallel.

The batch itself (plan, workers, stability, summary) is :mod:`simpro_mj.batch`
(:func:`simpro_mj.batch.runner.run_batch`; its module docstring is the contract).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from simpro_mj.batch.plan import scenario_files
from simpro_mj.batch.runner import PLOTS, TIMESERIES, run_batch
from simpro_mj.batch.tables import print_report
from simpro_mj.config.scenario import read_document, resolve_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.keys import short_text
from simpro_mj.report.folders import folder_name
from simpro_mj.report.runner import EXIT_INTERRUPTED
from simpro_mj.sim.executors import MAX_JOBS

HELP = "run scenario files, sweeps and Monte Carlo variants in parallel; write summary.csv"


def add_arguments(parser) -> None:
    parser.add_argument(
        "paths", nargs="+", metavar="PATH", help="scenario files, shipped names or folders"
    )
    parser.add_argument(
        "--out",
        default=None,
        help="output folder (default results/batch-<file stem>, one per sweep file)",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=None,
        metavar="N",
        help="variants at once, in worker processes (default: the number of CPUs; "
        "1: one after another in this process)",
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--processes",
        action="store_true",
        help="run the --jobs variants in worker processes (the default)",
    )
    where.add_argument(
        "--threads",
        action="store_true",
        help="run the --jobs variants on threads of this process instead of processes",
    )
    parser.add_argument(
        "--resume", action="store_true", help="skip variants whose result folder is complete"
    )
    parser.add_argument(
        "--strict",
        action="store_true",
        help="refuse the whole batch if any file or variant is invalid (exit 2)",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a Dask distributed scheduler at ADDRESS, or 'local' for a LocalCluster",
    )
    parser.add_argument(
        "--plots",
        choices=PLOTS,
        default="examples",
        help="whose run figures to draw: each file's first variant (examples, the default), "
        "also every variant not ok (failing), every variant (all) or none; the batch's own "
        "figures are always drawn",
    )
    parser.add_argument(
        "--no-plots",
        action="store_const",
        const="none",
        dest="plots",
        help="no variant's figures (--plots none; the batch's own figures stay)",
    )
    parser.add_argument(
        "--timeseries",
        choices=TIMESERIES,
        default="all",
        help="whose timeseries.csv to write: every variant's (all, the default), only those "
        "not ok (failing) or none; a folder without it is complete, its row the same",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def default_batch_out(paths) -> Path:
    """``results/batch-<stem>``: a folder per sweep file (stems joined by ``+``), so a
    second sweep never fills the first one's folder."""
    stem = "+".join(Path(p).name.removesuffix(".yaml").removesuffix(".yml") for p in paths)
    return Path("results") / folder_name(f"batch-{stem}")


def check_sets(paths, sets) -> None:
    """A ``--set`` that a file's base scenario refuses is the command line's mistake: one
    line, exit 2, before anything runs (not one ``invalid`` row per variant)."""
    if not sets:
        return
    for path, error in scenario_files(paths):
        if error is not None:
            continue
        try:
            where, doc = read_document(path)
            doc = {k: v for k, v in doc.items() if k != "sweep"}  # the base of its variants
            resolve_scenario(doc, (), default_name=where.stem, base=where.parent)
        except UserInputError:
            continue  # the file's own mistake: its row says so
        # raises UserInputError naming the field
        resolve_scenario(doc, sets, default_name=where.stem, base=where.parent)


def run(args) -> int:
    jobs = args.jobs if args.jobs is not None else (os.cpu_count() or 1)
    if not 1 <= jobs <= MAX_JOBS:
        raise UserInputError(
            f"invalid value at --jobs: {short_text(str(jobs))}; allowed: an integer 1..{MAX_JOBS}"
        )
    check_sets(args.paths, args.sets)
    report = run_batch(
        args.paths,
        Path(args.out) if args.out else default_batch_out(args.paths),
        sets=args.sets,
        jobs=jobs,
        resume=args.resume,
        strict=args.strict,
        scheduler=args.scheduler,
        plots=args.plots,
        progress=not args.quiet and not args.json,
        processes=not args.threads,
        timeseries=args.timeseries,
    )
    if args.json:
        emit_json(report.document())
    else:
        print_report(report)
    if report.stopped is not None:
        c = report.counts
        finished = len(report.rows) - c["cancelled"] - c["invalid"]
        sys.stderr.write(
            f"error: batch stopped: {report.stopped}; {finished} variant(s) finished, "
            f"{c['cancelled']} cancelled; summary in {report.out / 'summary.csv'}\n"
        )
        return EXIT_INTERRUPTED if report.stopped.startswith("interrupted") else 1
    return 0 if report.all_ok else 1
