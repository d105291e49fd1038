"""Worker processes that stop with their batch and never outlive it.

``simpro-sim batch`` and ``simpro-sim bench`` run variants in a
``ProcessPoolExecutor`` of worker processes (forked from a forkserver, or spawned:
:func:`simpro_mj.sim.executors.pool_context`). Each worker starts with
:func:`init_worker` (the pool's ``initializer``), which

* ignores SIGINT and SIGHUP: Ctrl-C or a closed terminal reaches the whole
  process group, and
  the parent decides what stops (it sends SIGTERM, :func:`stop_pool`);
* turns SIGTERM into ``KeyboardInterrupt`` while a task runs
  (:func:`run_task`; held while a run loads its simulation modules or writes
  its folder, see :mod:`simpro_mj.core.interrupts`): the simulation hands back what it computed, the
  variant's folder is written marked ``PARTIAL`` and the worker exits (it
  takes no further task, not even one the pool had queued); an idle worker
  exits at once;
* keeps the queue it was given (:func:`activity_queue`), on which a task may
  say what it is doing for its parent's progress line;
* takes its batch's environment (``os.environ`` as the batch had it when the pool
  started: a worker forked from a forkserver started earlier would otherwise hold
  the forkserver's);
* starts a watchdog thread that checks, every :data:`POLL_S`, that the batch is
  alive: by the batch's end of a pipe only the batch holds open
  (:func:`alive_pipe`; it reads at its end when the batch is gone, whatever
  process the worker was forked from) or, without one, by ``os.getppid()``
  (a spawned worker is re-parented when its parent dies). When the batch is gone
  (``kill -9``, a crash) an idle worker exits at once, a busy one sends itself
  SIGTERM (its variant writes what it had) and exits when the task returns,
  or outright :data:`GRACE_S` later. No worker keeps running, or idles, after
  its batch.
"""

from __future__ import annotations

import contextlib
import importlib.machinery
import os
import signal
import sys
import threading
import time

from simpro_mj.core.interrupts import hold_aware, raise_or_hold
from simpro_mj.sim.readiness import ENV

#: How often a worker checks that its parent is alive (s).
POLL_S = 0.5
#: How long a stopped worker may take to write its partial result (s) before SIGKILL.
GRACE_S = 30.0

_busy = False
_ending = False  # SIGTERM received or parent gone: no further task
_activity = None  # the parent's queue of what this worker is doing, if it gave one


def activity_queue():
    """The queue this worker's parent reads what its workers are doing from, or None."""
    return _activity


@contextlib.contextmanager
def main_not_imported():
    """Workers started in this block do not import the caller's main script.

    A spawned process imports the parent's ``__main__`` script (as ``__mp_main__``) so
    that functions defined there can be unpickled. The workers' functions live in
    ``simpro_mj``; a script that calls ``simpro_mj.sweep(..., jobs=2, processes=True)``
    at its top level, unguarded, would run again in every worker (each trying to start a pool of its
    own, which breaks the pool). ``multiprocessing`` skips that import when
    ``__main__.__spec__.name`` is ``"__main__"``: a script's module has no spec, one
    is set while the workers start and removed after. A program run with
    ``python -m`` (a spec of its own) and an interactive session (no file) are left
    as they are.
    """
    main = sys.modules.get("__main__")
    if main is None or getattr(main, "__spec__", None) is not None:
        yield
        return
    main.__spec__ = importlib.machinery.ModuleSpec("__main__", None)
    try:
        yield
    finally:
        main.__spec__ = None


@hold_aware
def _on_sigterm(signum, frame):
    global _ending
    _ending = True
    if _busy:
        raise_or_hold(signum, frame)  # KeyboardInterrupt, not while importing
        return
    os._exit(128 + signum)


def alive_pipe():
    """``(reader, writer)``: the batch keeps ``writer`` open while its workers live
    and gives them ``reader`` (:func:`init_worker`); nothing is ever written, so
    ``reader`` becomes readable (end of file) only when every ``writer`` is closed:
    the batch ended or died. The pipe's ends are not inherited by other processes
    (PEP 446), and forked workers get only the reader."""
    import multiprocessing

    return multiprocessing.Pipe(duplex=False)


def init_worker(parent_pid: int, activity=None, alive=None, environ=None) -> None:
    """Pool initializer: the signal handling, the batch's environment, the batch
    watchdog and the activity queue (module docstring).

    ``alive``: the reader of :func:`alive_pipe` (else the worker watches
    ``os.getppid()``); ``environ``: the batch's ``os.environ``. With
    ``SIMPRO_READY_FILE`` set, the worker's own readiness file (its variant is
    stepping) is ``<file>.worker-<pid>``, so it never stands for the parent's.
    """

    global _activity
    _activity = activity
    if environ is not None and dict(os.environ) != dict(environ):
        os.environ.clear()
        os.environ.update(environ)
    if os.environ.get(ENV):
        os.environ[ENV] = f"{os.environ[ENV]}.worker-{os.getpid()}"
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)  # the terminal's: the parent decides
    signal.signal(signal.SIGTERM, _on_sigterm)
    watch_parent(parent_pid, alive=alive)


def watch_parent(
    parent_pid: int, poll_s: float = POLL_S, grace_s: float = GRACE_S, alive=None
) -> None:
    """Start a daemon thread that ends this process when its batch is gone (SIGTERM
    to itself, then ``os._exit`` after ``grace_s``): ``alive`` (the reader of
    :func:`alive_pipe`) at its end, or, without it, ``parent_pid`` no longer this
    process's parent."""

    def gone() -> bool:
        if alive is None:
            time.sleep(poll_s)
            return os.getppid() != parent_pid
        try:
            return alive.poll(poll_s)  # readable: end of file, the batch's end closed
        except (OSError, EOFError, ValueError):
            return True

    def watch() -> None:
        global _ending
        while not gone():
            pass
        _ending = True  # run_task exits once the variant has written what it had
        if not _busy:
            os._exit(1)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(grace_s)
        os._exit(1)

    threading.Thread(target=watch, name="simpro-parent-watch", daemon=True).start()


def run_task(fn, *args):
    """Run ``fn(*args)`` in a worker as a task: SIGTERM interrupts it (module docstring)."""
    global _busy
    if _ending:  # a task queued before the stop (the pool prefetches one)
        os._exit(1)
    _busy = True
    try:
        return fn(*args)  # SIGTERM is held where a run imports (core.interrupts)
    finally:
        _busy = False
        if _ending:  # stopped: the partial result is written, nobody collects it
            os._exit(1)


def stop_pool(pool, grace_s: float = GRACE_S) -> None:
    """Stop a ``ProcessPoolExecutor`` now and wait until its workers are gone.

    Tasks not started are cancelled; every live worker gets SIGTERM (a running
    variant ends ``interrupted`` and writes its partial folder; an idle worker
    exits), and any still alive after ``grace_s`` (or at a second Ctrl-C) is
    killed.
    """
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(OSError, ValueError):
            if p.is_alive():
                p.terminate()
    try:
        deadline = time.monotonic() + grace_s
        for p in procs:
            p.join(max(0.0, deadline - time.monotonic()))
    except KeyboardInterrupt:
        pass  # a second Ctrl-C: no more waiting
    finally:
        for p in procs:
            with contextlib.suppress(OSError, ValueError):
                if p.is_alive():
                    p.kill()
                    p.join(5.0)
