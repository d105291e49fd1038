"""The compiled step loaded before a run's clock starts, with word of a first compile.

numba compiles the 1 ms step (:mod:`simpro_mj.sim.step`, made MuJoCo's control
callback by :mod:`simpro_mj.sim.callback`) when the callback module is first
imported: once per installation, 40-45 s on two cores, and then in
about a second from numba's on-disk cache. :func:`prepare_step` does that
import ahead of the simulation, so that

* a first run says what it is waiting for (one line, and a bar of the step's
  functions compiled so far on a terminal) instead of being silent,
* the compile is kept out of the run's ``wall_s`` and ``realtime_factor``
  (``metrics.json`` records it apart: ``kernel_load_s``, ``kernel_compiled``), and
* processes that start at once compile it once: the others wait for the first
  and load its cache (:func:`simpro_mj.sim.numba_cache.first_compile`).

A compile is recognised by numba's ``numba:compile`` events, which fire only
for a function that is not in the cache.
"""

from __future__ import annotations

import importlib
import sys
import threading
import time
from collections.abc import Callable

from simpro_mj.plant.kernels import kernel_choice

__all__ = ["COMPILE_NOTE", "note", "prepare_step"]

#: The callback module whose import compiles (or loads) the whole step.
CALLBACK_MODULE = "simpro_mj.sim.callback"

#: What a first run is told when numba starts compiling (stderr, one line).
COMPILE_NOTE = (
    "compiling the 1 ms step with numba: once per installation, under a minute "
    "on two cores (later runs load it from the cache in about a second)"
)

#: The packages whose functions make up the step (numba's own helpers are not counted).
_OWN = ("simpro_mj.", "controllers.")

_lock = threading.Lock()


def note(line: str) -> None:
    """A ``note: ...`` line on stderr (the commands' ``say``)."""
    sys.stderr.write(f"note: {line}\n")


class _Listener:
    """Counts the step's functions numba compiles; says so at the first one."""

    def __init__(self, say: Callable[[str], None] | None, bar: bool, total: int | None, own):
        self.say, self.bar_wanted, self.total, self.own = say, bar, total, tuple(own)
        self.done: set[str] = set()
        self.started = False
        self.bar = None

    def _name(self, ev) -> str | None:
        disp = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
        func = getattr(disp, "py_func", None)
        module = getattr(func, "__module__", "") or ""
        if func is None or not module.startswith(self.own):
            return None
        return f"{module}.{func.__qualname__}"

    def on_start(self, ev) -> None:
        if self.started:
            return
        self.started = True
        if self.say is not None:
            self.say(COMPILE_NOTE)
        if self.bar_wanted and self.say is not None:
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, desc="compiling the step", unit="function",
                            leave=False, file=sys.stderr)  # fmt: skip

    def on_end(self, ev) -> None:
        name = self._name(ev)
        if name is None or name in self.done:
            return
        self.done.add(name)
        if self.bar is not None:
            if self.total is not None and len(self.done) > self.total:
                self.bar.total = len(self.done)
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _expected_functions() -> int | None:
    """How many of the project's functions a compile of the whole step compiles."""
    from simpro_mj.sim import step

    plain = getattr(step, "_PLAIN", None)
    if plain is None:
        return None
    # the callback module's own two array views besides the step's functions
    return len({f"{f.__module__}.{f.__qualname__}" for f in plain}) + 2


def prepare_step(say: Callable[[str], None] | None = None, bar: bool = False) -> dict:
    """Load the compiled step into this process now, compiling it if it is not cached.

    Parameters
    ----------
    say : callable(str), optional
        Where the one-line note of a compile (or of a wait for another
        process's compile) goes (stderr in the commands); None: silent.
    bar : bool
        A tqdm bar of the step's functions compiled (a terminal only).

    Returns
    -------
    dict
        ``kernel_load_s``: the seconds this call waited for the compiled step
        (a compile, numba's cache loaded, or another thread's or process's compile;
        0 when it was loaded before in this process) and ``kernel_compiled``: whether
        numba compiled anything. Empty when the step runs interpreted
        (``SIMPRO_KERNEL=python``).
    """
    if kernel_choice() != "numba":
        return {}
    if CALLBACK_MODULE in sys.modules:
        return load_module(CALLBACK_MODULE, say, bar, _expected_functions, _OWN)
    from simpro_mj.sim import numba_cache, step

    t0 = time.perf_counter()
    # one process compiles a folder not yet complete; others wait, then load its cache
    with numba_cache.first_compile(step.compiled().cache_folder, say):
        got = load_module(CALLBACK_MODULE, say, bar, _expected_functions, _OWN)
    got["kernel_load_s"] = time.perf_counter() - t0  # a wait for another's compile included
    return got


def load_module(name: str, say, bar: bool, expected: Callable[[], int | None], own) -> dict:
    """Import module ``name`` (once per process) with word of what numba compiles meanwhile.

    ``expected()``: how many functions of the packages ``own`` its import compiles
    (None: unknown), the bar's total. Returns what :func:`prepare_step` does.
    """
    t0 = time.perf_counter()
    with _lock:
        if name in sys.modules:
            return {"kernel_load_s": time.perf_counter() - t0, "kernel_compiled": False}
        from numba.core import event

        listener = _Listener(say, bar, expected(), own)

        class _Hook(event.Listener):
            def on_start(self, ev):
                listener.on_start(ev)

            def on_end(self, ev):
                listener.on_end(ev)

        hook = _Hook()
        event.register("numba:compile", hook)
        try:
            importlib.import_module(name)
        finally:
            event.unregister("numba:compile", hook)
            listener.close()
        seconds = time.perf_counter() - t0
        if listener.started and say is not None:
            say(f"compiled the step in {seconds:.1f} s ({len(listener.done)} functions)")
        return {"kernel_load_s": seconds, "kernel_compiled": listener.started}
