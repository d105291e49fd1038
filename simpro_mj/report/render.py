"""Replaying recorded runs with MuJoCo's offscreen renderer.

A result folder's recorded motion (:mod:`.recording`) is posed and drawn
(:mod:`.scene`: the 3D view and the plot strip) by worker processes and
encoded to H.264 here. Nothing is simulated again, so what is drawn is
exactly what was computed.

Headless OpenGL: MuJoCo picks its backend from ``MUJOCO_GL`` when it is
first imported, so the frames are drawn in worker processes started with
``spawn`` and the variable set: ``egl`` (Mesa's software EGL works without a
GPU), then ``osmesa``; a ``MUJOCO_GL`` set by the user is the only one tried.
When none works the error names the missing library.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import pickle
import signal
import tempfile
import time
import warnings
from collections import deque
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.messages import one_line
from simpro_mj.report.marker import replacing
from simpro_mj.report.recording import frame_times, ghost_poses, load_recording, nearest_rows
from simpro_mj.report.scene import (
    CAMERAS,
    ReplayScene,
    TextStamp,
    draw_cursor,
    label_image,
    plot_strip,
    text_px,
)

#: What the user runs when imageio or its ffmpeg is missing.
VIDEO_HINT = "pip install 'simpro-sim[video]' (imageio and imageio-ffmpeg)"
#: Backends tried in order when ``MUJOCO_GL`` is not set.
GL_BACKENDS = ("egl", "osmesa")
GL_LIBRARIES = {"egl": "libEGL (Debian: libegl1)", "osmesa": "libOSMesa (Debian: libosmesa6)"}
#: Height of the plot strip as a fraction of the 3D view's height.
STRIP_FRACTION = 0.5


def require_video():
    """Import imageio's v3 API with its ffmpeg plugin; one-line error when missing."""
    try:  # the optional extra simpro-sim[video]
        import imageio.v3 as iio
        import imageio_ffmpeg

        imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError) as exc:
        raise UserInputError(
            f"video output needs imageio and imageio-ffmpeg ({one_line(exc)}); "
            f"install them with: {VIDEO_HINT}"
        ) from None
    return iio


def check_joints(rec) -> None:
    """The recording's joints are those of its plant (what the replay poses), else a
    one-line :class:`UserInputError` naming ``qpos.npz``."""
    from simpro_mj.report.scene import replay_model
    from simpro_mj.sim.result import qpos_names

    where = rec.folder / "qpos.npz"
    try:
        model, _ = replay_model(rec.scenario)
    except Exception as exc:  # noqa: BLE001 - a result folder's scenario is an input
        raise UserInputError(
            f"unreadable recording at {rec.folder / 'scenario.yaml'}: its plant does not "
            f"build ({one_line(exc)}); allowed: a folder written by simpro-sim run"
        ) from None
    names = qpos_names(model)
    if tuple(rec.qpos_names) != names:
        raise UserInputError(
            f"unreadable recording at {where}: {len(rec.qpos_names)} joints "
            f"({', '.join(rec.qpos_names[:3])}...), the plant has {len(names)}; allowed: a "
            "folder written by simpro-sim run"
        )


@dataclass
class PanelJob:
    """One run's panel of the video, per frame: what a worker draws (pickled to it)."""

    scenario: dict
    qpos: np.ndarray
    times: np.ndarray
    #: where the strip's cursor stands (0 at the start, 1 at the end)
    frac: np.ndarray
    #: the run's name, when runs stand side by side
    label: np.ndarray | None = None
    #: the set-point's ghost per frame (None: no ghost)
    ghost_pos: np.ndarray | None = None
    ghost_quat: np.ndarray | None = None
    #: the plot strip under the view and its axes' boxes (None: no strip)
    strip: np.ndarray | None = None
    boxes: Any = None


@dataclass
class Rendered:
    """A rendered video: its file, frames and size (all panels, strip included), the
    backend and workers that drew it, and the wall and worker CPU time per frame."""

    out: str
    frames: int
    width: int
    height: int
    fps: float
    camera: str
    shadows: bool
    gl: str
    workers: int
    wall_s: float
    s_per_frame: float
    worker_cpu_s_per_frame: float
    runs: list[str]

    def said(self) -> str:
        """One line about the video."""
        return (
            f"video: {self.out} ({self.frames} frames, {self.width}x{self.height}, "
            f"{self.fps:g} fps, camera {self.camera}; {self.wall_s:.1f} s with "
            f"{self.workers} workers, MUJOCO_GL={self.gl})"
        )


@dataclass
class _Worker:
    """A render worker's state (:func:`_worker_init`): its scenes or why it cannot render."""

    error: str | None = "worker not initialised"
    scenes: list = field(default_factory=list)
    jobs: list[PanelJob] = field(default_factory=list)
    text: Any = None


