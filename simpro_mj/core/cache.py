"""The on-disk cache of results that cost seconds and depend only on numbers.

Small JSON files under one folder per kind: ``$SIMPRO_CACHE_DIR/<kind>``, else
``$XDG_CACHE_HOME/simpro-sim/<kind>``, else ``~/.cache/simpro-sim/<kind>``.
A file is written under a temporary name and renamed, so concurrent runs (a
batch on threads or processes) never read half a file; a missing, damaged or
unwritable file only costs the work again. The callers name each file by a
hash of everything the result depends on, the code that computes it included.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

__all__ = ["cache_dir", "file_digest", "read_json", "source_digest", "write_json"]


def cache_dir(kind: str) -> Path:
    """The folder of cached results of one ``kind`` (module docstring)."""
    root = os.environ.get("SIMPRO_CACHE_DIR")
    if root:
        return Path(root) / kind
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "simpro-sim" / kind


def read_json(path: Path):
    """The document in ``path``, or None if it is missing or not JSON."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


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
    """Feed a file's bytes to the hash ``h``, a megabyte at a time."""
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)


def file_digest(path) -> str | None:
    """SHA-256 (hex) of one file's bytes, or None if it cannot be read."""
    h = hashlib.sha256()
    try:
        _update(h, path)
    except (OSError, TypeError, ValueError):
        return None
    return h.hexdigest()


def source_digest(files) -> str:
    """SHA-256 of source files: a cache entry made by other code is not found."""
    h = hashlib.sha256()
    for path in sorted({str(f) for f in files}):
        _update(h, path)
    return h.hexdigest()
