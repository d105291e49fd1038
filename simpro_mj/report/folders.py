"""Result folders on disk: whose they are, the write lock, the atomic install, complete or not.

Whose folder it is: the write rule
----------------------------------
A path is written only if it does not exist, or everything in it was written
by simpro-sim: the marker (:data:`RESULT_MARKER`) of a folder lists each file
simpro-sim wrote there with its size and SHA-256 (:func:`write_marker`,
:func:`record`), and :func:`foreign` finds every other file, and every listed
file that changed. A folder replaced whole (:func:`check_out`, kind ``run``,
``response``, ...) must hold nothing foreign; a folder filled in place
(:data:`IN_PLACE`: ``batch``, ``compare``) only the paths it writes must be
ours; a single file (:func:`check_file`, :func:`write_file`) must be listed
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

A folder is *complete* (:func:`is_complete`, what ``batch --resume`` may
trust) when its marker lists its files and they are all there and ours, its
``metrics.json`` reads with status ``ok`` or ``diverged`` and the blocks a
summary row needs, its ``timeseries.csv`` is not empty and there is no
``PARTIAL`` file.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import stat
import sys
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from simpro_mj import __version__
from simpro_mj.analysis.verdict import FINISHED_STATUSES
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.safe_files import open_regular, read_text
from simpro_mj.core.shipped import user_path

__all__ = [
    "PARTIAL_MARKER",
    "RESULT_MARKER",
    "check_file",
    "check_free",
    "check_out",
    "claim",
    "default_out",
    "folder_name",
    "foreign",
    "record",
    "install_figures",
    "install_folder",
    "is_complete",
    "locked",
    "partial_sibling",
    "record_file",
    "result_hash",
    "said_replacing",
    "result_kind",
    "write_file",
    "write_marker",
]

#: File name of the marker of an interrupted run's folder.
PARTIAL_MARKER = "PARTIAL"
#: File name of the marker of a folder simpro-sim wrote (and may replace).
RESULT_MARKER = ".simpro-result"
#: Largest marker read (bytes): a list of a few hundred files.
MARKER_MAX_BYTES = 1_000_000
#: Largest ``metrics.json`` read back (bytes).
MAX_METRICS_BYTES = 20_000_000
#: Our temporaries, moved-aside folders and locks: ``.<name>.simpro-tmp-*``,
#: ``.<name>.simpro-old-*``, ``.<name>.simpro-lock``, made beside the path they stand
#: for (:func:`hidden`); a user's ``.env.lock`` or ``.thesis.old-v2`` is never ours.
_HIDDEN = re.compile(r"^\..+\.simpro-(?:(?:tmp|old)-[A-Za-z0-9_]+(?:\.[a-z0-9]+)?|lock)$")


def hidden(path, what: str) -> str:
    """The name of our temporary (``what`` = ``tmp``, ``old``) or lock (``lock``)
    beside ``path``: a long name is cut and a digest of it added, so a legal
    250-character name still leaves room for the suffix."""
    name = Path(path).name
    if len(name) > 100:
        name = f"{name[:80]}~{hashlib.sha256(name.encode()).hexdigest()[:12]}"
    return f".{name}.simpro-{what}" + ("" if what == "lock" else "-")


def partial_sibling(out_dir: Path) -> Path:
    """``<name>.partial`` beside ``out_dir`` (``.partial-2``, ... if that is not ours):
    a folder of that name is ours only if it is a partial result by its marker
    (``PARTIAL`` listed), never a complete result a user named so."""
    for i in range(1, 100):
        cand = out_dir.with_name(f"{out_dir.name}.partial" + (f"-{i}" if i > 1 else ""))
        files = _manifest(_marker(cand)) or {}
        if not cand.exists() or (PARTIAL_MARKER in files and _replaceable(cand, "run")):
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
    raise UserInputError(f"no room at {_short(base)}: 999 results beside it; allowed: --out")


def said_replacing(out: Path, digest: str) -> None:
    """One line on stderr when ``out`` holds a result the run will replace."""
    kind = result_kind(out)
    if kind is not None:
        old, new = str(result_hash(out))[:12], digest[:12]
        same = "the same scenario" if old == new else f"scenario {old}..., now {new}..."
        sys.stderr.write(f"replacing the previous {kind} result in {_short(out)} ({same})\n")


def result_hash(folder) -> str | None:
    """The scenario hash in a run result's ``metrics.json``, or None."""
    if result_kind(folder) != "run":
        return None
    try:
        doc = json.loads(read_text(Path(folder) / "metrics.json", MAX_METRICS_BYTES, "metrics"))
        return str(doc["scenario"]["hash"])
    except (OSError, ValueError, TypeError, KeyError, RecursionError):
        return None