_WORKER = _Worker()


def _worker_init(
    jobs_file: str, width: int, height: int, camera: str, ghost, shadows, gl: str, parent: int
):
    # Ctrl-C reaches the whole process group: the parent stops the pool and removes
    # the partial video; a worker must not die with a traceback of its own
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    # a parent killed outright (kill -9) ends its workers within a poll (0.5 s)
    from simpro_mj.sim.workers import watch_parent

    watch_parent(parent)
    os.environ["MUJOCO_GL"] = gl  # before MuJoCo is imported in this (spawned) process
    warnings.simplefilter("ignore")  # GLFW/OpenGL warnings: a failure is reported in one line
    _WORKER.error = None
    try:
        with open(jobs_file, "rb") as fh:
            jobs = pickle.load(fh)
        _WORKER.scenes = [
            ReplayScene(job.scenario, width, height, camera, ghost, shadows) for job in jobs
        ]
    except Exception as exc:  # noqa: BLE001 - reported by _probe as the backend's failure
        _WORKER.error = f"{type(exc).__name__}: {one_line(exc)}"
        return
    _WORKER.jobs = jobs
    _WORKER.text = TextStamp(text_px(width, height))


def _probe(_=None):
    """None if this worker can render, else why not."""
    return _WORKER.error


def _render_frames(indices) -> tuple[list[np.ndarray], float]:
    """The frames at ``indices`` and the CPU seconds this worker spent on them."""
    cpu0 = time.process_time()
    frames = []
    for i in indices:
        panels = []
        for scene, job in zip(_WORKER.scenes, _WORKER.jobs, strict=True):
            gp = gq = None
            if job.ghost_pos is not None and job.ghost_quat is not None:  # the set-point's ghost
                gp, gq = job.ghost_pos[i], job.ghost_quat[i]
            scene.pose(job.qpos[i], gp, gq)
            view = scene.render()
            # the simulated time, top right: what the strip's cursor marks
            _WORKER.text.stamp(view, f"t = {job.times[i]:6.2f} s", view.shape[1] - 4, 4)
            label = job.label
            if label is not None:  # runs side by side: which is which
                lh, lw = min(label.shape[0], view.shape[0]), min(label.shape[1], view.shape[1])
                view[:lh, :lw] = label[:lh, :lw]
            if job.strip is not None:
                strip = draw_cursor(job.strip, job.boxes, job.frac[i])
                view = np.concatenate([view, strip], axis=0)
            panels.append(view)
        frames.append(np.concatenate(panels, axis=1) if len(panels) > 1 else panels[0])
    return frames, time.process_time() - cpu0


def _start_pool(jobs_file: str, width, height, camera, ghost, shadows, workers: int):
    """A spawned pool whose workers can all render; tries the GL backends in order."""
    ctx = multiprocessing.get_context("spawn")  # a fresh interpreter: MUJOCO_GL applies
    why = []
    user = os.environ.get("MUJOCO_GL", "").strip().lower()
    for gl in (user,) if user else GL_BACKENDS:
        pool = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=ctx,
            initializer=_worker_init,
            initargs=(jobs_file, width, height, camera, ghost, shadows, gl, os.getpid()),
        )
        try:
            errors = list(pool.map(_probe, range(workers)))
        except BrokenProcessPool as exc:
            errors = [f"worker died: {exc}"]
        err = next((e for e in errors if e), None)
        if err is None:
            return pool, gl
        pool.shutdown(cancel_futures=True)
        lib = GL_LIBRARIES.get(gl, "its OpenGL library")
        why.append(f"MUJOCO_GL={gl} needs {lib}: {err}")
    raise UserInputError(
        "cannot render offscreen: " + "; ".join(why) + "; allowed: a machine with Mesa's EGL "
        "or OSMesa (apt-get install libegl1 libgl1-mesa-dri, or libosmesa6)"
    )


