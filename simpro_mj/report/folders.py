"""Result folders on disk: the write rule, the write lock, the atomic install.

Whose folder it is: the write rule
----------------------------------
A path is written only if it does not exist, or everything in it was written
by simpro-sim and is unchanged (:func:`~simpro_mj.report.marker.foreign`, by
the folder's marker). A folder replaced whole (:func:`check_out`, kind ``run``,
``response``, ...) must hold nothing foreign; a folder filled in place
(:data:`IN_PLACE`: ``batch``, ``compare``) only the paths it writes must be
ours; a single file (:mod:`simpro_mj.report.single_files`) must be listed
in its folder's marker, or the user says ``--overwrite``. Anything else is
refused (a user's mistake, exit 2, naming what would be lost) and nothing is
touched, as is an ``--out`` that is the working folder (or one above it),
holds the scenario file, or is a dangling link. A writer holds an exclusive
lock (:func:`locked`: ``flock`` on a hidden ``.<name>.simpro-lock`` beside the
folder) from its first check to the end of the write, so a second writer of
the same folder is refused, not raced; :func:`claim` also refuses a folder
inside a result or one another process is writing, or holding one.

Atomic install
--------------
The folder is written under a temporary name (``.<name>.simpro-tmp-*``) next to
``out_dir`` and renamed into place when complete. An existing ``out_dir`` is
first renamed aside (``.<name>.simpro-old-*``) and deleted only after the new folder
is in place; if anything (an exception, Ctrl-C) stops the write before that,
the temporary folder is removed and the previous folder put back. So a reader
never sees a truncated file under ``out_dir`` (on POSIX, ``out_dir`` is
briefly absent between the two renames: directories cannot be swapped
atomically there). A process killed outright (SIGKILL, power loss) can leave
a hidden temporary folder, never a half-written ``out_dir``. An interrupted
run never replaces a complete result: its partial result goes beside it, to
``<name>.partial`` (:func:`write_results` returns where it went). An
``OSError`` (read-only or full disk) names ``out_dir``, not a temporary name.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import shutil
import stat
import sys
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.safe_files import short
from simpro_mj.core.shipped import user_path
from simpro_mj.report.marker import (
    PARTIAL_MARKER,
    RESULT_MARKER,
    foreign,
    hidden,
    manifest_of,
    read_marker,
    result_hash,
    result_kind,
    umask,
    write_marker,
)


def partial_sibling(out_dir: Path) -> Path:
    """``<name>.partial`` beside ``out_dir`` (``.partial-2``, ... if that is not ours):
    a folder of that name is ours only if it is a partial result by its marker
    (``PARTIAL`` listed), never a complete result a user named so."""
    for i in range(1, 100):
        cand = out_dir.with_name(f"{out_dir.name}.partial" + (f"-{i}" if i > 1 else ""))
        files = manifest_of(read_marker(cand)) or {}
        if not cand.exists() or (
            PARTIAL_MARKER in files and result_kind(cand) == "run" and not foreign(cand)
        ):
            return cand
    raise UserInputError(
        f"no room at {out_dir}: 99 .partial folders beside it; allowed: remove some"
    )


def folder_name(text: str) -> str:
    """``text`` as a folder name: letters, digits and ``._=,+-`` kept, the rest ``_``;
    over 120 characters cut, a digest of the whole added."""
    name = re.sub(r"[^\w.=,+-]+", "_", text).lstrip(".") or "_"
    if len(name) > 120:
        name = f"{name[:100]}~{hashlib.sha256(name.encode()).hexdigest()[:12]}"
    return name


def default_out(base: Path, sets: Iterable[str], digest: str) -> Path:
    """Where a run goes without ``--out``: ``base`` (``results/<name>``) followed by
    its overrides (``results/step_pitch+controller.mode=joint_only``), and a number
    (``-2``, ``-3``, ...) past a folder holding anything but a result of the same
    scenario (SHA-256 ``digest``): a run never silently replaces another's results."""
    stem = folder_name(base.name + "".join(f"+{s}" for s in sets))
    for i in range(1, 1000):
        cand = base.with_name(stem + (f"-{i}" if i > 1 else ""))
        if not os.path.lexists(cand) or result_hash(cand) == digest:
            return cand
    raise UserInputError(f"no room at {short(base)}: 999 results beside it; allowed: --out")