def _marker(folder) -> dict | None:
    """The marker document of ``folder`` (a dict), or None: absent, not a regular
    file (a FIFO is refused at once, never waited on), too large or not JSON."""
    try:
        doc = json.loads(read_text(Path(folder) / RESULT_MARKER, MARKER_MAX_BYTES, "marker"))
    except (OSError, ValueError, RecursionError):  # RecursionError: JSON nested too deep
        return None
    return doc if isinstance(doc, dict) else None


def result_kind(folder) -> str | None:
    """The kind (``run``, ``batch``, ``compare``, ...) in ``folder``'s marker, or None."""
    doc = _marker(folder)
    kind = doc.get("kind") if doc else None
    return kind if isinstance(kind, str) else None


def _manifest(doc: dict | None) -> dict | None:
    """The list of files in a marker (``files``: relative path -> entry), or None
    when the marker has none (a folder whose files cannot be verified)."""
    files = doc.get("files") if doc else None
    return files if isinstance(files, dict) else None


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with open_regular(path, 1 << 40, "result", binary=True) as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _entry(path: Path) -> dict:
    return {"size": path.stat().st_size, "sha256": _digest(path)}


def _walk(folder: Path, prefix: str = "") -> Iterator[tuple[str, Path, str]]:
    """(relative path, path, what) of the entries of ``folder`` a marker lists:
    regular files (``file``), sub-folders carrying their own marker (``result``),
    anything else (``other``: links, FIFOs, devices); the marker itself and our
    hidden temporaries are skipped; plain sub-folders are walked."""
    try:
        entries = sorted(os.scandir(folder), key=lambda e: e.name)
    except OSError:
        return
    for e in entries:
        rel = f"{prefix}{e.name}"
        if e.name == RESULT_MARKER or _HIDDEN.match(e.name):
            continue
        path = Path(e.path)
        if e.is_symlink():
            yield rel, path, "other"
        elif e.is_dir():
            if os.path.lexists(path / RESULT_MARKER):
                yield rel, path, "result"
            else:
                yield from _walk(path, rel + "/")
        elif e.is_file():
            yield rel, path, "file"
        else:
            yield rel, path, "other"


def _pending(files: dict, rel: str) -> bool:
    parts = rel.split("/")
    for i in range(1, len(parts) + 1):
        key = "/".join(parts[:i])
        for k in (key, key + "/"):
            entry = files.get(k)
            if isinstance(entry, dict) and entry.get("pending"):
                return True
    return False


def _matches(files: dict, rel: str, path: Path) -> bool:
    if _pending(files, rel):
        return True
    entry = files.get(rel)
    if not isinstance(entry, dict):
        return False
    try:
        return entry.get("size") == path.stat().st_size and entry.get("sha256") == _digest(path)
    except (OSError, ValueError):
        return False


def foreign(folder, only: Iterable[str] | None = None) -> list[str]:
    """Files under ``folder`` that simpro-sim did not write, or that changed since.

    A file is ours when the marker of its folder lists it (``files``: size and
    SHA-256 at the time we wrote it) and it still matches. A sub-folder with a
    marker of its own is another result: foreign to a folder replaced whole,
    checked against its own list when named in ``only`` (a batch's variants).
    Our hidden temporaries (:func:`hidden`) are ours. A folder whose marker
    holds no list has every file foreign.

    Parameters
    ----------
    folder : path
    only : iterable of str, optional
        Check only these relative paths (files or folders) instead of everything.

    Returns
    -------
    list of str
        Relative paths, ``name (changed since simpro-sim wrote it)`` for a
        listed file whose content differs, sorted.
    """
    folder = Path(folder)
    files = _manifest(_marker(folder)) or {}
    if only is None:
        items = list(_walk(folder))
    else:
        items = []
        for rel in only:
            path = folder / rel
            if not os.path.lexists(path):
                continue
            if path.is_dir() and not path.is_symlink():
                if os.path.lexists(path / RESULT_MARKER):
                    items.append((rel, path, "result"))
                else:
                    items.extend(_walk(path, rel.rstrip("/") + "/"))
            elif path.is_file() and not path.is_symlink():
                items.append((rel, path, "file"))
            else:
                items.append((rel, path, "other"))
    out = []
    for rel, path, what in items:
        if what == "result" and only is None:  # a result never inside another
            out.append(f"{rel}/ (a simpro-sim result of its own)")
        elif what == "result":
            out += [f"{rel}/{x}" for x in foreign(path)]
        elif what == "other" or not _matches(files, rel, path):
            listed = what == "file" and rel in files
            out.append(f"{rel} (changed since simpro-sim wrote it)" if listed else rel)
    return sorted(out)


