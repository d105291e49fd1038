"""Replaying recorded runs with MuJoCo's offscreen renderer (issue 17).

A result folder written by ``simpro-sim run`` holds ``qpos.npz``: the full
``qpos`` of the closed chain at every logged row (a copy taken in the loop,
:attr:`simpro_mj.sim.loop.SimResult.qpos`). A replay sets those positions and
calls ``mj_kinematics``; nothing is simulated again, so what is drawn is
exactly what was computed. The set-point ghost (the ``ghost`` mocap body of
``simpro_mj/models/simpro_platform.xml``) is posed from the recorded set-point columns
(``roll_ref_rad``, ``pitch_ref_rad``, ``heave_ref_m``) through the
controller's nominal kinematics (:func:`controllers.kinematics.platform_position`).

Headless OpenGL: MuJoCo picks its backend from ``MUJOCO_GL`` when it is
first imported, so the frames are drawn in worker processes started with
``spawn`` and the variable set: ``egl`` (Mesa's software EGL works without a
GPU), then ``osmesa``; a ``MUJOCO_GL`` set by the user is the only one tried.
When none works the error names the missing library.

The plot strip under the 3D view is drawn once with matplotlib (the whole
replayed window); each frame only adds its time cursor, a column of pixels,
so the strip costs almost nothing per frame.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simpro_mj.core.errors import UserInputError

__all__ = [
    "CAMERAS",
    "Recording",
    "find_runs",
    "load_recording",
    "frame_times",
    "ReplayScene",
    "replay_model",
    "pose_data",
    "recording_of",
    "plot_strip",
    "render_video",
    "require_video",
    "VIDEO_HINT",
    "benchmark",
    "benchmark_table",
]

#: Named cameras of the MJCF, the first the default.
CAMERAS = ("three_quarter", "side", "driver")
#: What the user runs when imageio or its ffmpeg is missing.
VIDEO_HINT = "pip install 'simpro-sim[video]' (imageio and imageio-ffmpeg)"
RECORDING_FILE = "qpos.npz"
#: Backends tried in order when ``MUJOCO_GL`` is not set.
GL_BACKENDS = ("egl", "osmesa")
GL_LIBRARIES = {"egl": "libEGL (Debian: libegl1)", "osmesa": "libOSMesa (Debian: libosmesa6)"}
#: Height of the plot strip as a fraction of the 3D view's height.
STRIP_FRACTION = 0.5
#: Most runs drawn side by side (a batch folder holds many: render one of them).
MAX_RUNS = 4


def require_video():
    """Import imageio's v3 API with its ffmpeg plugin; one-line error when missing."""
    try:
        import imageio.v3 as iio
        import imageio_ffmpeg

        imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError) as exc:
        raise UserInputError(
            f"video output needs imageio and imageio-ffmpeg ({' '.join(str(exc).split())}); "
            f"install them with: {VIDEO_HINT}"
        ) from None
    return iio


# ---------------------------------------------------------------- recordings


@dataclass
class Recording:
    """One recorded run: its motion, its set-points and what the plots need."""

    name: str
    folder: Path
    time_s: np.ndarray
    qpos: np.ndarray  # (rows, nq)
    qpos_names: tuple
    columns: dict
    scenario: dict

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1]) if len(self.time_s) else 0.0


