"""Result folders on disk: whose they are, the write lock, the atomic install, complete or not.

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
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from simpro_mj import __version__
from simpro_mj.core.errors import UserInputError

__all__ = [
    "PARTIAL_MARKER",
    "RESULT_MARKER",
    "check_out",
    "claim",
    "install_folder",
    "is_complete",
    "locked",
    "partial_sibling",
    "result_kind",
    "write_marker",
]

#: File name of the marker of an interrupted run's folder.
PARTIAL_MARKER = "PARTIAL"
#: File name of the marker of a folder simpro-sim wrote (and may replace).
RESULT_MARKER = ".simpro-result"


def partial_sibling(out_dir: Path) -> Path:
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
