"""``simpro-sim compare SCENARIO``: joint-only vs task-space control (paper Fig. 15 a/b).

The job is :func:`simpro_mj.report.compare.compare`."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from simpro_mj.report.video_options import add_video_flag

HELP = "run a scenario with joint-only and with task-space control on the same plant and seed"


#: What a compare writes into ``--out``: both runs' folders, the table, the figure.
COMPARE_FILES = (
    "joint_only", "task_space", "comparison.txt", "comparison.json", "compare.png", "replay.mp4"
)  # fmt: skip


def add_arguments(parser) -> None:
    parser.add_argument("scenario", help="shipped scenario name or a path")
    parser.add_argument(
        "--out", default=None, help="result folder (default results/<name>-compare)"
    )
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_video_flag(parser)


def run(args) -> int:
    # the job's modules on use: --help and argparse's refusals import none of them
    from simpro_mj.core.jsonout import emit_json
    from simpro_mj.core.progress import show_progress
    from simpro_mj.report.compare import compare, table
    from simpro_mj.report.folders import claim
    from simpro_mj.report.marker import record
    from simpro_mj.report.runner import EXIT_INTERRUPTED, interrupted_message
    from simpro_mj.report.video_options import scenario_to_run, video_after_run

    scenario = scenario_to_run(args)
    out = Path(args.out) if args.out else Path("results") / f"{scenario.name}-compare"
    with claim(out, "compare", inputs=[args.scenario], writes=COMPARE_FILES):
        out.mkdir(parents=True, exist_ok=True)
        record(out, COMPARE_FILES, "compare", pending=True)
        both = compare(
            scenario, out, plots=not args.no_plots, quiet=args.quiet, progress=show_progress(args)
        )
    metrics = both["metrics"]
    for mode, res in both["results"].items():
        if res.status == "interrupted":
            msg = interrupted_message(res, out / mode)
            sys.stderr.write(f"error: {mode}: {msg}; no comparison written\n")
            return EXIT_INTERRUPTED
    text = table(metrics)
    (out / "comparison.txt").write_text(text + "\n")
    (out / "comparison.json").write_text(json.dumps(metrics, indent=2, default=float))
    record(out, COMPARE_FILES, "compare")
    if args.json:
        emit_json(metrics)
    else:
        print(text)
        for mode, met in metrics.items():
            if met["status"] != "ok":
                print(f"{mode} {met['status'].upper().replace('_', ' ')}: {met['reason']}")
        print(f"results: {out}")
    if args.video:  # both runs side by side
        video_after_run(out, quiet=args.json)
    return 0 if all(m["status"] == "ok" for m in metrics.values()) else 1