def find_runs(folder) -> list[Path]:
    """The run folders under ``folder``: itself, or (``compare``) its sub-folders.

    Raises
    ------
    UserInputError
        No such folder, or no recorded motion in it.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise UserInputError(
            f"no such folder at RESULT_DIR: {folder}; allowed: a folder written by "
            "simpro-sim run or compare"
        )
    if (folder / RECORDING_FILE).is_file():
        return [folder]
    subs = sorted(p for p in folder.iterdir() if (p / RECORDING_FILE).is_file())
    if len(subs) > MAX_RUNS:
        names = ", ".join(p.name for p in subs[:6]) + (", ..." if len(subs) > 6 else "")
        raise UserInputError(
            f"too many runs at RESULT_DIR: {folder} holds {len(subs)} ({names}); allowed: at "
            f"most {MAX_RUNS} side by side (a compare folder), or one run folder"
        )
    if not subs:
        raise UserInputError(
            f"no recorded motion at RESULT_DIR: {folder} has no {RECORDING_FILE} (nor its "
            "sub-folders); allowed: a folder written by simpro-sim run or compare (re-run it "
            "with this version to record the motion)"
        )
    return subs


def load_recording(folder) -> Recording:
    """Read ``qpos.npz``, ``timeseries.csv`` and ``scenario.yaml`` of a run folder."""
    import yaml

    from simpro_mj.report.results import read_timeseries

    folder = Path(folder)
    try:
        with np.load(folder / RECORDING_FILE, allow_pickle=False) as z:
            t, q, names = z["time_s"], z["qpos"], tuple(str(n) for n in z["qpos_names"])
        columns = read_timeseries(folder / "timeseries.csv")
        scenario = yaml.safe_load((folder / "scenario.yaml").read_text(encoding="utf-8"))
    except (OSError, KeyError, ValueError, yaml.YAMLError) as exc:
        raise UserInputError(
            f"unreadable recording at {folder}: {' '.join(str(exc).split())}; allowed: a "
            "complete folder written by simpro-sim run (qpos.npz, timeseries.csv, scenario.yaml)"
        ) from None
    if q.ndim != 2 or len(t) != len(q) or len(t) == 0 or not isinstance(scenario, dict):
        raise UserInputError(
            f"no recorded motion at {folder / RECORDING_FILE}: {len(t)} times, qpos "
            f"{q.shape}; allowed: a folder written by simpro-sim run"
        )
    return Recording(folder.name, folder, t, q, names, columns, scenario)


def recording_of(result) -> Recording:
    """A :class:`Recording` of a run still in memory (:class:`simpro_mj.sim.loop.SimResult`)."""
    if result.qpos is None:
        raise UserInputError("no recorded motion in this run: allowed: a run of this version")
    name = str(result.scenario.get("name", "run"))
    t = result.columns["time_s"]
    return Recording(name, Path(name), t, result.qpos, result.qpos_names, result.columns,
                     result.scenario)  # fmt: skip


def frame_times(start: float, end: float, fps: float, speed: float) -> np.ndarray:
    """Simulated time of each frame: ``start + i * speed / fps`` while < ``end``.

    ``speed`` < 1 is slow motion (0.25: a quarter of real time). A 1 s window
    at 25 fps and speed 1 gives 25 frames, a 1 s video.
    """
    n = int(math.floor((end - start) * fps / speed + 1e-9))
    return start + np.arange(max(n, 1)) * (speed / fps)


def nearest_rows(time_s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Row of the logged sample nearest to each time (exact samples, no interpolation)."""
    i = np.clip(np.searchsorted(time_s, t), 1, len(time_s) - 1)
    left = time_s[i - 1]
    return np.where(np.abs(t - left) <= np.abs(time_s[i] - t), i - 1, i)


def ghost_poses(columns: dict, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mocap position and quaternion (w, x, y, z) of the set-point pose at ``rows``."""
    from controllers.kinematics import platform_position

    pose = np.stack(
        [
            columns["roll_ref_rad"][rows],
            columns["pitch_ref_rad"][rows],
            columns["heave_ref_m"][rows],
        ],
        axis=-1,
    )
    pos, _ = platform_position(pose)
    # R = Ry(pitch) Rx(roll) (eq. 8) as a quaternion: q = q_y(pitch) * q_x(roll)
    cr, sr = np.cos(pose[:, 0] / 2), np.sin(pose[:, 0] / 2)
    cp, sp = np.cos(pose[:, 1] / 2), np.sin(pose[:, 1] / 2)
    quat = np.stack([cp * cr, cp * sr, sp * cr, -sp * sr], axis=-1)
    return pos, quat


# ---------------------------------------------------------------- the 3D view


def replay_model(scenario: dict):
    """The run's plant (its ``plant`` parameters) as ``(MjModel, MjData)``."""
    import mujoco

    from simpro_mj.plant.model import load_model

    model = load_model(scenario.get("plant"))
    return model, mujoco.MjData(model)


def pose_data(model, data, qpos, ghost_pos=None, ghost_quat=None) -> None:
    """Put a recorded ``qpos`` (and the ghost's pose) into ``data``; no physics.

    ``mj_kinematics`` places the bodies, ``mj_camlight`` the cameras and
    lights that follow them; nothing else is computed, nothing integrated.
    """
    import mujoco

    data.qpos[:] = qpos
    if ghost_pos is not None:
        data.mocap_pos[0] = ghost_pos
        data.mocap_quat[0] = ghost_quat
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)


