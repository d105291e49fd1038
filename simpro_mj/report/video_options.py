"""The video options shared by ``simpro-sim render`` and ``run/compare --video``.

Checked here, once, for every command that renders (one-line
:class:`~simpro_mj.core.errors.UserInputError` naming the option and the
allowed values); the rendering itself is :func:`simpro_mj.report.render.render_video`.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from simpro_mj.core.errors import UserInputError

if TYPE_CHECKING:
    from simpro_mj.report.render import Rendered

# the renderer (report.render, report.scene: MuJoCo's GL context, imageio) is imported
# by the functions that render, so that a run without --video never loads it

#: Largest video side accepted (pixels).
MAX_SIDE = 4096


def add_video_options(parser, out: bool) -> None:
    """The options shared by ``render`` and ``run/compare --video``."""
    from simpro_mj.report.scene import CAMERAS

    options = [
        ("--fps", "25", "frames per second of the video (default 25)"),
        ("--size", "640x480", "WIDTHxHEIGHT of each 3D view, even numbers (640x480)"),
        ("--speed", "1", "playback speed, < 1 is slow motion (0.25: quarter speed)"),
        ("--camera", CAMERAS[0], f"camera of the model: {', '.join(CAMERAS)}"),
        ("--start", "0", "first simulated second shown (default 0)"),
        ("--end", None, "last simulated second (default: the end)"),
        ("--out", None, "the MP4 to write (default RESULT_DIR/replay.mp4)"),
        ("--overwrite", False, "replace --out even if simpro-sim did not write it (default: "
         "refuse)"),
        ("--no-strip", False, "no plot strip under the 3D view"),
        ("--no-ghost", False, "no set-point ghost"),
        ("--shadows", False, "cast shadows (about 3x slower per frame)"),
        ("--jobs", None, "render worker processes (default: the CPU count)"),
    ]  # fmt: skip
    for flag, default, text in options:
        if out or flag not in ("--out", "--overwrite"):  # a default of False: a flag
            how = {"action": "store_true"} if default is False else {"default": default}
            parser.add_argument(flag, help=text, **how)


def scenario_to_run(args):
    """The scenario of ``args`` (its file said first), the video's needs checked before the
    run, not after it (``run`` and ``compare``)."""
    from simpro_mj.config.scenario import find_scenario, load_scenario

    source = find_scenario(args.scenario)
    scenario = load_scenario(args.scenario, args.sets)
    if not args.json:
        print(f"scenario: {source.resolve()}", flush=True)
    if args.video:
        from simpro_mj.report.render import require_video  # the renderer only for a video

        require_video()
    return scenario


def add_video_flag(parser) -> None:
    """``run/compare --video``: render the result at the end, with render's defaults."""
    parser.add_argument(
        "--video",
        action="store_true",
        help="also render the result to OUT/replay.mp4 (simpro-sim render's defaults; "
        "needs simpro-sim[video]; simpro-sim render OUT for other options)",
    )


def number(value, field: str, lo: float, hi: float, lo_open: bool = True) -> float:
    """``value`` as a float in ``(lo, hi]`` (``[lo, hi]`` unless ``lo_open``), else a
    one-line error naming ``field``."""
    try:
        x = float(str(value))
    except ValueError:
        x = math.nan
    ok = math.isfinite(x) and (x > lo if lo_open else x >= lo) and x <= hi
    if not ok:
        low = f"> {lo:g}" if lo_open else f">= {lo:g}"
        raise UserInputError(
            f"invalid value at {field}: {value!r}; allowed: a number {low} and <= {hi:g}"
        )
    return x


def _size(value) -> tuple[int, int]:
    parts = str(value).lower().split("x")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        w = h = -1
    if len(parts) != 2 or not (16 <= w <= MAX_SIDE and 16 <= h <= MAX_SIDE) or w % 2 or h % 2:
        raise UserInputError(
            f"invalid value at --size: {value!r}; allowed: WIDTHxHEIGHT, even integers "
            f"16..{MAX_SIDE} (H.264 needs even sides), e.g. 640x480"
        )
    return w, h


def _out_path(value, default: Path, overwrite: bool = False) -> Path:
    """The video path, checked writable and ours to write (:func:`check_file`)
    before any rendering."""
    out = Path(value).expanduser() if value else default
    if out.suffix.lower() != ".mp4":
        raise UserInputError(
            f"invalid value at --out: {str(out)!r}; allowed: a file name ending .mp4"
        )
    if out.is_dir():
        raise UserInputError(
            f"invalid value at --out: {out} is a folder; allowed: an .mp4 file path"
        )
    if any(p.exists() and not p.is_dir() for p in out.parents):
        raise UserInputError(
            f"cannot write at --out: {out}: a parent is a file, not a folder; "
            "allowed: a writable .mp4 path"
        )
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserInputError(
            f"cannot write at --out: {out}: {exc.strerror or exc}; allowed: a writable .mp4 path"
        ) from None
    if not os.access(out.parent, os.W_OK | os.X_OK) or (
        out.exists() and not os.access(out, os.W_OK)
    ):
        raise UserInputError(
            f"cannot write at --out: {out}: permission denied; allowed: a writable .mp4 path"
        )
    from simpro_mj.report.single_files import check_file  # on use: not for a --help

    return check_file(out, overwrite)


def video_options(args, default_out: Path) -> dict:
    """Checked keyword arguments of :func:`simpro_mj.report.render.render_video`
    (one-line errors)."""
    from simpro_mj.report.render import require_video
    from simpro_mj.report.scene import CAMERAS

    # lower bounds so that a frame count stays finite: one frame a second, a hundredfold
    # slow motion (1e-320 made the count infinite)
    fps = number(args.fps, "--fps", 1.0, 240.0, lo_open=False)
    size = _size(args.size)
    speed = number(args.speed, "--speed", 0.01, 100.0, lo_open=False)
    if args.camera not in CAMERAS:
        raise UserInputError(
            f"unknown camera at --camera: {args.camera!r}; allowed: {', '.join(CAMERAS)}"
        )
    start = number(args.start, "--start", 0.0, 1e9, lo_open=False)
    end = None if args.end is None else number(args.end, "--end", 0.0, 1e9)
    jobs = None
    if args.jobs is not None:
        jobs = int(number(args.jobs, "--jobs", 0.0, 256.0))
        if jobs != float(args.jobs):
            raise UserInputError(
                f"invalid value at --jobs: {args.jobs!r}; allowed: an integer 1..256"
            )
    out = _out_path(
        getattr(args, "out_video", None) or getattr(args, "out", None),
        default_out,
        bool(getattr(args, "overwrite", False)),
    )
    require_video()  # before anything is rendered: the one-line install hint
    return {
        "out": out,
        "fps": fps,
        "size": size,
        "speed": speed,
        "camera": args.camera,
        "start": start,
        "end": end,
        "plots": not args.no_strip,
        "ghost": not args.no_ghost,
        "shadows": bool(args.shadows),
        "jobs": jobs,
    }


def video_after_run(folder, quiet: bool) -> Rendered:
    """Render a finished run or compare folder to ``folder/replay.mp4``."""
    # on use: none of them is needed for a --help
    from simpro_mj.report.recording import find_runs
    from simpro_mj.report.render import render_video
    from simpro_mj.report.single_files import check_file, record_file

    folder = Path(folder)
    out = check_file(folder / "replay.mp4")
    info = render_video(find_runs(folder), out, progress=not quiet and sys.stderr.isatty())
    record_file(out)
    if not quiet:
        print(info.said())
    return info
