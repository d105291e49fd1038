"""Whose files a folder holds: the marker simpro-sim writes, and a result complete or not.

The marker (:data:`RESULT_MARKER`) of a folder lists each file simpro-sim wrote
there with its size and SHA-256 (:func:`write_marker`, :func:`record`);
:func:`foreign` finds every other file, and every listed file that changed.
Our temporaries, moved-aside folders and locks carry hidden names beside the
path they stand for (:func:`hidden`). The write rule built on them, the lock
and the atomic install are :mod:`simpro_mj.report.folders`'.

A folder is *complete* (:func:`is_complete`, what ``batch --resume`` may
trust) when its marker lists its files and they are all there and ours, its
``metrics.json`` reads with status ``ok`` or ``diverged`` and the blocks a
summary row needs, its ``timeseries.csv`` is not empty (or ``metrics.json`` says it
was not asked for: :data:`TIMESERIES_WRITTEN`) and there is no ``PARTIAL`` file.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from simpro_mj import __version__
from simpro_mj.analysis.verdict import FINISHED_STATUSES
from simpro_mj.core.cache import file_digest
from simpro_mj.core.safe_files import read_text

__all__ = [
    "MAX_METRICS_BYTES",
    "PARTIAL_MARKER",
    "RESULT_MARKER",
    "TIMESERIES_WRITTEN",
    "foreign",
    "hidden",
    "is_complete",
    "manifest_of",
    "read_marker",
    "record",
    "replacing",
    "result_hash",
    "result_kind",
    "umask",
    "write_marker",
]

#: File name of the marker of an interrupted run's folder.
PARTIAL_MARKER = "PARTIAL"
#: File name of the marker of a folder simpro-sim wrote (and may replace).
RESULT_MARKER = ".simpro-result"
#: Key of ``metrics.json``, false when the run's ``timeseries.csv`` was not asked for
#: (a batch's ``--timeseries``); absent when it was written.
TIMESERIES_WRITTEN = "timeseries_written"
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


def result_hash(folder) -> str | None:
    """The scenario hash in a run result's ``metrics.json``, or None."""
    if result_kind(folder) != "run":
        return None
    try:
        doc = json.loads(read_text(Path(folder) / "metrics.json", MAX_METRICS_BYTES, "metrics"))
        return str(doc["scenario"]["hash"])
    except (OSError, ValueError, TypeError, KeyError, RecursionError):
        return None


def read_marker(folder) -> dict | None:
    """The marker document of ``folder`` (a dict), or None: absent, not a regular
    file (a FIFO is refused at once, never waited on), too large or not JSON."""
    try:
        doc = json.loads(read_text(Path(folder) / RESULT_MARKER, MARKER_MAX_BYTES, "marker"))
    except (OSError, ValueError, RecursionError):  # RecursionError: JSON nested too deep
        return None
    return doc if isinstance(doc, dict) else None


def result_kind(folder) -> str | None:
    """The kind (``run``, ``batch``, ``compare``, ...) in ``folder``'s marker, or None."""
    doc = read_marker(folder)
    kind = doc.get("kind") if doc else None
    return kind if isinstance(kind, str) else None


def manifest_of(doc: dict | None) -> dict | None:
    """The list of files in a marker (``files``: relative path -> entry), or None
    when the marker has none (a folder whose files cannot be verified)."""
    files = doc.get("files") if doc else None
    return files if isinstance(files, dict) else None


def _entry(path: Path) -> dict:
    return {"size": path.stat().st_size, "sha256": file_digest(path, strict=True)}


def _kind(path: Path) -> str:
    """What a marker makes of ``path``: a regular file (``file``), a sub-folder
    carrying its own marker (``result``), a plain sub-folder (``folder``), anything
    else (``other``: links, FIFOs, devices)."""
    if path.is_symlink():
        return "other"
    if path.is_dir():
        return "result" if os.path.lexists(path / RESULT_MARKER) else "folder"
    return "file" if path.is_file() else "other"


