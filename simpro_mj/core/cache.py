"""The on-disk cache of results that cost seconds and depend only on numbers.

Small JSON files under one folder per kind: ``$SIMPRO_CACHE_DIR/<kind>``, else
``$XDG_CACHE_HOME/simpro-sim/<kind>``, else ``~/.cache/simpro-sim/<kind>``.
A file is written under a temporary name and renamed, so concurrent runs (a
batch on threads or processes) never read half a file; a missing, damaged or
unwritable file only costs the work again; a damaged one is said in one line
(:func:`read_json`). The callers name each file by a
hash of everything the result depends on, the code that computes it included.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.messages import one_line
from simpro_mj.core.safe_files import open_regular, read_text


def cache_dir(kind: str) -> Path:
    """The folder of cached results of one ``kind`` (module docstring)."""
    root = os.environ.get("SIMPRO_CACHE_DIR")
    if root:
        return Path(root) / kind
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "simpro-sim" / kind


#: Largest cache file read (bytes): an entry is a few hundred.
MAX_BYTES = 1_000_000


def _no_nan(name: str) -> float:
    if name == "NaN":
        raise ValueError("NaN")
    return float(name)  # Infinity: an unconditionally stable loop's limit


def read_json(path: Path, check: Callable[[Any], Any] | None = None):
    """The document in ``path`` (``check(doc)`` when given), or None when it is
    missing or damaged: computed again, a damaged file with a one-line notice.

    Read by the read rule (:func:`simpro_mj.core.safe_files.read_text`: a FIFO or
    a device is refused at once, never waited on; at most :data:`MAX_BYTES`); no
    NaN; ``check`` raises ``ValueError``, ``KeyError`` or ``TypeError`` for a
    document of the wrong shape. Damaged: not a regular file, too large, not
    JSON, nested past the parser's depth, a NaN, or refused by ``check``.
    """
    path = Path(path)
    if not os.path.lexists(path):
        return None
    try:
        doc = json.loads(read_text(path, MAX_BYTES, "cache"), parse_constant=_no_nan)
        return doc if check is None else check(doc)
    except (OSError, UserInputError, ValueError, KeyError, TypeError, RecursionError) as exc:
        why = one_line(str(exc) or type(exc).__name__).split("; allowed")[0]
        why = why.split(f"{path}: ", 1)[-1][:120]
        notice(f"notice: cache file {path} is damaged ({why}); computing it again")
        return None


def notice(line: str) -> None:
    """One line on stderr, if there is a stderr (``2>&-`` closes it)."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        sys.stderr.write(line + "\n")


def write_json(path: Path, doc) -> None:
    """Write ``doc`` to ``path`` atomically; an unwritable cache is left alone."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=path.parent)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(doc, f, indent=1)
        os.replace(tmp, path)
    except OSError:
        pass  # no cache: the next run computes again


def _update(h, path) -> None:
    """Feed a file's bytes to the hash ``h``, a megabyte at a time (a regular file
    only: a FIFO is refused, never waited on)."""
    with open_regular(path, 1 << 40, "file", binary=True) as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)


def file_digest(path, strict: bool = False) -> str | None:
    """SHA-256 (hex) of one file's bytes, or None if it cannot be read (``strict``: raise)."""
    h = hashlib.sha256()
    try:
        _update(h, path)
    except (OSError, TypeError, ValueError, UserInputError):
        if strict:
            raise
        return None
    return h.hexdigest()


def source_digest(files) -> str:
    """SHA-256 of source files: a cache entry made by other code is not found."""
    h = hashlib.sha256()
    for path in sorted({str(f) for f in files}):
        _update(h, path)
    return h.hexdigest()
