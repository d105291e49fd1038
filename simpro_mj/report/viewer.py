"""What ``simpro-sim view`` shows in MuJoCo's interactive viewer.

A result folder is replayed from its ``qpos.npz``; a scenario is simulated
first, in memory (a 20 s run takes about a second, far faster than real
time), then played the same way (:func:`recording_for`). Playback is paced to
the wall clock (:func:`play`), with the set-point ghost and a text overlay of
the time, the pose against its set-point and the valve voltages
(:func:`overlay`). The viewer needs a display: :func:`check_display` says so
in one line, before anything is opened (``launch_passive`` would otherwise
wait for a window that never comes).
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.messages import one_line
from simpro_mj.report.recording import (
    find_runs,
    ghost_poses,
    load_recording,
    nearest_rows,
    recording_of,
)
from simpro_mj.report.scene import pose_data


def check_display() -> None:
    """Raise :class:`UserInputError` (one line) when no window can be opened."""
    hint = "render a video instead: simpro-sim render RESULT_DIR (or run/compare --video)"
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        raise UserInputError(f"no display for the viewer (DISPLAY is not set); {hint}")
    try:
        import glfw  # MuJoCo's windowing library, loaded only to open a window

        ok = glfw.init()
    except Exception as exc:  # noqa: BLE001 - any GLFW failure means no window
        ok, why = False, one_line(exc)
    else:
        why = "glfw.init() failed"
    if not ok:
        raise UserInputError(f"no display for the viewer ({why}); {hint}")


def overlay(rec, row: int) -> str:
    """Overlay text at a logged row: time, pose vs set-point, valve voltages."""
    c = rec.columns
    deg = 180.0 / math.pi
    return (
        f"t {c['time_s'][row]:7.3f} s\n"
        f"roll  {c['roll_rad'][row] * deg:+7.3f} deg (set {c['roll_ref_rad'][row] * deg:+.3f})\n"
        f"pitch {c['pitch_rad'][row] * deg:+7.3f} deg (set {c['pitch_ref_rad'][row] * deg:+.3f})\n"
        f"heave {c['heave_m'][row] * 1e3:8.2f} mm (set {c['heave_ref_m'][row] * 1e3:.2f})\n"
        f"valves {c['u1_v'][row]:+.2f} {c['u2_v'][row]:+.2f} {c['u3_v'][row]:+.2f} V"
    )


def play(handle, model, data, rec, *, speed=1.0, start=0.0, ghost=True, clock=time.monotonic,
         sleep=time.sleep, hold=True) -> int:  # fmt: skip
    """Play a recording in a viewer handle, paced by ``clock``; returns the frames shown.

    ``handle`` is a :func:`mujoco.viewer.launch_passive` handle (or anything
    with ``is_running``, ``lock``, ``sync`` and ``set_texts``). Each frame
    shows the logged row nearest to ``start + speed * (clock() - t0)``.
    With ``hold`` the last frame stays until the window is closed.
    """
    t_end = rec.duration_s
    if not ghost:
        with handle.lock():
            handle.opt.geomgroup[1] = 0  # the ghost's group (models/simpro_platform.xml)
    t0 = clock()
    frames = 0
    row = -1
    while handle.is_running():
        t = min(start + speed * (clock() - t0), t_end)
        new = int(nearest_rows(rec.time_s, np.array([t]))[0])
        if new != row:
            row = new
            gp = gq = None
            if ghost:
                gp, gq = ghost_poses(rec.columns, np.array([row]))
                gp, gq = gp[0], gq[0]
            with handle.lock():
                pose_data(model, data, rec.qpos[row], gp, gq)
                data.time = float(rec.time_s[row])
            handle.set_texts((None, None, overlay(rec, row), None))
            handle.sync()
            frames += 1
        if t >= t_end and not hold:
            break
        sleep(1.0 / 60.0)
    return frames


def recording_for(target: str, sets):
    """The recording of a result folder, or of a scenario simulated here, in memory."""
    path = Path(target)
    if path.is_dir():
        runs = find_runs(path)
        if len(runs) > 1:
            names = ", ".join(str(r) for r in runs)
            raise UserInputError(
                f"several runs at SCENARIO|RESULT_DIR: {path}; allowed: one of {names}"
            )
        return load_recording(runs[0])
    scenario = load_scenario(target, sets)
    # the loop (and MuJoCo) is loaded only when a scenario is to be simulated
    from simpro_mj.sim.build import simulate

    result = simulate(scenario)
    if result.status != "ok":
        sys.stderr.write(f"warning: the run {result.status}: {result.reason}; showing it\n")
    if result.qpos is None or not len(result.qpos):
        raise UserInputError(f"no recorded motion in {target}")
    return recording_of(result)