def _write_marker_doc(folder: Path, doc: dict) -> None:
    """The marker written whole (temporary name, then renamed): a reader never
    sees half a list."""
    text = json.dumps(doc, sort_keys=True)
    fd, tmp = tempfile.mkstemp(prefix=hidden(RESULT_MARKER, "tmp"), dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, folder / RESULT_MARKER)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_marker(folder, kind: str) -> None:
    """Mark ``folder`` as a simpro-sim result of ``kind`` listing every file in it
    now (size and SHA-256; sub-folders with a marker of their own apart): what
    :func:`install_folder` calls on the finished temporary folder."""
    folder = Path(folder)
    files = {rel: _entry(path) for rel, path, what in _walk(folder) if what == "file"}
    _write_marker_doc(folder, {"kind": kind, "simpro-sim": __version__, "files": files})


def record(folder, rels: Iterable[str], kind: str, pending: bool = False) -> None:
    """Add ``rels`` (files or folders, relative to ``folder``) to ``folder``'s list of
    files written by simpro-sim, for a folder filled in place (``batch``,
    ``compare``, a video written into a result folder).

    With ``pending``, each is listed as about to be written (any content is
    ours until the next call lists what was written): a process killed between
    the write and the list leaves the file ours, not a stranger's.
    """
    folder = Path(folder)
    doc = _marker(folder)
    files = dict(_manifest(doc) or {}) if doc and doc.get("kind") == kind else {}
    for rel in rels:
        rel = rel.rstrip("/")
        for key in [k for k in files if k == rel or k.startswith(rel + "/")]:
            del files[key]
        path = folder / rel
        if pending:
            files[rel] = {"pending": True}
            continue
        if path.is_dir() and not path.is_symlink():
            for sub, p, what in _walk(path, rel + "/"):
                if what == "file":
                    files[sub] = _entry(p)
        elif path.is_file() and not path.is_symlink():
            files[rel] = _entry(path)
    _write_marker_doc(folder, {"kind": kind, "simpro-sim": __version__, "files": files})


def _lost(folder: Path, found: list[str]) -> str:
    shown = ", ".join(found[:5]) + (f" and {len(found) - 5} more" if len(found) > 5 else "")
    return _short(shown, 400)


def _replaceable(folder: Path, kind: str) -> bool:
    try:
        empty = not any(folder.iterdir())
    except OSError:
        return False
    return empty or (result_kind(folder) == kind and not foreign(folder))


def _abs(out, where: str = "--out") -> Path:
    """``out`` absolute, ``~`` and ``~USER`` expanded (an unknown user refused)."""
    return user_path(out, where).absolute()


def _short(path, limit: int = 200) -> str:
    text = str(path)
    return text if len(text) <= limit else f"{text[:90]}...{text[-90:]}"


#: Kinds filled in place (files added to an existing folder, never replaced whole):
#: only the paths they write must be theirs (``check_out(writes=...)``).
IN_PLACE = ("batch", "compare")


