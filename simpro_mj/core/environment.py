"""Environment variables that change how a run computes, checked before any work.

``SIMPRO_MODEL`` (another MJCF) is checked where it is read
(:func:`simpro_mj.core.shipped.model_path`); the thread counts here, because a
bad one breaks the compiled step deep inside numba (``NUMBA_NUM_THREADS=0``:
``ValueError`` at the first compile, an internal error).
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

#: Largest thread count accepted from the environment.
MAX_THREADS = 1024

#: Read by numba as a plain count (OpenMP's own variables allow lists: left to it).
_THREADS = "NUMBA_NUM_THREADS"


def environment_problem() -> str | None:
    """The one-line problem with the environment (``invalid value at NAME: ...``), or
    None. Thread counts must be whole numbers 1..:data:`MAX_THREADS` when set."""
    text = os.environ.get(_THREADS, "")
    if text.strip() and not (text.strip().isdigit() and 1 <= int(text) <= MAX_THREADS):
        return (
            f"invalid value at {_THREADS}: {text[:40]!r}; allowed: a whole number of "
            f"threads 1..{MAX_THREADS}, or unset"
        )
    return None


def _usable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return folder.is_dir() and os.access(folder, os.W_OK | os.X_OK)


def matplotlib_home() -> str | None:
    """Give matplotlib a writable folder when its own cannot be made.

    With ``MPLCONFIGDIR`` unset, matplotlib keeps its configuration and font cache in
    ``$XDG_CONFIG_HOME/matplotlib`` and ``$XDG_CACHE_HOME/matplotlib`` (``~/.config``,
    ``~/.cache``); where ``HOME`` is a file or read-only it makes a temporary folder and
    says so in two warnings on stderr, whatever ``--quiet`` asked. Here the same
    fallback is made without a word: a private temporary folder, removed at exit.
    Returns the folder set, or None (``MPLCONFIGDIR`` given, or the defaults usable).
    """
    if os.environ.get("MPLCONFIGDIR"):
        return None
    try:
        home = Path.home()
    except RuntimeError:  # no home directory at all
        home = None
    ok = home is not None
    for var, default in (("XDG_CONFIG_HOME", ".config"), ("XDG_CACHE_HOME", ".cache")):
        if not ok:
            break
        base = os.environ.get(var) or (str(home / default) if home else "")
        ok = bool(base) and _usable(Path(base) / "matplotlib")
    if ok:
        return None
    folder = tempfile.mkdtemp(prefix="simpro-matplotlib-")
    atexit.register(shutil.rmtree, folder, True)
    os.environ["MPLCONFIGDIR"] = folder
    return folder