def said_replacing(out: Path, digest: str) -> None:
    """One line on stderr when ``out`` holds a result the run will replace."""
    kind = result_kind(out)
    if kind is not None:
        old, new = str(result_hash(out))[:12], digest[:12]
        same = "the same scenario" if old == new else f"scenario {old}..., now {new}..."
        sys.stderr.write(f"replacing the previous {kind} result in {short(out)} ({same})\n")


def out_path(out, where: str = "--out") -> Path:
    """``out`` absolute, ``~`` and ``~USER`` expanded (an unknown user refused)."""
    return user_path(out, where).absolute()


#: Kinds filled in place (files added to an existing folder, never replaced whole):
#: only the paths they write must be theirs (``check_out(writes=...)``).
IN_PLACE = ("batch", "compare")


def _real_out(out: Path) -> Path:
    """``out`` with a symbolic link as its last part followed (the link is kept and
    the folder it names written); a dangling link is refused."""
    if out.is_symlink():
        if not out.exists():
            raise UserInputError(
                f"refused --out at {short(out)}: a symbolic link to {short(os.readlink(out))}, "
                "which does not exist; nothing was touched; allowed: a new folder, or a link "
                "to an existing folder"
            )
        return out.resolve()
    return out


def check_out(out, kind: str = "run", inputs: Iterable = (), writes: Iterable[str] = ()) -> Path:
    """Refuse an output folder that is not simpro-sim's to write; return it absolute.

    Parameters
    ----------
    out : path
        The ``--out`` folder.
    kind : str
        What will be written there (``run``, ``batch``, ``compare``, ...): an
        existing folder must be empty or carry the marker of this kind with
        every file in it ours (:func:`foreign`); for a kind filled in place
        (:data:`IN_PLACE`) only the paths in ``writes`` must be ours.
    inputs : iterable of paths
        Files the command reads (the scenario): ``out`` must not hold them.
    writes : iterable of str
        For :data:`IN_PLACE` kinds: the relative paths the command writes.

    Raises
    ------
    UserInputError
        ``out`` is a file, a dangling link, the working folder or one above
        it, holds an input, or is a non-empty folder not ours to write
        (nothing is touched).
    """
    out = _real_out(out_path(out))
    real = out.resolve()
    cwd = Path.cwd().resolve()
    if real == cwd or real in cwd.parents:
        raise UserInputError(
            f"refused --out at {short(out)}: it is the working folder or holds it; "
            "allowed: a new folder, e.g. results/<name>"
        )
    for item in inputs:
        p = user_path(item, "scenario")
        if p.is_file() and p.resolve().is_relative_to(real):
            raise UserInputError(
                f"refused --out at {short(out)}: it holds the input {short(p)}; "
                "allowed: a folder apart from the scenario files"
            )
    if out.exists() and not out.is_dir():
        raise UserInputError(f"not a folder at {short(out)}: allowed: a new or existing folder")
    if not out.is_dir():
        return out
    try:
        empty = not any(out.iterdir())
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(out)) from exc
    if empty:
        return out
    if kind not in IN_PLACE:  # a batch checks each variant's lock before it runs it
        _check_inside_free(out)
    found = result_kind(out)
    if found != kind:
        what = f"a simpro-sim {found} result" if found else "not a simpro-sim result"
        raise UserInputError(
            f"refused --out at {short(out)}: the folder holds files and is {what} "
            f"(no {RESULT_MARKER} of kind {kind}); nothing was touched; allowed: a new or "
            f"empty folder, or a simpro-sim {kind} result to replace"
        )
    lost = foreign(out, only=list(writes)) if kind in IN_PLACE else foreign(out)
    if lost:
        verb = "overwrite" if kind in IN_PLACE else "delete"
        more = f" and {len(lost) - 5} more" if len(lost) > 5 else ""
        raise UserInputError(
            f"refused --out at {short(out)}: simpro-sim did not write "
            f"{short(', '.join(lost[:5]) + more, 400)} "
            f"(not in its {RESULT_MARKER} list of files); writing the {kind} result would "
            f"{verb} them; nothing was touched; allowed: move them out of the folder, or "
            "choose another --out"
        )
    return out


def check_free(out) -> None:
    """Refuse ``out`` while another process holds its write lock (:func:`locked`):
    what a batch checks of each variant before running it."""
    out = out_path(out)
    pid = _writer(out)
    if pid is not None:
        raise _busy(out, pid, "this folder")