class ReplayScene:
    """A recorded run posed at given rows and drawn by :class:`mujoco.Renderer`.

    Parameters
    ----------
    scenario : dict
        The run's resolved scenario (its ``plant`` rebuilds the same model).
    width, height : int
        Image size in pixels.
    camera : str
        One of :data:`CAMERAS`.
    ghost : bool
        Draw the set-point ghost (otherwise it is hidden).
    shadows : bool
        Cast shadows: about 3x the cost of a frame with Mesa's software
        renderer (docs/performance.md), so off by default.
    """

    def __init__(
        self,
        scenario: dict,
        width: int,
        height: int,
        camera: str,
        ghost: bool = True,
        shadows: bool = False,
    ):
        import mujoco

        self.model, self.data = m, _ = replay_model(scenario)
        m.vis.global_.offwidth = max(int(m.vis.global_.offwidth), width)
        m.vis.global_.offheight = max(int(m.vis.global_.offheight), height)
        self.camera = camera
        self.renderer = mujoco.Renderer(m, height, width)
        self.option = mujoco.MjvOption()
        self.option.geomgroup[1] = 1 if ghost else 0
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = bool(shadows)

    def pose(self, qpos, ghost_pos=None, ghost_quat=None) -> None:
        """Set the recorded ``qpos`` (and the ghost's pose): :func:`pose_data`."""
        pose_data(self.model, self.data, qpos, ghost_pos, ghost_quat)

    def render(self) -> np.ndarray:
        """RGB image (height, width, 3) uint8 of the current pose."""
        self.renderer.update_scene(self.data, camera=self.camera, scene_option=self.option)
        return self.renderer.render()

    def segmentation(self) -> np.ndarray:
        """Geom id per pixel (-1: background), (height, width) int32."""
        r = self.renderer
        r.enable_segmentation_rendering()
        try:
            r.update_scene(self.data, camera=self.camera, scene_option=self.option)
            seg = r.render()
        finally:
            r.disable_segmentation_rendering()
        ids = seg[..., 0].copy()
        import mujoco

        ids[seg[..., 1] != int(mujoco.mjtObj.mjOBJ_GEOM)] = -1
        return ids

    def close(self) -> None:
        self.renderer.close()


# ---------------------------------------------------------------- plot strip