def render_video(
    folders: list,
    out,
    *,
    fps: float = 25.0,
    size: tuple[int, int] = (640, 480),
    speed: float = 1.0,
    camera: str = CAMERAS[0],
    start: float = 0.0,
    end: float | None = None,
    plots: bool = True,
    ghost: bool = True,
    shadows: bool = False,
    jobs: int | None = None,
    progress: bool = True,
) -> Rendered:
    """Render recorded runs side by side into one MP4.

    Parameters
    ----------
    folders : list of path
        Run folders (:func:`find_runs`); more than one are drawn side by side.
    out : path
        The ``.mp4`` to write (written under a temporary name, then renamed).
    fps, size, speed, camera, start, end
        Frames per second of the video, (width, height) of each 3D view, slow
        motion factor (< 1 slower), camera name, replayed window in simulated
        seconds (``end`` None: the shortest run's end).
    plots, ghost, shadows : bool
        Add the plot strip under each view; draw the set-point ghost; cast shadows.
    jobs : int, optional
        Worker processes (default: the CPU count).
    progress : bool
        A tqdm progress bar on stderr.

    Returns
    -------
    Rendered
    """
    require_video()

    width, height = size
    recs = [load_recording(f) for f in folders]
    for rec in recs:
        check_joints(rec)
    t_end = min(r.duration_s for r in recs)
    end = t_end if end is None else end
    if not 0.0 <= start < end <= t_end + 1e-9:
        raise UserInputError(
            f"invalid value at --start/--end: {start:g}..{end:g} s; allowed: "
            f"0 <= start < end <= {t_end:g} s (the recorded run)"
        )
    times = frame_times(start, end, fps, speed)
    strip_h = 2 * int(round(height * STRIP_FRACTION / 2)) if plots else 0
    wjobs = []
    for rec in recs:
        rows = nearest_rows(rec.time_s, times)
        job = PanelJob(
            scenario=rec.scenario,
            qpos=rec.qpos[rows],
            times=times,
            frac=(times - start) / (end - start),
            label=label_image(rec.name, height) if len(recs) > 1 else None,
        )
        if ghost:
            job.ghost_pos, job.ghost_quat = ghost_poses(rec.columns, nearest_rows(
                rec.columns["time_s"], times))  # fmt: skip
        if plots:
            job.strip, job.boxes = plot_strip(rec, width, strip_h, start, end)
        wjobs.append(job)
    out = Path(out)
    n = len(times)
    workers = max(1, min(jobs or os.cpu_count() or 1, n))
    chunk = max(1, min(8, n // (4 * workers) or 1))
    wall0 = time.perf_counter()
    # the workers read their jobs (poses, strips) from a file: what goes down the spawn
    # pipe stays a few hundred bytes, so a Ctrl-C during start-up cannot truncate it
    fd, jobs_file = tempfile.mkstemp(prefix="simpro-render-", suffix=".pkl")
    with os.fdopen(fd, "wb") as fh:
        pickle.dump(wjobs, fh, protocol=pickle.HIGHEST_PROTOCOL)
    try:
        pool, gl = _start_pool(jobs_file, width, height, camera, ghost, shadows, workers)
    except BaseException:
        os.unlink(jobs_file)
        raise
    try:
        with replacing(out, suffix=".mp4") as tmp:
            bar = tqdm(total=n, unit="frame", desc="render", disable=not progress, leave=False)
            pending: deque = deque()
            cpu: list[float] = []  # worker CPU seconds per chunk (independent of other load)
            writer = _ffmpeg_writer(tmp, fps, len(recs) * width, height + strip_h)
            try:
                for s in range(0, n, chunk):
                    pending.append(pool.submit(_render_frames, range(s, min(s + chunk, n))))
                    if len(pending) >= 2 * workers:
                        _drain(pending.popleft(), writer, bar, cpu)
                while pending:
                    _drain(pending.popleft(), writer, bar, cpu)
            finally:
                writer.close()
                bar.close()
    finally:
        pool.shutdown(cancel_futures=True)
        os.unlink(jobs_file)
    wall = time.perf_counter() - wall0
    return Rendered(
        out=str(out),
        frames=n,
        width=len(recs) * width,
        height=height + strip_h,
        fps=fps,
        camera=camera,
        shadows=bool(shadows),
        gl=gl,
        workers=workers,
        wall_s=wall,
        s_per_frame=wall / n,
        worker_cpu_s_per_frame=sum(cpu) / n,
        runs=[r.name for r in recs],
    )


def _drain(future, writer, bar, cpu: list) -> None:
    frames, cpu_s = future.result()
    cpu.append(cpu_s)
    for frame in frames:
        writer.send(np.ascontiguousarray(frame))
        bar.update(1)


class _ffmpeg_writer:  # noqa: N801 - a small closable writer
    """H.264 (yuv420p) through imageio-ffmpeg's ffmpeg binary; frames in order."""

    def __init__(self, path, fps, width, height):
        import imageio_ffmpeg  # the optional extra simpro-sim[video]

        self._gen = imageio_ffmpeg.write_frames(
            str(path),
            (width, height),
            fps=fps,
            codec="libx264",
            pix_fmt_out="yuv420p",
            macro_block_size=2,
            quality=None,
            output_params=["-crf", "20", "-preset", "veryfast"],
            ffmpeg_log_level="error",
        )
        self._gen.send(None)
        self.frames = 0

    def send(self, frame: np.ndarray) -> None:
        self._gen.send(frame)
        self.frames += 1

    def close(self) -> None:
        log = logging.getLogger("imageio_ffmpeg")
        level = log.level
        if not self.frames:  # stopped before the first frame: the file is removed anyway
            log.setLevel(logging.ERROR)
        try:
            self._gen.close()
        finally:
            log.setLevel(level)