def _real_out(out: Path) -> Path:
    """``out`` with a symbolic link as its last part followed (the link is kept and
    the folder it names written); a dangling link is refused."""
    if out.is_symlink():
        if not out.exists():
            raise UserInputError(
                f"refused --out at {_short(out)}: a symbolic link to {_short(os.readlink(out))}, "
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
    out = _real_out(_abs(out))
    real = out.resolve()
    cwd = Path.cwd().resolve()
    if real == cwd or real in cwd.parents:
        raise UserInputError(
            f"refused --out at {_short(out)}: it is the working folder or holds it; "
            "allowed: a new folder, e.g. results/<name>"
        )
    for item in inputs:
        p = user_path(item, "scenario")
        if p.is_file() and p.resolve().is_relative_to(real):
            raise UserInputError(
                f"refused --out at {_short(out)}: it holds the input {_short(p)}; "
                "allowed: a folder apart from the scenario files"
            )
    if out.exists() and not out.is_dir():
        raise UserInputError(f"not a folder at {_short(out)}: allowed: a new or existing folder")
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
            f"refused --out at {_short(out)}: the folder holds files and is {what} "
            f"(no {RESULT_MARKER} of kind {kind}); nothing was touched; allowed: a new or "
            f"empty folder, or a simpro-sim {kind} result to replace"
        )
    lost = foreign(out, only=list(writes)) if kind in IN_PLACE else foreign(out)
    if lost:
        verb = "overwrite" if kind in IN_PLACE else "delete"
        raise UserInputError(
            f"refused --out at {_short(out)}: simpro-sim did not write {_lost(out, lost)} "
            f"(not in its {RESULT_MARKER} list of files); writing the {kind} result would "
            f"{verb} them; nothing was touched; allowed: move them out of the folder, or "
            "choose another --out"
        )
    return out


def check_free(out) -> None:
    """Refuse ``out`` while another process holds its write lock (:func:`locked`):
    what a batch checks of each variant before running it."""
    out = _abs(out)
    pid = _writer(out)
    if pid is not None:
        raise UserInputError(
            f"busy at {_short(out)}: another simpro-sim process (pid {pid}) is writing this "
            "folder; allowed: wait for it to end or choose another --out"
        )


def _check_inside_free(out: Path) -> None:
    """Refuse ``out`` holding a folder another process is writing (``run --out q``
    while ``run --out q/sub`` runs): its lock is inside ``out``."""
    ours = {Path(k).parent / hidden(k, "lock") for k in _HELD}
    for root, _dirs, names in os.walk(out):
        for name in names:
            if name.endswith(".simpro-lock") and Path(root, name) not in ours:
                pid = _lock_holder(Path(root) / name)
                if pid is not None:
                    raise UserInputError(
                        f"busy at {_short(out)}: another simpro-sim process (pid {pid}) is "
                        f"writing inside it ({_short(Path(root) / name[1:-12], 120)}); "
                        "allowed: wait for it to end or choose another --out"
                    )