def plot_strip(rec: Recording, width: int, height: int, t0: float, t1: float):
    """The plots under the 3D view, drawn once; the cursor is added per frame.

    Four panels: set-point and pose for roll, pitch (deg) and heave (mm), and
    the three valve voltages (V), over the replayed window.

    Returns
    -------
    image : ndarray (height, width, 3) uint8
    boxes : list of (x0, x1, y0, y1)
        Pixel extent of each panel's plotting area (where the cursor goes).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    dpi = 100.0
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    c, t = rec.columns, rec.columns["time_s"]
    sel = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    small = max(4.0, min(8.0, width / 110.0))
    panels = [
        ("roll [deg]", "roll_ref_rad", "roll_rad", 180.0 / math.pi),
        ("pitch [deg]", "pitch_ref_rad", "pitch_rad", 180.0 / math.pi),
        ("heave [mm]", "heave_ref_m", "heave_m", 1e3),
    ]
    axes = fig.subplots(1, 4)
    for ax, (label, ref, real, scale) in zip(axes[:3], panels, strict=True):
        ax.plot(t[sel], c[ref][sel] * scale, color="0.55", lw=0.8, ls="--", label="set-point")
        ax.plot(t[sel], c[real][sel] * scale, color="tab:blue", lw=1.0, label="pose")
        ax.set_title(label, fontsize=small, pad=2)
    for i, color in zip((1, 2, 3), ("tab:orange", "tab:green", "tab:purple"), strict=True):
        axes[3].plot(t[sel], c[f"u{i}_v"][sel], color=color, lw=0.8, label=f"u{i}")
    axes[3].set_title(f"valves [V] ({rec.name})", fontsize=small, pad=2)
    axes[0].legend(fontsize=small * 0.8, loc="best", frameon=False)
    for ax in axes:
        ax.set_xlim(t0, t1)
        ax.ticklabel_format(axis="y", useOffset=False)  # 1265.0 mm, not +1.265e3
        ax.tick_params(labelsize=small * 0.85, length=2, pad=1)
        ax.set_xlabel("t [s]", fontsize=small * 0.85, labelpad=1)
    fig.subplots_adjust(left=0.05, right=0.99, bottom=0.22, top=0.86, wspace=0.35)
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    boxes = []
    for ax in axes:
        (x0, y0), (x1, y1) = ax.get_window_extent().get_points()
        # figure pixels have y up; the image's rows go down
        boxes.append(
            (int(round(x0)), int(round(x1)), int(round(height - y1)), int(round(height - y0)))
        )
    return img, boxes


def label_image(text: str, height: int) -> np.ndarray:
    """A small white-on-dark RGB label (drawn once with matplotlib, pasted per frame)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    h = max(10, int(height * 0.06)) // 2 * 2
    w = max(2 * h, int(0.62 * h * (len(text) + 1))) // 2 * 2
    fig = Figure(figsize=(w / 100.0, h / 100.0), dpi=100.0, facecolor=(0.1, 0.1, 0.12))
    FigureCanvasAgg(fig)
    fig.text(0.5, 0.5, text, color="white", ha="center", va="center", fontsize=h * 0.5)
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()


def draw_cursor(strip: np.ndarray, boxes, frac: float) -> np.ndarray:
    """A copy of the strip with a red time cursor at ``frac`` (0..1) of each panel."""
    out = strip.copy()
    for x0, x1, y0, y1 in boxes:
        x = int(round(x0 + frac * (x1 - x0)))
        x = min(max(x, x0), max(x1 - 1, x0))
        out[max(y0, 0) : y1, max(x - 1, 0) : x + 1] = (220, 30, 30)
    return out


# ---------------------------------------------------------------- workers

_WORKER: dict = {}


def _worker_init(jobs_file: str, width: int, height: int, camera: str, ghost, shadows, gl: str):
    import pickle
    import signal
    import warnings

    # Ctrl-C reaches the whole process group: the parent stops the pool and removes
    # the partial video; a worker must not die with a traceback of its own
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ["MUJOCO_GL"] = gl  # before MuJoCo is imported in this (spawned) process
    warnings.simplefilter("ignore")  # GLFW/OpenGL warnings: a failure is reported in one line
    _WORKER["error"] = None
    try:
        with open(jobs_file, "rb") as fh:
            jobs = pickle.load(fh)
        _WORKER["scenes"] = [
            ReplayScene(job["scenario"], width, height, camera, ghost, shadows) for job in jobs
        ]
    except Exception as exc:  # noqa: BLE001 - reported by _probe as the backend's failure
        _WORKER["error"] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
        return
    _WORKER["jobs"] = jobs


def _probe(_=None):
    """None if this worker can render, else why not."""
    return _WORKER.get("error", "worker not initialised")


def _render_frames(indices) -> tuple[list[np.ndarray], float]:
    """The frames at ``indices`` and the CPU seconds this worker spent on them."""
    cpu0 = time.process_time()
    frames = []
    for i in indices:
        panels = []
        for scene, job in zip(_WORKER["scenes"], _WORKER["jobs"], strict=True):
            gp, gq = (job["ghost_pos"][i], job["ghost_quat"][i]) if job["ghost"] else (None, None)
            scene.pose(job["qpos"][i], gp, gq)
            view = scene.render()
            label = job.get("label")
            if label is not None:  # runs side by side: which is which
                lh, lw = min(label.shape[0], view.shape[0]), min(label.shape[1], view.shape[1])
                view[:lh, :lw] = label[:lh, :lw]
            if job["strip"] is not None:
                strip = draw_cursor(job["strip"], job["boxes"], job["frac"][i])
                view = np.concatenate([view, strip], axis=0)
            panels.append(view)
        frames.append(np.concatenate(panels, axis=1) if len(panels) > 1 else panels[0])
    return frames, time.process_time() - cpu0


