"""Notices said once per batch: the same line from many variants, counted.

A run says what it does that takes time (``identifying the scenario's own plant
(Fig. 12) ...``) on stderr. In a batch the same line would come once per
variant; :func:`collecting` gathers them instead, on the thread that runs the
variant, and the batch prints each distinct line once with the number of
variants that said it. :func:`phase` tells the batch's progress line what the
variant's worker is doing (``identifying``, ``running``).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator

_local = threading.local()


class Collector:
    """The notices of one variant (text -> count) and a hook for its phases."""

    def __init__(self, on_phase: Callable[[str], None] | None = None):
        self.counts: dict[str, int] = {}
        self.on_phase = on_phase

    def add(self, text: str) -> None:
        self.counts[text] = self.counts.get(text, 0) + 1


@contextlib.contextmanager
def collecting(on_phase: Callable[[str], None] | None = None) -> Iterator[Collector]:
    """Gather this thread's notices (and phases) in a :class:`Collector` while inside."""
    previous = getattr(_local, "collector", None)
    _local.collector = c = Collector(on_phase)
    try:
        yield c
    finally:
        _local.collector = previous


def say(text: str, fallback: Callable[[str], None] | None = None) -> None:
    """Count ``text`` when this thread is collecting, else hand it to ``fallback``."""
    c = getattr(_local, "collector", None)
    if c is not None:
        c.add(text)
    elif fallback is not None:
        fallback(text)


def phase(name: str) -> None:
    """Tell the collecting batch, if any, what this thread's variant is doing."""
    c = getattr(_local, "collector", None)
    if c is not None and c.on_phase is not None:
        c.on_phase(name)