def _check_parents_free(out: Path) -> None:
    """Refuse ``out`` inside a folder another process is writing (a ``run --out
    OUT/x`` while a batch writes ``OUT``), or inside a result (``run --out r/sub``
    with ``r`` a result): two writers never share a folder, a result never holds
    another."""
    for parent in out.parents:
        kind = result_kind(parent)
        if kind is not None:
            raise UserInputError(
                f"refused --out at {_short(out)}: it is inside the simpro-sim {kind} result "
                f"{_short(parent)}; nothing was touched; allowed: a folder outside any "
                "result, e.g. beside it"
            )
        pid = _writer(parent)
        if pid is not None:
            raise UserInputError(
                f"busy at {_short(out)}: another simpro-sim process (pid {pid}) is writing "
                f"{_short(parent)}, which holds it; allowed: wait for it to end or choose "
                "another --out"
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


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


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
    out = _abs(out)
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
def claim(
    out, kind: str = "run", inputs: Iterable = (), writes: Iterable[str] = ()
) -> Iterator[Path]:
    """:func:`check_out` then :func:`locked`, re-checked under the lock: what a
    command wraps around its whole job so that a refusal comes before any work.
    A folder inside one another process is writing is refused too (a ``run
    --out OUT/x`` while a batch writes ``OUT``)."""
    writes = list(writes)
    _check_parents_free(_real_out(_abs(out)))
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
    out_dir = _real_out(_abs(out_dir))
    with locked(out_dir):
        check_out(out_dir, kind)
        tmp: Path | None = None
        old = None
        try:
            tmp = Path(tempfile.mkdtemp(prefix=hidden(out_dir, "tmp"), dir=out_dir.parent))
            tmp.chmod(0o777 & ~_umask())  # mkdtemp's 0700 is for the temporary name only
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


def is_complete(folder) -> bool:
    """Whether ``folder`` holds a complete result (the one check ``--resume`` uses).

    Complete: the :data:`RESULT_MARKER` of a run listing ``metrics.json`` and a
    non-empty ``timeseries.csv``, every file it lists present and every file in
    the folder as simpro-sim wrote it (:func:`foreign` finds none), a
    ``metrics.json`` that reads with the status of a finished run (``ok``,
    ``limit_cycle``, ``not_settled``, ``diverged``) and the
    blocks a summary row is built from (``scenario`` with its hash, ``axes``),
    and no ``PARTIAL`` file. Anything
    else is not.
    """
    folder = Path(folder)
    if os.path.lexists(folder / PARTIAL_MARKER) or result_kind(folder) != "run":
        return False
    files = _manifest(_marker(folder)) or {}
    listed = files.get("timeseries.csv")
    if not isinstance(listed, dict) or not listed.get("size") or "metrics.json" not in files:
        return False
    if foreign(folder) or not all(os.path.isfile(folder / rel) for rel in files):
        return False  # a stranger's file, or one of ours gone
    try:
        doc = json.loads(read_text(folder / "metrics.json", MAX_METRICS_BYTES, "metrics"))
    except (OSError, ValueError, RecursionError):  # RecursionError: JSON nested too deep
        return False
    return (
        isinstance(doc, dict)
        and doc.get("status") in FINISHED_STATUSES
        and isinstance(doc.get("scenario"), dict)
        and isinstance(doc["scenario"].get("hash"), str)
        and isinstance(doc.get("axes"), dict)
    )


def check_file(path, overwrite: bool = False, option: str = "--out") -> Path:
    """Refuse a file path that is not simpro-sim's to write; return it absolute.

    A single output file (a calibrated preset, a video, a telemetry CSV) is
    written only if it does not exist, or the marker of its folder lists it as
    written by simpro-sim and it is unchanged (:func:`foreign`), or with
    ``overwrite`` (the user's explicit ``--overwrite``). A folder, a device, a
    dangling link, or a parent that is a file are refused whatever
    ``overwrite`` says. A link to a file is followed (the link is kept).

    Raises
    ------
    UserInputError
        Any of the above (nothing is touched).
    """
    path = _abs(path, "--out")
    if path.is_symlink():
        if not path.exists():
            raise UserInputError(
                f"refused {option} at {_short(path)}: a symbolic link to a file that does not "
                "exist; nothing was touched; allowed: a new file path"
            )
        path = path.resolve()
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise UserInputError(
                    f"cannot write at {option}: {_short(path)}: a parent is a file, not a "
                    "folder; allowed: a path in a folder"
                )
            if not os.access(parent, os.W_OK | os.X_OK):
                raise UserInputError(
                    f"cannot write at {option}: {_short(path)}: permission denied in "
                    f"{_short(parent)}; allowed: a writable path"
                )
            break
    if not os.path.lexists(path):
        return path
    if path.is_dir():
        raise UserInputError(
            f"refused {option} at {_short(path)}: it is a folder; allowed: a file path"
        )
    if not path.is_file():
        raise UserInputError(
            f"refused {option} at {_short(path)}: not a regular file; allowed: a new file path"
        )
    if overwrite or not foreign(path.parent, only=[path.name]):
        return path
    raise UserInputError(
        f"refused {option} at {_short(path)}: the file exists and simpro-sim did not write "
        f"it (or it changed since); nothing was touched; allowed: a new file, or "
        f"{option} with --overwrite to replace it"
    )


def record_file(path, created: bool = False) -> None:
    """List a file just written in its folder's marker (the marker's kind kept),
    so that the next run may replace it; a folder without a marker gets one
    (kind ``files``) only if simpro-sim ``created`` it: a user's folder is never
    given a marker."""
    path = Path(path).absolute()
    kind = result_kind(path.parent)
    if kind is None and not created:
        return
    with locked(path.parent):
        record(path.parent, [path.name], kind or "files")


def write_file(path, data: str | bytes, overwrite: bool = False, option: str = "--out") -> Path:
    """Write one output file by the rule of :func:`check_file`: under a temporary
    name in its folder, renamed into place, then listed (:func:`record_file`)."""
    path = check_file(path, overwrite, option)
    created = not path.parent.exists()
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=hidden(path, "tmp"), dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data.encode("utf-8") if isinstance(data, str) else data)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    record_file(path, created)
    return path