def _check_inside_free(out: Path) -> None:
    """Refuse ``out`` holding a folder another process is writing (``run --out q``
    while ``run --out q/sub`` runs): its lock is inside ``out``."""
    ours = {Path(k).parent / hidden(k, "lock") for k in _HELD}
    for root, _dirs, names in os.walk(out):
        for name in names:
            if name.endswith(".simpro-lock") and Path(root, name) not in ours:
                pid = _lock_holder(Path(root) / name)
                if pid is not None:
                    inside = short(Path(root) / name[1:-12], 120)
                    raise _busy(out, pid, f"inside it ({inside})")


def _check_parents_free(out: Path) -> None:
    """Refuse ``out`` inside a folder another process is writing (a ``run --out
    OUT/x`` while a batch writes ``OUT``), or inside a result (``run --out r/sub``
    with ``r`` a result): two writers never share a folder, a result never holds
    another."""
    for parent in out.parents:
        kind = result_kind(parent)
        if kind is not None:
            raise UserInputError(
                f"refused --out at {short(out)}: it is inside the simpro-sim {kind} result "
                f"{short(parent)}; nothing was touched; allowed: a folder outside any "
                "result, e.g. beside it"
            )
        pid = _writer(parent)
        if pid is not None:
            raise _busy(out, pid, f"{short(parent)}, which holds it")


def _busy(out: Path, pid: str, what: str) -> UserInputError:
    """The refusal of ``out`` while process ``pid`` writes ``what``."""
    return UserInputError(
        f"busy at {short(out)}: another simpro-sim process (pid {pid}) is writing {what}; "
        "allowed: wait for it to end or choose another --out"
    )


def _writer(folder: Path) -> str | None:
    """The pid of another process holding ``folder``'s write lock, else None."""
    lock = folder.parent / hidden(folder, "lock")
    if str(folder) in _HELD or not os.path.lexists(lock):
        return None
    return _lock_holder(lock)


def _lock_holder(lock: Path) -> str | None:
    """The pid in a lock file whose ``flock`` another process holds, else None."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return None
    try:
        fd = os.open(lock, os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return os.read(fd, 32).decode("ascii", "replace").strip() or "?"
        return None
    finally:
        os.close(fd)


_HELD: dict[str, list] = {}


@contextlib.contextmanager
def locked(out) -> Iterator[Path]:
    """Hold the exclusive write lock of folder ``out`` (reentrant in this process).

    The lock is ``flock`` on ``.<name>.simpro-lock`` beside ``out``, holding the
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
    out = out_path(out)
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
    path = out.parent / hidden(out, "lock")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = os.read(fd, 32).decode("ascii", "replace").strip() or "?"
                os.close(fd)
                raise _busy(out, pid, "this folder") from None
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
def claim(
    out, kind: str = "run", inputs: Iterable = (), writes: Iterable[str] = ()
) -> Iterator[Path]:
    """:func:`check_out` then :func:`locked`, re-checked under the lock: what a
    command wraps around its whole job so that a refusal comes before any work.
    A folder inside one another process is writing is refused too (a ``run
    --out OUT/x`` while a batch writes ``OUT``)."""
    writes = list(writes)
    _check_parents_free(_real_out(out_path(out)))
    check_free(out)
    out = check_out(out, kind, inputs, writes)
    with locked(out):
        yield check_out(out, kind, inputs, writes)


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
    out_dir = _real_out(out_path(out_dir))
    with locked(out_dir):
        check_out(out_dir, kind)
        tmp: Path | None = None
        old = None
        try:
            tmp = Path(tempfile.mkdtemp(prefix=hidden(out_dir, "tmp"), dir=out_dir.parent))
            tmp.chmod(0o777 & ~umask())  # mkdtemp's 0700 is for the temporary name only
            fill(tmp)
            write_marker(tmp, kind)
            if out_dir.exists():
                old = Path(tempfile.mkdtemp(prefix=hidden(out_dir, "old"), dir=out_dir.parent))
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


def install_figures(out_dir, draw, kind: str) -> list[Path]:
    """:func:`install_folder` for a command whose ``draw(tmp)`` writes figures and
    returns their paths; returns them under ``out_dir``."""
    drawn: list = []

    def fill(tmp: Path) -> None:
        drawn.extend(Path(f).name for f in draw(tmp) or ())

    out_dir = install_folder(out_dir, fill, kind=kind)
    return [out_dir / name for name in drawn]
