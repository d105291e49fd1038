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

from controllers.kinematics import platform_position
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.messages import one_line
from simpro_mj.report.results import read_timeseries

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


#: Largest ``qpos.npz`` read, and largest array in it once inflated (bytes).
MAX_RECORDING_BYTES = 2_000_000_000
#: What ``qpos.npz`` holds: name -> (dtype kinds allowed, number of dimensions).
RECORDING_ARRAYS = {"time_s": ("f", 1), "qpos": ("f", 2), "qpos_names": ("U", 1)}
#: Columns of ``timeseries.csv`` a replay draws (the set-point ghost and the plot strip).
REPLAY_COLUMNS = (
    "roll_ref_rad", "pitch_ref_rad", "heave_ref_m", "roll_rad", "pitch_rad", "heave_m",
    "u1_v", "u2_v", "u3_v",
)  # fmt: skip


def read_npz(path, spec: dict = RECORDING_ARRAYS, max_bytes: int = MAX_RECORDING_BYTES) -> dict:
    """The arrays of an ``.npz`` file, each header checked before anything is allocated.

    The file must be a regular file of at most ``max_bytes``
    (:mod:`simpro_mj.core.safe_files`); each array named in ``spec`` must be
    present, declare (in the zip directory) an inflated size of at most
    ``max_bytes`` (a zip bomb is refused unread), carry an ``.npy`` header of an
    allowed dtype kind and number of dimensions, and a shape whose bytes are
    exactly the declared size (a header claiming 10^12 rows in a small member
    is refused before NumPy allocates them). No pickles.

    Raises
    ------
    UserInputError
        One line naming the file and the array.
    """
    import zipfile

    from simpro_mj.core.safe_files import open_regular

    path = Path(path)
    allowed = "allowed: a qpos.npz written by simpro-sim run"
    out = {}
    with open_regular(path, max_bytes, "recording", binary=True) as fh:
        try:
            with zipfile.ZipFile(fh) as zf:
                for name, (kinds, ndim) in spec.items():
                    try:
                        info = zf.getinfo(f"{name}.npy")
                    except KeyError:
                        raise UserInputError(
                            f"unreadable recording at {path}: no array {name!r}; {allowed}"
                        ) from None
                    if info.file_size > max_bytes:
                        raise UserInputError(
                            f"unreadable recording at {path}: array {name} inflates to "
                            f"{info.file_size:,} bytes; allowed: at most {max_bytes:,}"
                        )
                    with zf.open(info) as member:
                        version = np.lib.format.read_magic(member)
                        if version == (1, 0):
                            shape, fortran, dtype = np.lib.format.read_array_header_1_0(member)
                        else:
                            shape, fortran, dtype = np.lib.format.read_array_header_2_0(member)
                        header = member.tell()
                        need = int(np.prod(shape, dtype=object)) * dtype.itemsize
                        if dtype.kind not in kinds or len(shape) != ndim:
                            raise UserInputError(
                                f"unreadable recording at {path}: array {name} of dtype "
                                f"{dtype.str} and shape {shape}; {allowed}"
                            )
                        if header + need != info.file_size:
                            raise UserInputError(
                                f"unreadable recording at {path}: array {name} claims shape "
                                f"{shape} ({need:,} bytes) in {info.file_size:,} bytes; {allowed}"
                            )
                    with zf.open(info) as member:  # read_array reads the header again
                        out[name] = np.lib.format.read_array(member, allow_pickle=False)
        except (zipfile.BadZipFile, ValueError, EOFError, OSError, NotImplementedError) as exc:
            if isinstance(exc, UserInputError):
                raise
            raise UserInputError(
                f"unreadable recording at {path}: {one_line(exc)}; {allowed}"
            ) from None
    return out


def load_recording(folder) -> Recording:
    """Read ``qpos.npz``, ``timeseries.csv`` and ``scenario.yaml`` of a run folder,
    each validated as an input (:func:`read_npz`,
    :func:`simpro_mj.report.results.read_timeseries` with :data:`REPLAY_COLUMNS`,
    the bounded YAML reader); a one-line :class:`UserInputError` naming the file."""
    from simpro_mj.core.keys import read_yaml

    folder = Path(folder)
    z = read_npz(folder / RECORDING_FILE)
    t, q, names = z["time_s"], z["qpos"], tuple(str(n) for n in z["qpos_names"])
    columns = read_timeseries(folder / "timeseries.csv", required=REPLAY_COLUMNS)
    scenario = read_yaml(folder / "scenario.yaml", "result scenario")
    for bad, what, file, why in (
        (len(t) == 0 or len(t) != len(q) or q.shape[1] != len(names), "no recorded motion",
         RECORDING_FILE, f"{len(t)} times, qpos {q.shape}, {len(names)} joint names"),
        (not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0) and np.all(np.isfinite(q))),
         "unreadable recording", RECORDING_FILE, "times not increasing or values not finite"),
        (not isinstance(scenario, dict), "unreadable recording", "scenario.yaml",
         "not a mapping"),
        (len(columns["time_s"]) == 0, "unreadable recording", "timeseries.csv", "no rows"),
    ):  # fmt: skip
        if bad:
            raise UserInputError(
                f"{what} at {folder / file}: {why}; allowed: a folder written by simpro-sim run"
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
    names = ("roll_ref_rad", "pitch_ref_rad", "heave_ref_m")
    pose = np.stack([columns[c][rows] for c in names], axis=-1)
    pos, _ = platform_position(pose)
    # R = Ry(pitch) Rx(roll) (eq. 8) as a quaternion: q = q_y(pitch) * q_x(roll)
    cr, sr = np.cos(pose[:, 0] / 2), np.sin(pose[:, 0] / 2)
    cp, sp = np.cos(pose[:, 1] / 2), np.sin(pose[:, 1] / 2)
    quat = np.stack([cp * cr, cp * sr, sp * cr, -sp * sr], axis=-1)
    return pos, quat
