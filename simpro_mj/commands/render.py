"""``simpro-sim render RESULT_DIR``: an MP4 replay of recorded runs.

The motion comes from the folder's ``qpos.npz`` (no re-simulation); a
``compare`` folder's runs are drawn side by side. See :mod:`simpro_mj.report.render`;
the options are :mod:`simpro_mj.report.video_options` (shared with ``run/compare --video``).
"""

from __future__ import annotations

from pathlib import Path

from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.progress import show_progress
from simpro_mj.report.folders import locked
from simpro_mj.report.recording import find_runs
from simpro_mj.report.render import render_video
from simpro_mj.report.single_files import record_file
from simpro_mj.report.video_options import add_video_options, video_options

HELP = "render a result folder (or each run of a compare folder, side by side) to MP4"
#: the recorded runs' scenarios are replayed as they ran: nothing to override
COMMON_OPTIONS = ("json", "quiet")


def add_arguments(parser) -> None:
    parser.add_argument("result_dir", metavar="RESULT_DIR", help="a run or compare result folder")
    add_video_options(parser, out=True)


def run(args) -> int:
    folder = Path(args.result_dir)
    find_runs(folder)  # a folder that is no result: refused before it is locked
    # the folder's write lock while it is read: a run replacing it meanwhile is refused
    with locked(folder):
        runs = find_runs(folder)
        opts = video_options(args, folder / "replay.mp4")
        out = opts.pop("out")
        # SIGTERM as Ctrl-C (commands.main): exit 130, no partial video left
        info = render_video(runs, out, progress=show_progress(args), **opts)
        record_file(out)  # listed in its folder's marker: a re-render may replace it
    if args.json:
        emit_json(info)
    else:
        print(info.said())
    return 0
