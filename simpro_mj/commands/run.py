"""``simpro-sim run SCENARIO``: one co-simulation, results written to a folder.

Before stepping, :func:`simpro_mj.analysis.preflight.preflight` refuses a payload the
cylinders cannot hold (exit 2) and warns about outer gains above the analysed
stability limit. Warnings go to stderr as ``warning: ...`` lines and into
``metrics.json`` (``warnings``, figures under ``preflight``).

Exit codes: 0 ok, 1 diverged, limit_cycle or not_settled (the pose still
oscillates or drifts at the end, :mod:`simpro_mj.analysis.verdict`), 2 a
user's mistake, 130 interrupted (Ctrl-C or SIGTERM: the partial result is
written with status ``interrupted`` and a ``PARTIAL`` file when the
simulation hands it back, see docs/robustness.md).
With ``SIMPRO_READY_FILE`` set, the file is written once the simulation has
taken its first step under the signal handlers (:mod:`simpro_mj.sim.readiness`).
The job itself is :func:`simpro_mj.report.runner.execute`.
"""

from __future__ import annotations

import sys
from pathlib import Path

from simpro_mj.report.video_options import add_video_flag

HELP = "run a scenario (shipped name or YAML path) and write time series, metrics and plots"


def add_arguments(parser) -> None:
    parser.add_argument("scenario", help="shipped scenario name (e.g. step_pitch.yaml) or a path")
    parser.add_argument(
        "--out",
        default=None,
        help="result folder (default results/<name>, +<each --set>, -2, -3... past another "
        "run's result)",
    )
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_video_flag(parser)


def run(args) -> int:
    # the job's modules on use: --help and argparse's refusals import none of them
    from simpro_mj.analysis.verdict import FINISHED_STATUSES
    from simpro_mj.config.scenario import scenario_hash
    from simpro_mj.core.jsonout import emit_json
    from simpro_mj.core.progress import show_progress
    from simpro_mj.report.folders import claim, default_out, said_replacing
    from simpro_mj.report.results import print_summary
    from simpro_mj.report.runner import EXIT_INTERRUPTED, execute, interrupted_message
    from simpro_mj.report.video_options import scenario_to_run, video_after_run

    scenario = scenario_to_run(args)
    digest = scenario_hash(scenario)
    base = Path("results") / scenario.name
    out = Path(args.out) if args.out else default_out(base, args.sets or (), digest)
    # refused (exit 2) before anything runs: not ours to replace, or busy
    with claim(out, "run", inputs=[args.scenario]):
        said_replacing(out, digest)
        res, metrics = execute(
            scenario,
            out,
            plots=not args.no_plots,
            quiet=args.quiet,
            progress=show_progress(args),
        )
    if args.json:
        emit_json(metrics)
    else:
        print_summary(metrics, res.folder)
        if res.status != "ok" and res.status in FINISHED_STATUSES:
            print(f"{res.status.upper().replace('_', ' ')}: {res.reason}")
    if res.status == "interrupted":
        sys.stderr.write(f"error: {interrupted_message(res, out)}\n")
        return EXIT_INTERRUPTED
    if args.video:  # a diverged run too: its motion up to the divergence
        video_after_run(res.folder, quiet=args.json)
    return 0 if res.status == "ok" else 1
