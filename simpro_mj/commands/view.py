"""``simpro-sim view SCENARIO|RESULT_DIR``: MuJoCo's interactive viewer.

A result folder is replayed from its ``qpos.npz``; a scenario is simulated
first, in memory, then played the same way (:mod:`simpro_mj.report.viewer`).
Playback is paced to the wall clock (``--speed``), with the set-point ghost
and a text overlay. The window stays open on the last frame until it is closed.

The viewer needs a display: without one (no ``DISPLAY``/``WAYLAND_DISPLAY``,
or GLFW cannot start) the command stops with one line suggesting
``simpro-sim render``, before opening anything.
"""

from __future__ import annotations

from simpro_mj.core.errors import UserInputError
from simpro_mj.report.video_options import number

HELP = "watch a scenario or a result folder in MuJoCo's interactive viewer (needs a display)"


def add_arguments(parser) -> None:
    parser.add_argument("target", metavar="SCENARIO|RESULT_DIR", help="a scenario or a run folder")
    parser.add_argument("--speed", default="1", help="playback speed, < 1 is slow motion")
    parser.add_argument("--start", default="0", help="first simulated second shown (default 0)")
    parser.add_argument("--no-ghost", action="store_true", help="no set-point ghost")


def run(args) -> int:
    # the job's modules on use: --help and argparse's refusals import none of them
    from simpro_mj.report.scene import replay_model
    from simpro_mj.report.viewer import check_display, play, recording_for

    speed = number(args.speed, "--speed", 0.0, 100.0)
    start = number(args.start, "--start", 0.0, 1e9, lo_open=False)
    check_display()
    rec = recording_for(args.target, args.sets)
    if start >= rec.duration_s:
        raise UserInputError(
            f"invalid value at --start: {start:g}; allowed: 0 <= start < {rec.duration_s:g} s"
        )
    # MuJoCo's viewer (and MuJoCo) only once the display and the input are known good
    import mujoco.viewer

    model, data = replay_model(rec.scenario)
    handle = mujoco.viewer.launch_passive(model, data)
    with handle:
        play(handle, model, data, rec, speed=speed, start=start, ghost=not args.no_ghost)
    return 0