def _walk(folder: Path, prefix: str = "") -> Iterator[tuple[str, Path, str]]:
    """(relative path, path, :func:`_kind`) of the entries of ``folder`` a marker
    lists, plain sub-folders walked; the marker itself and our hidden temporaries
    are skipped."""
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return
    for name in names:
        path, rel = Path(folder, name), f"{prefix}{name}"
        if name == RESULT_MARKER or _HIDDEN.match(name):
            continue
        kind = _kind(path)
        if kind == "folder":
            yield from _walk(path, rel + "/")
        else:
            yield rel, path, kind


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
        return entry.get("size") == path.stat().st_size and entry.get("sha256") == file_digest(path)
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
    files = manifest_of(read_marker(folder)) or {}
    items = list(_walk(folder)) if only is None else []
    for rel in only or ():
        path = folder / rel
        if os.path.lexists(path):
            kind = _kind(path)
            if kind == "folder":
                items.extend(_walk(path, rel.rstrip("/") + "/"))
            else:
                items.append((rel, path, kind))
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


@contextlib.contextmanager
def replacing(path, suffix: str = "") -> Iterator[str]:
    """A hidden temporary file beside ``path`` (:func:`hidden`, ending ``suffix``) for
    the body to write; then given the umask's mode and renamed over ``path``, or
    removed if the body raises: a reader never sees half a file."""
    fd, tmp = tempfile.mkstemp(prefix=hidden(path, "tmp"), suffix=suffix, dir=Path(path).parent)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _write_marker_doc(folder: Path, doc: dict) -> None:
    """The marker written whole (:func:`replacing`): a reader never sees half a list."""
    with replacing(folder / RESULT_MARKER) as tmp:
        Path(tmp).write_text(json.dumps(doc, sort_keys=True) + "\n", encoding="utf-8")


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
    doc = read_marker(folder)
    files = dict(manifest_of(doc) or {}) if doc and doc.get("kind") == kind else {}
    for rel in rels:
        rel = rel.rstrip("/")
        for key in [k for k in files if k == rel or k.startswith(rel + "/")]:
            del files[key]
        path = folder / rel
        if pending:
            files[rel] = {"pending": True}
            continue
        what = _kind(path) if os.path.lexists(path) else None
        if what in ("folder", "result"):  # a result inside: its files listed here too
            files.update({sub: _entry(p) for sub, p, k in _walk(path, rel + "/") if k == "file"})
        elif what == "file":
            files[rel] = _entry(path)
    _write_marker_doc(folder, {"kind": kind, "simpro-sim": __version__, "files": files})


def umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def is_complete(folder) -> bool:
    """Whether ``folder`` holds a complete result (the one check ``--resume`` uses).

    Complete: the :data:`RESULT_MARKER` of a run listing ``metrics.json`` and a
    non-empty ``timeseries.csv`` (none, when ``metrics.json`` has
    :data:`TIMESERIES_WRITTEN` false), every file it lists present and every file in
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
    files = manifest_of(read_marker(folder)) or {}
    listed = files.get("timeseries.csv")
    written = isinstance(listed, dict) and bool(listed.get("size"))
    if "metrics.json" not in files or (listed is not None and not written):
        return False
    if foreign(folder) or not all(os.path.isfile(folder / rel) for rel in files):
        return False  # a stranger's file, or one of ours gone
    try:
        doc = json.loads(read_text(folder / "metrics.json", MAX_METRICS_BYTES, "metrics"))
    except (OSError, ValueError, RecursionError):  # RecursionError: JSON nested too deep
        return False
    return (
        isinstance(doc, dict)
        and (written or doc.get(TIMESERIES_WRITTEN) is False)
        and doc.get("status") in FINISHED_STATUSES
        and isinstance(doc.get("scenario"), dict)
        and isinstance(doc["scenario"].get("hash"), str)
        and isinstance(doc.get("axes"), dict)
    )
