"""Ctrl-C, SIGTERM and SIGHUP as ``KeyboardInterrupt``, never in the middle of an import.

A signal handler that raises ``KeyboardInterrupt`` raises it in whatever Python
code runs next. When that code runs inside the initialisation of a compiled
module (MuJoCo's bindings, parts of SciPy and Matplotlib are pybind11
modules), the extension turns the interrupt into ``ImportError:
initialization failed``, and CPython may also remember an "unhandled
interrupt" that makes the process die from SIGINT at exit whatever status the
program returned. Measured on this project before this module existed: of 30
batches sent Ctrl-C in their first 1.5 s, 2 reported the first variant
``failed: ImportError`` and then ran the next 600 s variant to its end, and 3
exited with -2 instead of 130.

So the modules are imported at the top of the modules that need them, and the
imports that load them run inside :func:`held_signals`: a signal that arrives
meanwhile, or while a block that must not be cut (a result folder being
written) runs, is *held* and raised as ``KeyboardInterrupt`` as soon as the
outermost such block ends. Those blocks are few and named: the command's
module with everything it imports (:func:`simpro_mj.commands.main.main`), a
run's simulation modules, MuJoCo's among them, once its input is known good
(:class:`simpro_mj.job.run.Run`), and a result folder with its figures
(:func:`simpro_mj.report.runner.execute`). No import hook: Python's own import
machinery is left as it is.

- :func:`interruptible` installs :func:`raise_or_hold` for SIGINT, SIGTERM and
  SIGHUP (the terminal closed: the same stop, the result written, the lock
  released; :func:`hung_up` says it came) for the duration of a command;
- :func:`held_signals` holds the signals for a block (it works with or
  without :func:`interruptible`, and in a pool worker whose SIGTERM handler
  calls :func:`raise_or_hold`);
- :func:`import_module` is :func:`importlib.import_module` under
  :func:`held_signals`.

Only the main thread holds: Python runs signal handlers there.
"""

from __future__ import annotations

import contextlib
import importlib
import signal
import threading

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

_holding = 0  # open held blocks in the main thread
_held: list[int] = []  # signals that arrived while holding
_hung_up = False  # a SIGHUP arrived: the terminal may be gone


def hung_up() -> bool:
    """Whether this process received SIGHUP (its terminal may be gone, so a failed
    write to it is nobody's loss)."""
    return _hung_up


def hold_aware(handler):
    """Mark a signal handler that calls :func:`raise_or_hold` itself, so that
    :func:`held_signals` leaves it in place (the pool workers' SIGTERM handler)."""
    handler.holds_signals = True
    return handler


def _interrupt(signum: int) -> KeyboardInterrupt:
    # SIGINT reads as Python's own Ctrl-C (no message); SIGTERM names itself
    if signum == signal.SIGINT:
        return KeyboardInterrupt()
    return KeyboardInterrupt(f"signal {signal.Signals(signum).name}")


@hold_aware
def raise_or_hold(signum, frame=None):  # noqa: ARG001 - signal handler signature
    """Signal handler: ``KeyboardInterrupt`` now, or when the held block ends."""
    global _hung_up
    _hung_up = _hung_up or signum == signal.SIGHUP
    if _holding:
        _held.append(signum)
        return
    raise _interrupt(signum)


@contextlib.contextmanager
def held_signals():
    """Within the block, SIGINT/SIGTERM are held; the first is raised as
    ``KeyboardInterrupt`` when the block (the outermost one) ends.

    A handler that is not hold-aware is replaced by :func:`raise_or_hold` for
    the block; an ignored signal stays ignored. Outside the main thread this is
    a no-op.
    """
    global _holding
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    for s in SIGNALS:
        h = signal.getsignal(s)
        if h is not signal.SIG_IGN and not getattr(h, "holds_signals", False):
            previous[s] = signal.signal(s, raise_or_hold)
    _holding += 1
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        _holding -= 1
        if _holding == 0 and _held:  # the outermost block: raise what arrived meanwhile
            signum = _held[0]
            _held.clear()
            raise _interrupt(signum)


class Interrupted(KeyboardInterrupt):
    """A signal that came while a result was written: the message says what was
    kept (:func:`writing`)."""


@contextlib.contextmanager
def writing(kept):
    """:func:`held_signals` around a result's write; a signal that came meanwhile is
    raised afterwards as :class:`Interrupted` with ``kept()``, one line saying
    what is on disk (a second Ctrl-C says what the first one kept)."""
    try:
        with held_signals():
            yield
    except KeyboardInterrupt as exc:
        if isinstance(exc, Interrupted):
            raise
        raise Interrupted(kept()) from None


def import_module(name: str):
    """:func:`importlib.import_module` with the signals held during the import."""
    with held_signals():
        return importlib.import_module(name)


@contextlib.contextmanager
def interruptible():
    """Within the block, SIGINT, SIGTERM and SIGHUP raise ``KeyboardInterrupt``
    (as Ctrl-C does), held within :func:`held_signals` (module docstring).

    The previous handlers are restored on exit; nested use is harmless.
    Outside the main thread this is a no-op.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, raise_or_hold) for s in SIGNALS}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
