"""Standard output and error that say which of them failed.

A command writes its result files, then prints. When the printing fails, the
error must name the stream, not the output folder (``run ... > /dev/full``
said ``cannot access at --out``); a closed stderr (``2>&-``, which leaves
``sys.stderr`` None) must not turn a refusal into a crash; and once the
terminal has hung up (SIGHUP, :func:`simpro_mj.core.interrupts.hung_up`) a
failed write is nobody's loss and is dropped.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator

from simpro_mj.core.interrupts import hung_up


class StreamError(OSError):
    """A write to stdout or stderr failed; ``filename`` is ``<stdout>`` or ``<stderr>``."""


class _Named:
    """A text stream that remembers its first failed write instead of stopping the
    command (whose files come first) and raises it, named, at :meth:`check`."""

    def __init__(self, raw, name: str):
        self._raw, self._name = raw, name
        self._error: OSError | None = None

    def _failed(self, exc: OSError) -> None:
        if isinstance(exc, BrokenPipeError) and not hung_up():
            raise exc  # a reader that stopped (| head): exit 141, its own case
        self._error = self._error or exc

    def write(self, text):
        try:
            return self._raw.write(text)
        except OSError as exc:
            self._failed(exc)
            return len(text)

    def flush(self):
        try:
            self._raw.flush()
        except OSError as exc:
            self._failed(exc)

    def check(self) -> None:
        """Raise :class:`StreamError` if a write failed (not after SIGHUP: the
        terminal is gone, nobody reads it)."""
        self.flush()
        exc = self._error
        if exc is not None and not hung_up():
            raise StreamError(exc.errno, exc.strerror or str(exc), f"<{self._name}>")

    def __getattr__(self, name):
        return getattr(self._raw, name)


@contextlib.contextmanager
def standard_streams() -> Iterator[None]:
    """Within the block, ``sys.stdout`` and ``sys.stderr`` name themselves when a write
    fails; a closed one (None) writes to the null device. Restored on exit."""
    for fd in (0, 1, 2):  # a closed descriptor would be the next file opened
        try:
            os.fstat(fd)
        except OSError:
            os.open(os.devnull, os.O_RDWR)  # the lowest free descriptor: this one
    saved = sys.stdout, sys.stderr
    null = None
    for attr in ("stdout", "stderr"):
        raw = getattr(sys, attr)
        if raw is None:
            null = null or open(os.devnull, "w", encoding="utf-8")  # noqa: SIM115
            raw = null
        setattr(sys, attr, _Named(raw, attr))
    try:
        yield
    finally:
        sys.stdout, sys.stderr = saved
        if null is not None:
            null.close()
