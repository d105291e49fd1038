"""A readiness signal for whoever drives simpro-sim from outside.

When ``SIMPRO_READY_FILE`` names a path, a long command writes that file once
its signal handlers are installed and its work has begun, so that a test, a
supervisor or a script can send SIGINT/SIGTERM (or watch progress) without
guessing how long the start takes. The file holds one line, ``<what> <pid>``,
and appears whole (written under another name, then renamed).
"""

from __future__ import annotations

import os

#: Environment variable naming the readiness file.
ENV = "SIMPRO_READY_FILE"

_signalled: set[str] = set()


def signal_ready(what: str = "running") -> None:
    """Write the readiness file if ``SIMPRO_READY_FILE`` is set (once per process)."""
    path = os.environ.get(ENV)
    if not path or path in _signalled:
        return
    _signalled.add(path)
    # a hidden name beside it: a reader globbing for ready files never sees a half-written one
    folder, name = os.path.split(path)
    tmp = os.path.join(folder, f".{name}.{os.getpid()}.tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(f"{what} {os.getpid()}\n")
    os.replace(tmp, path)