def _gl_candidates() -> tuple[str, ...]:
    user = os.environ.get("MUJOCO_GL", "").strip().lower()
    return (user,) if user else GL_BACKENDS


def _start_pool(jobs_file: str, width, height, camera, ghost, shadows, workers: int):
    """A spawned pool whose workers can all render; tries the GL backends in order."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    ctx = multiprocessing.get_context("spawn")  # a fresh interpreter: MUJOCO_GL applies
    why = []
    for gl in _gl_candidates():
        pool = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=ctx,
            initializer=_worker_init,
            initargs=(jobs_file, width, height, camera, ghost, shadows, gl),
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


# ---------------------------------------------------------------- the video


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
) -> dict:
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
    dict
        ``out``, ``frames``, ``width``, ``height``, ``fps``, ``gl`` (backend),
        ``workers``, ``wall_s``, ``s_per_frame``.
    """
    require_video()
    from tqdm import tqdm

    width, height = size
    recs = [load_recording(f) for f in folders]
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
        job = {
            "scenario": rec.scenario,
            "qpos": rec.qpos[rows],
            "ghost": ghost,
            "strip": None,
            "boxes": None,
            "frac": (times - start) / (end - start),
            "label": label_image(rec.name, height) if len(recs) > 1 else None,
        }
        if ghost:
            job["ghost_pos"], job["ghost_quat"] = ghost_poses(rec.columns, nearest_rows(
                rec.columns["time_s"], times))  # fmt: skip
        if plots:
            job["strip"], job["boxes"] = plot_strip(rec, width, strip_h, start, end)
        wjobs.append(job)
    out = Path(out)
    n = len(times)
    workers = max(1, min(jobs or os.cpu_count() or 1, n))
    chunk = max(1, min(8, n // (4 * workers) or 1))
    wall0 = time.perf_counter()
    # the workers read their jobs (poses, strips) from a file: what goes down the spawn
    # pipe stays a few hundred bytes, so a Ctrl-C during start-up cannot truncate it
    import pickle

    fd, jobs_file = tempfile.mkstemp(prefix="simpro-render-", suffix=".pkl")
    with os.fdopen(fd, "wb") as fh:
        pickle.dump(wjobs, fh, protocol=pickle.HIGHEST_PROTOCOL)
    try:
        pool, gl = _start_pool(jobs_file, width, height, camera, ghost, shadows, workers)
    except BaseException:
        os.unlink(jobs_file)
        raise
    tmp = None
    try:
        fd, name = tempfile.mkstemp(prefix=f".{out.stem}.tmp-", suffix=".mp4", dir=out.parent)
        os.close(fd)
        tmp = Path(name)
        bar = tqdm(total=n, unit="frame", desc="render", disable=not progress, leave=False)
        pending: deque = deque()
        cpu: list[float] = []  # worker CPU seconds per chunk (independent of other load)
        starts = iter(range(0, n, chunk))
        writer = _ffmpeg_writer(tmp, fps, len(recs) * width, height + strip_h)
        try:
            for s in starts:
                pending.append(pool.submit(_render_frames, range(s, min(s + chunk, n))))
                if len(pending) >= 2 * workers:
                    _drain(pending.popleft(), writer, bar, cpu)
            while pending:
                _drain(pending.popleft(), writer, bar, cpu)
        finally:
            writer.close()
            bar.close()
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 -> what a plain open would give
        os.replace(tmp, out)
        tmp = None
    finally:
        pool.shutdown(cancel_futures=True)
        os.unlink(jobs_file)
        if tmp is not None:
            tmp.unlink(missing_ok=True)
    wall = time.perf_counter() - wall0
    return {
        "out": str(out),
        "frames": n,
        "width": len(recs) * width,
        "height": height + strip_h,
        "fps": fps,
        "camera": camera,
        "shadows": bool(shadows),
        "gl": gl,
        "workers": workers,
        "wall_s": wall,
        "s_per_frame": wall / n,
        "worker_cpu_s_per_frame": sum(cpu) / n,
        "runs": [r.name for r in recs],
    }


def _drain(future, writer, bar, cpu: list) -> None:
    frames, cpu_s = future.result()
    cpu.append(cpu_s)
    for frame in frames:
        writer.send(np.ascontiguousarray(frame))
        bar.update(1)


class _ffmpeg_writer:  # noqa: N801 - a small closable writer
    """H.264 (yuv420p) through imageio-ffmpeg's ffmpeg binary; frames in order."""

    def __init__(self, path, fps, width, height):
        import imageio_ffmpeg

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
        import logging

        log = logging.getLogger("imageio_ffmpeg")
        level = log.level
        if not self.frames:  # stopped before the first frame: the file is removed anyway
            log.setLevel(logging.ERROR)
        try:
            self._gen.close()
        finally:
            log.setLevel(level)


# ---------------------------------------------------------------- benchmark

#: The issue's target for the benchmark below (s, on a 2-core machine).
BENCH_TARGET_S = 90.0


def benchmark(scenario: dict, *, fps=25.0, size=(640, 480), jobs=None, progress=True) -> dict:
    """Time a replay video of a run (``simpro-sim bench --video``).

    The scenario is run first (not timed) into a temporary folder, then
    rendered with the plot strip and the ghost; ``render_s`` is the wall time
    of :func:`render_video` from the start of the worker processes to the
    closed MP4 (strip drawing, encoding and worker start-up included).
    """
    import shutil

    from simpro_mj.report.machine import describe_machine
    from simpro_mj.report.runner import execute

    require_video()
    tmp = Path(tempfile.mkdtemp(prefix="simpro-video-bench-"))
    try:
        execute(scenario, tmp / "run", plots=False, quiet=True)
        info = render_video([tmp / "run"], tmp / "run" / "replay.mp4", fps=fps, size=size,
                            jobs=jobs, progress=progress)  # fmt: skip
        mb = (tmp / "run" / "replay.mp4").stat().st_size / 1e6
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {
        "scenario": scenario.get("name"),
        "duration_s": scenario["duration_s"],
        "fps": fps,
        "size": f"{size[0]}x{size[1]}",
        "video_size": f"{info['width']}x{info['height']}",
        "frames": info["frames"],
        "workers": info["workers"],
        "gl": info["gl"],
        "render_s": info["wall_s"],
        "s_per_frame": info["s_per_frame"],
        "worker_s_per_frame": info["s_per_frame"] * info["workers"],
        # CPU time the workers spent per frame: what the frames cost on an idle machine
        "worker_cpu_s_per_frame": info["worker_cpu_s_per_frame"],
        "load_average": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        "mp4_mb": mb,
        "target_s": BENCH_TARGET_S,
        "within_target": info["wall_s"] <= BENCH_TARGET_S,
        "machine": describe_machine(),
    }


def benchmark_table(r: dict) -> str:
    m = r["machine"]
    return "\n".join(
        [
            f"video benchmark: {r['scenario']}, {r['duration_s']:g} s at {r['fps']:g} fps, "
            f"{r['size']} view + plot strip ({r['video_size']}), ghost on",
            f"  frames            {r['frames']}",
            f"  workers           {r['workers']} (MUJOCO_GL={r['gl']})",
            f"  render wall time  {r['render_s']:.1f} s (target <= {r['target_s']:g} s: "
            f"{'met' if r['within_target'] else 'NOT met'})",
            f"  per frame         {r['s_per_frame']:.3f} s wall, "
            f"{r['worker_s_per_frame']:.3f} s per worker, "
            f"{r['worker_cpu_s_per_frame']:.3f} s of worker CPU",
            f"  load average      {r['load_average']} (other jobs slow the wall time)",
            f"  MP4               {r['mp4_mb']:.1f} MB",
            f"  machine           {m['cpu']}, {m['cores']} cores, MuJoCo {m['mujoco']}",
        ]
    )
