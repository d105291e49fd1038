"""Recorded runs, read back: the motion (``qpos.npz``) and the set-points of a result folder.

A result folder written by ``simpro-sim run`` holds ``qpos.npz``: the full
``qpos`` of the closed chain at every logged row (a copy taken in the loop,
:attr:`simpro_mj.sim.result.SimResult.qpos`). A replay (:mod:`.render`,
:mod:`.viewer`) shows exactly those positions: nothing is simulated again.
The set-point ghost is posed from the recorded set-point columns
(``roll_ref_rad``, ``pitch_ref_rad``, ``heave_ref_m``) through the
controller's nominal kinematics (:func:`controllers.kinematics.platform_position`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from controllers.kinematics import platform_position
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.messages import one_line
from simpro_mj.report.results import read_timeseries

__all__ = [
    "MAX_RUNS",
    "RECORDING_FILE",
    "Recording",
    "find_runs",
    "frame_times",
    "ghost_poses",
    "load_recording",
    "nearest_rows",
    "recording_of",
]

RECORDING_FILE = "qpos.npz"
#: Most runs drawn side by side (a batch folder holds many: render one of them).
MAX_RUNS = 4


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
    folder = Path(folder)
    try:
        with np.load(folder / RECORDING_FILE, allow_pickle=False) as z:
            t, q, names = z["time_s"], z["qpos"], tuple(str(n) for n in z["qpos_names"])
        columns = read_timeseries(folder / "timeseries.csv")
        scenario = yaml.safe_load((folder / "scenario.yaml").read_text(encoding="utf-8"))
    except (OSError, KeyError, ValueError, yaml.YAMLError) as exc:
        raise UserInputError(
            f"unreadable recording at {folder}: {one_line(exc)}; allowed: a "
            "complete folder written by simpro-sim run (qpos.npz, timeseries.csv, scenario.yaml)"
        ) from None
    if q.ndim != 2 or len(t) != len(q) or len(t) == 0 or not isinstance(scenario, dict):
        raise UserInputError(
            f"no recorded motion at {folder / RECORDING_FILE}: {len(t)} times, qpos "
            f"{q.shape}; allowed: a folder written by simpro-sim run"
        )
    return Recording(folder.name, folder, t, q, names, columns, scenario)


def recording_of(result) -> Recording:
    """A :class:`Recording` of a run still in memory (:class:`simpro_mj.sim.result.SimResult`)."""
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
