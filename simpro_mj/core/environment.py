"""Environment variables that change how a run computes, checked before any work.

``SIMPRO_MODEL`` (another MJCF) is checked where it is read
(:func:`simpro_mj.core.shipped.model_path`); the thread counts here, because a
bad one breaks the compiled step deep inside numba (``NUMBA_NUM_THREADS=0``:
``ValueError`` at the first compile, an internal error).
"""

from __future__ import annotations

import os

__all__ = ["MAX_THREADS", "environment_problem"]

#: Largest thread count accepted from the environment.
MAX_THREADS = 1024

#: Read by numba as a plain count (OpenMP's own variables allow lists: left to it).
_THREADS = ("NUMBA_NUM_THREADS",)


def environment_problem() -> str | None:
    """The one-line problem with the environment (``invalid value at NAME: ...``), or
    None. Thread counts must be whole numbers 1..:data:`MAX_THREADS` when set."""
    for name in _THREADS:
        text = os.environ.get(name)
        if text is None or text.strip() == "":
            continue
        if not (text.strip().isdigit() and 1 <= int(text) <= MAX_THREADS):
            return (
                f"invalid value at {name}: {text[:40]!r}; allowed: a whole number of "
                f"threads 1..{MAX_THREADS}, or unset"
            )
    return None
