"""Writing a run's results folder, atomically, and printing its summary.

A results folder holds:

* ``timeseries.csv``: one row per logged sample, a header of column names
  with their units (``time_s``, ``roll_rad``, ``p1a_pa``, ...), SI values with
  12 significant digits;
* ``metrics.json``: ``status`` (ok | diverged | interrupted), ``reason``, the scenario's
  name and hash, ``axes`` and ``joints`` (:func:`simpro_mj.analysis.metrics.compute_metrics`),
  the metric ``definitions``, a ``sim`` block (deterministic figures, with the
  wall-clock ones such as ``realtime_factor`` apart under ``sim.wall_clock``)
  and ``versions``;
* ``scenario.yaml``: the resolved scenario (loads back to the same hash);
* the PNG figures of :func:`simpro_mj.report.plots.plot_run`;
* ``PARTIAL`` (only for status ``interrupted``): one line saying the run was
  stopped before its end and how far it got;
* ``.simpro-result`` (:data:`RESULT_MARKER`): one JSON line ``{"kind": "run",
  "simpro-sim": version}`` saying the folder is simpro-sim's to replace.

Whose folder it is
------------------
A folder is replaced only if it is new, empty or carries the marker of the
same kind (:func:`check_out`): any other existing folder is refused (a user's
mistake, exit 2) and nothing in it is touched, as is an ``--out`` that is the
working folder (or one above it) or holds the scenario file. A writer holds
an exclusive lock (:func:`locked`: ``flock`` on a hidden ``.<name>.lock``
beside the folder) from its first check to the end of the write, so a second
writer of the same folder is refused, not raced.

Atomic install
--------------
The folder is written under a temporary name (``.<name>.tmp-*``) next to
``out_dir`` and renamed into place when complete. An existing ``out_dir`` is
first renamed aside (``.<name>.old-*``) and deleted only after the new folder
is in place; if anything (an exception, Ctrl-C) stops the write before that,
the temporary folder is removed and the previous folder put back. So a reader
never sees a truncated file under ``out_dir`` (on POSIX, ``out_dir`` is
briefly absent between the two renames: directories cannot be swapped
atomically there). A process killed outright (SIGKILL, power loss) can leave
a hidden ``.tmp-`` folder, never a half-written ``out_dir``. An interrupted
run never replaces a complete result: its partial result goes beside it, to
``<name>.partial`` (:func:`write_results` returns where it went). An
``OSError`` (read-only or full disk) names ``out_dir``, not a temporary name.

A folder is *complete* (:func:`is_complete`, what ``batch --resume`` may
trust) when it carries the marker, its ``metrics.json`` reads and has status
``ok`` or ``diverged``, its ``timeseries.csv`` is not empty and there is no
``PARTIAL`` file.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import platform
import shutil
import sys
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from importlib import metadata
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import yaml

from simpro_mj.config.scenario import scenario_hash
from simpro_mj.core.errors import UserInputError

__all__ = [
    "write_results",
    "write_timeseries",
    "read_timeseries",
    "versions",
    "print_summary",
    "STATUSES",
    "WALL_CLOCK_KEYS",
    "PARTIAL_MARKER",
    "RESULT_MARKER",
    "is_complete",
    "result_kind",
    "check_out",
    "locked",
    "claim",
    "install_folder",
]

#: ``ok``: ran to the end; ``diverged``: stopped by the divergence checks (the
#: folder holds everything up to that point); ``interrupted``: stopped by the
#: user (Ctrl-C, SIGTERM), marked with a ``PARTIAL`` file.
STATUSES = ("ok", "diverged", "interrupted")
#: File name of the marker of an interrupted run's folder.
PARTIAL_MARKER = "PARTIAL"
#: File name of the marker of a folder simpro-sim wrote (and may replace).
RESULT_MARKER = ".simpro-result"
#: ``extra["sim"]`` keys that depend on the machine, not on the scenario.
WALL_CLOCK_KEYS = ("realtime_factor", "wall_time_s", "wall_s", "elapsed_s", "steps_per_s", "host")
_RESERVED = {"status", "reason", "scenario", "axes", "joints", "metrics", "sim", "versions"}


def versions(resolved: Mapping | None = None) -> dict:
    """Versions of simpro-sim and its numerical dependencies (and the scenario hash)."""

    def dist(name: str) -> str | None:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return None

    from simpro_mj import __version__
    from simpro_mj.plant import pneumatics_kernel
    from simpro_mj.report.machine import fingerprint_id

    out = {
        "simpro-sim": __version__,
        "mujoco": dist("mujoco"),
        "numpy": np.__version__,
        "python-control": dist("control"),
        "python": platform.python_version(),
        "kernels": pneumatics_kernel.kernel_label(),  # SIMPRO_KERNEL: pneumatics + sensors
        # results are bit-identical only under one fingerprint (simpro_mj.report.machine)
        "machine": fingerprint_id(),
    }
    if resolved is not None:
        out["scenario_hash"] = scenario_hash(resolved)
    return out


def jsonable(obj: Any) -> Any:
    """Plain JSON types: numpy scalars/arrays converted, NaN and inf as null."""
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if math.isfinite(x) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_timeseries(path, columns: Mapping[str, np.ndarray]) -> Path:
    """Write columns as CSV in one numpy call: header of names, ``%.12g`` values.

    Raises
    ------
    ValueError
        If the columns differ in length, are not 1-D, or a name contains a comma.
    """
    path = Path(path)
    names = list(columns)
    if "time_s" in names:  # time first
        names.remove("time_s")
        names.insert(0, "time_s")
    for name in names:
        if "," in name or "\n" in name:
            raise ValueError(f"column name {name!r} cannot go into a CSV header")
    arrays = [np.asarray(columns[n], dtype=float) for n in names]
    lengths = {a.shape for a in arrays}
    if len(lengths) > 1 or (arrays and arrays[0].ndim != 1):
        shapes = {n: a.shape for n, a in zip(names, arrays, strict=True)}
        raise ValueError(f"columns must be 1-D and of equal length, got {shapes}")
    data = np.column_stack(arrays) if arrays else np.empty((0, 0))
    np.savetxt(path, data, fmt="%.12g", delimiter=",", header=",".join(names), comments="")
    return path


def read_timeseries(path) -> dict[str, np.ndarray]:
    """Read a ``timeseries.csv`` back into columns."""
    path = Path(path)
    with path.open(encoding="utf-8") as fh:
        names = fh.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if data.size == 0:
        return {n: np.empty(0) for n in names}
    return {n: data[:, i] for i, n in enumerate(names)}


def _sim_block(sim: Mapping | None) -> dict:
    sim = dict(sim or {})
    wall = dict(sim.pop("wall_clock", {}) or {})
    for key in list(sim):
        if key in WALL_CLOCK_KEYS:
            wall[key] = sim.pop(key)
    sim["wall_clock"] = wall
    # issue 5's layout names sim.realtime_factor; it is a wall-clock figure, so it
    # is also kept under sim.wall_clock with the others (compare runs without both)
    if "realtime_factor" in wall:
        sim["realtime_factor"] = wall["realtime_factor"]
    return sim


def write_results(
    out_dir,
    columns: Mapping[str, np.ndarray],
    metrics: Mapping,
    scenario: Mapping,
    extra: Mapping | None = None,
    arrays: Mapping[str, Mapping[str, np.ndarray]] | None = None,
) -> Path:
    """Write a complete results folder atomically and return its path.

    Parameters
    ----------
    out_dir : path
        The folder to create (replaced if it exists; its parent is created).
    columns : mapping of str to ndarray
        Logged time series, SI, names with units (``time_s``, ``roll_rad``, ...).
    metrics : mapping
        :func:`simpro_mj.analysis.metrics.compute_metrics` output.
    scenario : mapping
        The resolved scenario.
    extra : mapping, optional
        ``status`` (one of :data:`STATUSES`; default ``metrics["status"]``, else
        "ok"), ``reason`` (why it diverged or stopped; default ``metrics["reason"]``),
        ``sim`` (figures of the simulation: steps, physics step, ...; wall-clock
        keys go to ``sim.wall_clock``), ``plots`` (False: no PNGs). Any other
        key is copied into ``metrics.json`` as is.
    arrays : mapping, optional
        File name -> named arrays, each written with ``numpy.savez_compressed``
        (``qpos.npz``: the recorded joint positions that ``simpro-sim render`` replays).

    Returns
    -------
    Path
        Where the folder went (absolute): ``out_dir``, or for an interrupted
        run whose ``out_dir`` holds a complete result, ``<out_dir>.partial``.

    Raises
    ------
    UserInputError
        If ``out_dir`` exists and is not a folder, is not simpro-sim's to
        replace, or is being written by another process.
    ValueError
        Unknown status, or unequal column lengths.
    """
    extra = dict(extra or {})
    out_dir = Path(out_dir).expanduser().absolute()
    check_out(out_dir)
    status = extra.pop("status", metrics.get("status", "ok"))
    if status not in STATUSES:
        raise ValueError(f"status must be one of {STATUSES}, got {status!r}")
    reason = extra.pop("reason", metrics.get("reason"))
    make_plots = bool(extra.pop("plots", True))
    doc: dict = {
        "status": status,
        "reason": reason,
        "scenario": {"name": scenario.get("name"), "hash": scenario_hash(scenario)},
        "axes": metrics.get("axes", {}),
        "joints": metrics.get("joints", {}),
        "metrics": {k: v for k, v in metrics.items() if k not in _RESERVED},
        "sim": _sim_block(extra.pop("sim", None)),
        "versions": versions(scenario),
    }
    for key, value in extra.items():
        doc[key if key not in _RESERVED else f"extra_{key}"] = value

    def fill(tmp: Path) -> None:
        if status == "interrupted":
            (tmp / PARTIAL_MARKER).write_text(
                f"partial results: the run was interrupted ({reason}); "
                "see metrics.json (status interrupted)\n",
                encoding="utf-8",
            )
        write_timeseries(tmp / "timeseries.csv", columns)
        for name, named in (arrays or {}).items():
            np.savez_compressed(tmp / name, **named)
        text = json.dumps(jsonable(doc), indent=2, allow_nan=False)
        (tmp / "metrics.json").write_text(text + "\n", encoding="utf-8")
        with (tmp / "scenario.yaml").open("w", encoding="utf-8") as fh:
            fh.write(f"# resolved scenario, sha256 {doc['scenario']['hash']}\n")
            yaml.safe_dump(jsonable(scenario), fh, sort_keys=False, default_flow_style=None)
        if make_plots:
            from simpro_mj.report.plots import plot_run

            plot_run(columns, scenario, tmp)

    with locked(out_dir):
        target = out_dir
        if status == "interrupted" and is_complete(out_dir):
            # never replace a complete result with a partial one: write it beside
            target = _partial_sibling(out_dir)
        return install_folder(target, fill)


def _partial_sibling(out_dir: Path) -> Path:
    """``<name>.partial`` beside ``out_dir`` (``.partial-2``, ... if that is not ours)."""
    for i in range(1, 100):
        cand = out_dir.with_name(f"{out_dir.name}.partial" + (f"-{i}" if i > 1 else ""))
        if not cand.exists() or _replaceable(cand, "run"):
            return cand
    raise UserInputError(
        f"no room at {out_dir}: 99 .partial folders beside it; allowed: remove some"
    )


def result_kind(folder) -> str | None:
    """The kind (``run``, ``batch``, ``compare``) in ``folder``'s marker, or None."""
    try:
        doc = json.loads((Path(folder) / RESULT_MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return doc.get("kind") if isinstance(doc, dict) else None


def write_marker(folder, kind: str) -> None:
    """Mark ``folder`` as a simpro-sim result of ``kind`` (see :func:`check_out`)."""
    from simpro_mj import __version__

    text = json.dumps({"kind": kind, "simpro-sim": __version__})
    (Path(folder) / RESULT_MARKER).write_text(text + "\n", encoding="utf-8")


def _replaceable(folder: Path, kind: str) -> bool:
    try:
        empty = not any(folder.iterdir())
    except OSError:
        return False
    return empty or result_kind(folder) == kind


def _short(path: Path, limit: int = 200) -> str:
    text = str(path)
    return text if len(text) <= limit else f"{text[:90]}...{text[-90:]}"


def check_out(out, kind: str = "run", inputs: Iterable = ()) -> Path:
    """Refuse an output folder that is not simpro-sim's to write; return it absolute.

    Parameters
    ----------
    out : path
        The ``--out`` folder.
    kind : str
        What will be written there (``run``, ``batch``, ``compare``): an
        existing folder must be empty or carry the marker of this kind.
    inputs : iterable of paths
        Files the command reads (the scenario): ``out`` must not hold them.

    Raises
    ------
    UserInputError
        ``out`` is a file, the working folder or one above it, holds an input,
        or is a non-empty folder without the marker of ``kind`` (nothing is
        touched).
    """
    out = Path(out).expanduser().absolute()
    real = out.resolve()
    cwd = Path.cwd().resolve()
    if real == cwd or real in cwd.parents:
        raise UserInputError(
            f"refused --out at {_short(out)}: it is the working folder or holds it; "
            "allowed: a new folder, e.g. results/<name>"
        )
    for item in inputs:
        p = Path(item).expanduser()
        if p.is_file() and p.resolve().is_relative_to(real):
            raise UserInputError(
                f"refused --out at {_short(out)}: it holds the input {_short(p)}; "
                "allowed: a folder apart from the scenario files"
            )
    if out.exists() and not out.is_dir():
        raise UserInputError(f"not a folder at {_short(out)}: allowed: a new or existing folder")
    if out.is_dir() and not _replaceable(out, kind):
        found = result_kind(out)
        what = f"a simpro-sim {found} result" if found else "not a simpro-sim result"
        raise UserInputError(
            f"refused --out at {_short(out)}: the folder holds files and is {what} "
            f"(no {RESULT_MARKER} of kind {kind}); nothing was touched; allowed: a new or "
            f"empty folder, or a simpro-sim {kind} result to replace"
        )
    return out


_HELD: dict[str, list] = {}


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def locked(out) -> Iterator[Path]:
    """Hold the exclusive write lock of folder ``out`` (reentrant in this process).

    The lock is ``flock`` on ``.<name>.lock`` beside ``out``, holding the
    writer's pid; it is removed on release. A lock file removed and re-created
    by another writer between our ``open`` and ``flock`` is detected (inode
    check) and the lock taken again.

    Raises
    ------
    UserInputError
        Another process holds the lock (exit 2: choose another ``--out`` or
        wait).
    OSError
        The lock cannot be created (read-only parent); ``filename`` is ``out``.
    """
    out = Path(out).expanduser().absolute()
    key = str(out)
    if key in _HELD:
        _HELD[key][1] += 1
        try:
            yield out
        finally:
            _HELD[key][1] -= 1
        return
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield out
        return
    path = out.parent / f".{out.name}.lock"
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = os.read(fd, 32).decode("ascii", "replace").strip() or "?"
                os.close(fd)
                raise UserInputError(
                    f"busy at {_short(out)}: another simpro-sim process (pid {pid}) is writing "
                    "this folder; allowed: wait for it to end or choose another --out"
                ) from None
            try:
                same = os.stat(path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)  # released and removed meanwhile: take the new one
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(out)) from exc
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
    except OSError:
        pass  # the pid is only for the message
    _HELD[key] = [fd, 1]
    try:
        yield out
    finally:
        del _HELD[key]
        with contextlib.suppress(OSError):
            path.unlink()
        os.close(fd)


@contextlib.contextmanager
def claim(out, kind: str = "run", inputs: Iterable = ()) -> Iterator[Path]:
    """:func:`check_out` then :func:`locked`, re-checked under the lock: what a
    command wraps around its whole job so that a refusal comes before any work."""
    out = check_out(out, kind, inputs)
    with locked(out):
        yield check_out(out, kind, inputs)


def install_folder(out_dir, fill, kind: str = "run") -> Path:
    """Create ``out_dir`` atomically: ``fill(tmp)`` writes a temporary sibling,
    which is then marked (:data:`RESULT_MARKER`, ``kind``) and renamed into
    place, replacing a previous ``out_dir`` that is empty or of the same kind.

    On any exception, Ctrl-C included, the previous folder is back under its
    name and no temporary folder is left behind: a reader sees the old
    complete folder or the new complete one, never a half-written one.
    Shared by :func:`write_results` and ``simpro-sim batch`` (result folders
    shipped back from Dask workers). Holds :func:`locked` while it works.

    Returns
    -------
    Path
        ``out_dir``.

    Raises
    ------
    UserInputError
        ``out_dir`` is not simpro-sim's to replace (:func:`check_out`) or is
        being written by another process.
    OSError
        A write failed (full or read-only disk); ``filename`` is ``out_dir``.
    """
    out_dir = Path(out_dir).expanduser().absolute()
    with locked(out_dir):
        check_out(out_dir, kind)
        tmp: Path | None = None
        old = None
        try:
            tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.tmp-", dir=out_dir.parent))
            tmp.chmod(0o777 & ~_umask())  # mkdtemp's 0700 is for the temporary name only
            fill(tmp)
            write_marker(tmp, kind)
            if out_dir.exists():
                old = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.old-", dir=out_dir.parent))
                old.rmdir()
                out_dir.rename(old)
            tmp.rename(out_dir)
            tmp = None
        except BaseException as exc:
            if old is not None and not out_dir.exists():
                old.rename(out_dir)
                old = None
            if tmp is not None:
                shutil.rmtree(tmp, ignore_errors=True)
            if isinstance(exc, OSError) and not isinstance(exc, UserInputError):
                # name the user's folder, not the hidden temporary one
                raise OSError(exc.errno, exc.strerror or str(exc), str(out_dir)) from exc
            raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return out_dir


def is_complete(folder) -> bool:
    """Whether ``folder`` holds a complete result (the one check ``--resume`` uses).

    Complete: the :data:`RESULT_MARKER` of a run, a non-empty
    ``timeseries.csv``, a ``metrics.json`` that reads with status ``ok`` or
    ``diverged``, and no ``PARTIAL`` file. Anything else is not.
    """
    folder = Path(folder)
    if (folder / PARTIAL_MARKER).exists() or result_kind(folder) != "run":
        return False
    try:
        if (folder / "timeseries.csv").stat().st_size == 0:
            return False
        doc = json.loads((folder / "metrics.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and doc.get("status") in ("ok", "diverged")


def _fmt(value, scale: float = 1.0, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value * scale:.{digits}f}"


def print_summary(metrics: Mapping, out_dir=None, file: TextIO | None = None) -> None:
    """Print a short table of the figures per axis and where the files are.

    Parameters
    ----------
    metrics : mapping
        :func:`simpro_mj.analysis.metrics.compute_metrics` output or a loaded ``metrics.json``.
    out_dir : path, optional
        The results folder (listed if given).
    file : text stream, optional
        Default ``sys.stdout``.
    """
    file = sys.stdout if file is None else file
    axes = metrics.get("axes", {})
    status = metrics.get("status")
    if status:
        reason = metrics.get("reason")
        print(f"status: {status}" + (f" ({reason})" if reason else ""), file=file)
    header = f"{'axis':<6} {'ss error':>14} {'rise [s]':>9} {'settling [s]':>13} {'overshoot':>10}"
    print(header, file=file)
    print("-" * len(header), file=file)
    for axis, unit, scale in (
        ("roll", "deg", 180.0 / math.pi),
        ("pitch", "deg", 180.0 / math.pi),
        ("heave", "mm", 1e3),
    ):
        m = axes.get(axis)
        if not m:
            continue
        sse = _fmt(m.get("steady_state_error"), scale, 4)
        sse = f"{sse} {unit}" if sse != "-" else sse
        over = _fmt(m.get("overshoot_pct"), 1.0, 1)
        over = f"{over} %" if over != "-" else over
        print(
            f"{axis:<6} {sse:>14} {_fmt(m.get('rise_time_s')):>9} "
            f"{_fmt(m.get('settling_time_s')):>13} {over:>10}",
            file=file,
        )
    window = metrics.get("final_window_s") or metrics.get("metrics", {}).get("final_window_s")
    if window:
        print(f"(ss error: mean of reference - true pose over {window[0]:.2f}..{window[1]:.2f} s)",
              file=file)  # fmt: skip
    if out_dir is not None:
        out_dir = Path(out_dir)
        listing = out_dir.iterdir() if out_dir.is_dir() else ()
        files = sorted(p.name for p in listing if not p.name.startswith("."))
        print(f"results: {out_dir}", file=file)
        if files:
            print("  " + ", ".join(files), file=file)
