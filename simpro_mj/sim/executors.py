"""The executors of many simulations: here, threads of this process, a process pool, or Dask.

``simpro-sim batch`` (:mod:`simpro_mj.batch.runner`) and ``simpro-sim response``
(:mod:`simpro_mj.analysis.response`) run their tasks through :func:`run_tasks` with their
own worker function: a task is plain data (it pickles to a pool worker or a
Dask worker), a worker function is top level in its module (it pickles by
name). Pool workers end themselves if their parent dies (:mod:`simpro_mj.sim.workers`);
readiness is signalled once the tasks are submitted
(:mod:`simpro_mj.sim.readiness`). No command lives here.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import (
    FIRST_COMPLETED,
    ProcessPoolExecutor,
    ThreadPoolExecutor,
    wait,
)

from tqdm import tqdm

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.messages import one_line
from simpro_mj.sim.readiness import signal_ready
from simpro_mj.sim.workers import (
    alive_pipe,
    init_worker,
    main_not_imported,
    run_task,
    stop_pool,
)

#: A Dask run whose cluster has had no live worker this long (s) ends with an error.
NO_WORKERS_S = 60.0
#: Most worker processes (``--jobs``); a run never starts more than it has tasks.
MAX_JOBS = 256
#: The longest (s) the main thread waits for a task of :func:`run_threads` or
#: :func:`run_pool` without running Python code: how late, at most, it acts on a signal
#: the kernel gave another thread (:func:`_completed`).
WAKE_S = 0.1


class Progress:
    """tqdm bar with ok/not ok/left, what each worker does and the time left, or nothing.

    ``activity``, when given, maps a worker to ``(label, phase, since)`` (``since``
    from :func:`time.monotonic`), read once a second for the line (the batch's
    threads: :data:`simpro_mj.batch.worker.ACTIVITY`). The time left is the mean
    wall time of the finished tasks times the tasks not finished, over ``workers``,
    less what the running ones have done.
    """

    def __init__(
        self,
        total: int,
        enabled: bool,
        desc: str = "batch",
        *,
        activity: Mapping | None = None,
        workers: int = 1,
    ):
        self.done = self.failed = 0
        self.total = total
        self.bar = None
        self.activity = activity
        self.workers = max(1, int(workers))
        self.walls: list[float] = []
        self._stop = threading.Event()
        self._ticker = None
        if enabled and total and sys.stderr.isatty():
            self.bar = tqdm(total=total, desc=desc, unit="run", file=sys.stderr, dynamic_ncols=True)
            self._post()
            if activity is not None:
                self._ticker = threading.Thread(target=self._tick, name="progress", daemon=True)
                self._ticker.start()

    def _tick(self) -> None:
        while not self._stop.wait(1.0):
            with contextlib.suppress(Exception):  # a line not redrawn is no failure
                self._post()

    def line(self) -> str:
        """The postfix: counts, the expected time left, then each worker's variant and phase."""
        left = self.total - self.done - self.failed
        text = f"ok={self.done} not ok={self.failed} left={left}"
        now = time.monotonic()
        running = sorted(dict(self.activity or {}).items())
        if self.walls and left:
            mean = sum(self.walls) / len(self.walls)
            spent = sum(now - since for _, (_, _, since) in running)
            eta = max(0.0, (left * mean - spent) / self.workers)
            text += f" time left ~{eta:.0f} s"
        for _, (label, phase, since) in running:
            text += f" | {label}: {phase} {now - since:.0f} s"
        return text

    def _post(self, refresh: bool = True) -> None:
        assert self.bar is not None  # called only with a bar
        self.bar.set_postfix_str(self.line(), refresh=refresh)

    def update(self, status: str, wall_s: float | None = None) -> None:
        """One task finished with ``status`` (``ok`` counts done), in ``wall_s`` seconds."""
        if status == "ok":
            self.done += 1
        else:
            self.failed += 1
        if wall_s is not None:
            self.walls.append(float(wall_s))
        if self.bar is not None:
            self._post(refresh=False)  # shown by the update, with the new count
            self.bar.update(1)

    def close(self) -> None:
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join(timeout=2.0)
        if self.bar is not None:
            self.bar.close()


Callback = Callable[[int, dict], None]
#: A worker function: a task (plain data, with ``ship`` on Dask; on threads with ``stop``,
#: the runs' stop token) -> a result dict with ``status`` and ``reason``
#: (:func:`simpro_mj.batch.worker.run_variant`; ``simpro-sim response`` passes its own).
#: Top level in its module, so that it pickles by name.
Worker = Callable[[Mapping], dict]


def _failed(exc: Exception) -> dict:
    """The result of a task that raised, or whose worker died."""
    return {"status": "failed", "reason": one_line(exc, with_type=True), "metrics": None}


def _finished_meanwhile(futures: dict, reported: set, done: Callback) -> None:
    """Report the tasks that finished before or while the runs stopped (not counted as
    cancelled)."""
    for fut, key in futures.items():
        if fut in reported or not fut.done() or fut.cancelled():
            continue
        with contextlib.suppress(Exception):
            done(key, fut.result(timeout=0))


def _collect(finished, futures: dict, done: Callback, reported: set, stop: bool = True) -> None:
    """``done(futures[fut], result)`` of each future of ``finished`` (a task that raised,
    or whose worker died, fails alone); with ``stop``, a task that reports
    ``interrupted`` (Ctrl-C/SIGTERM stopped it) raises :class:`KeyboardInterrupt`."""
    for fut in finished:
        try:
            result = fut.result()
        except Exception as exc:  # noqa: BLE001 - a failing task fails its variant only
            result = _failed(exc)
        reported.add(fut)
        done(futures[fut], result)
        if stop and result.get("status") == "interrupted":
            raise KeyboardInterrupt(result.get("reason") or "interrupted")


def _completed(futures, period: float = WAKE_S):
    """The futures as they finish, like ``as_completed``, waking every ``period`` seconds.

    The kernel hands a signal sent to the process to any thread that does not block
    it (seen under load: one of the runs' threads took the SIGTERM; a pool's own
    threads, its manager and its queues' feeders, can take it too). CPython runs the
    handler in the main thread only, the next time it runs Python code; a wait
    with no timeout would put that off until a task ends (a 600 s variant then
    runs to its end, ``ok``, after the batch was told to stop).
    """
    pending = set(futures)
    while pending:
        finished, pending = wait(pending, timeout=period, return_when=FIRST_COMPLETED)
        yield from finished


def run_tasks(
    tasks: list[tuple[int, dict]],
    done: Callback,
    *,
    fn: Worker,
    jobs: int = 1,
    scheduler: str | None = None,
    no_workers_s: float | None = None,
    threads: bool = False,
    activity: dict | None = None,
) -> None:
    """Run ``fn(task)`` for each ``(key, task)``; ``done(key, result)`` in this process
    as each finishes (``jobs == 1`` here; ``jobs`` threads of this process with
    ``threads``, else a process pool, :func:`run_pool`; or Dask with ``scheduler``). A worker that
    dies fails its task only. ``activity``, on a process pool: filled with what the
    workers say they are doing (:func:`run_pool`).

    Raises
    ------
    KeyboardInterrupt
        SIGINT/SIGTERM (the pool's workers are stopped, Dask's futures cancelled),
        or a task here that reports ``status == "interrupted"``.
    NoWorkers
        Dask: no live worker for ``no_workers_s`` (default :data:`NO_WORKERS_S`).
    """
    if not tasks:
        return
    if scheduler is not None:
        run_dask(tasks, scheduler, jobs, done, fn=fn, no_workers_s=no_workers_s)
    elif jobs == 1:  # one after the other in this process
        signal_ready("batch")
        for key, task in tasks:
            result = fn(task)
            done(key, result)
            if result.get("status") == "interrupted":  # Ctrl-C/SIGTERM stopped this variant
                raise KeyboardInterrupt(result.get("reason") or "interrupted")
    elif threads:
        run_threads(tasks, jobs, done, fn=fn)
    else:
        run_pool(tasks, jobs, done, fn=fn, activity=activity)


def run_threads(tasks: list[tuple[int, dict]], jobs: int, done: Callback, fn: Worker) -> None:
    """The tasks on at most ``jobs`` threads of this process.

    The compiled step runs inside ``mj_step``, which releases the GIL, so
    threads step several simulations at once without starting processes or
    pickling results. Each task gets these runs' stop token as ``task["stop"]``
    (its worker passes it to :meth:`simpro_mj.sim.loop.CoSimulation.run`):
    SIGINT/SIGTERM (in the main thread) set it, every running simulation of
    these tasks stops at its next chunk and reports ``interrupted``, the ones
    not started are cancelled. Runs elsewhere in the process go on.
    """
    stop = threading.Event()
    pool = ThreadPoolExecutor(max_workers=min(jobs, len(tasks)), thread_name_prefix="simpro")
    futures: dict = {}
    reported: set = set()
    try:
        for key, task in tasks:  # a signal meanwhile finds those submitted so far
            futures[pool.submit(fn, {**task, "stop": stop})] = key
        signal_ready("batch")
        _collect(_completed(futures), futures, done, reported)
    except BaseException:
        stop.set()  # the running simulations end at their next chunk
        for fut in futures:
            fut.cancel()
        pool.shutdown(wait=True)
        _finished_meanwhile(futures, reported, done)
        raise
    pool.shutdown(wait=True)


def preload_of(fn: Worker) -> tuple[str, ...]:
    """The modules a pool worker running ``fn`` imports before its first task: ``fn``'s
    module and the names in its ``PRELOAD`` (if it has one)."""
    module = sys.modules.get(fn.__module__)
    return (fn.__module__, *getattr(module, "PRELOAD", ()))


def pool_context(preload: tuple[str, ...] = ()):
    """The workers' start method: a forkserver that has imported ``preload``.

    A pool worker is forked from the forkserver, a process of its own started from
    the interpreter (not forked from this one) that imports ``preload`` and does
    nothing else: no MuJoCo model, no callback set, no thread of this process
    (a progress ticker, a BLAS pool in use, a run) and none of its own. So each
    worker starts with the modules loaded (their imports and numba's cache of the
    step, paid once, in a process that starts before this one plans its tasks:
    :func:`start_early`) and with no inherited state, as a spawned one would.
    ``preload`` takes effect when the forkserver starts (the first pool of this
    process, or :func:`start_early`); later pools share it. Where there is no
    forkserver (Windows), spawn.
    """
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(preload))  # no effect once the server runs
    return ctx


def start_early(fn: Worker) -> None:
    """Start the pool workers' forkserver now, so that its imports (:func:`preload_of`
    ``fn``) run while this process plans the tasks; nothing where there is no
    forkserver."""
    ctx = pool_context(preload_of(fn))
    if ctx.get_start_method() == "forkserver":
        from multiprocessing import forkserver

        forkserver.ensure_running()


def run_pool(
    tasks: list[tuple[int, dict]],
    jobs: int,
    done: Callback,
    fn: Worker,
    activity: dict | None = None,
) -> None:
    """The tasks on a process pool of at most ``jobs`` workers (:func:`pool_context`).

    With ``activity``, the workers get a queue (:func:`simpro_mj.sim.workers.activity_queue`)
    on which a task puts ``(worker, label, phase, since)``, or ``(worker, None, None,
    None)`` when it ends; a thread here keeps ``activity[worker]`` = ``(label, phase,
    since)`` from them for the progress line.
    """
    ctx = pool_context(preload_of(fn))
    queue = ctx.Queue() if activity is not None else None
    alive, keep_alive = alive_pipe()  # the workers' watchdogs read the batch's end
    pool = ProcessPoolExecutor(
        max_workers=min(jobs, len(tasks)),
        mp_context=ctx,
        initializer=init_worker,  # SIGTERM stops a variant; no worker outlives the batch
        initargs=(os.getpid(), queue, alive, dict(os.environ)),
    )
    futures: dict = {}
    reported: set = set()
    reader = _Activity(queue, activity) if queue is not None and activity is not None else None
    try:
        with main_not_imported():  # the workers start while the tasks are submitted
            futures = {pool.submit(run_task, fn, task): key for key, task in tasks}
        signal_ready("batch")
        _collect(_completed(futures), futures, done, reported, stop=False)
    except BaseException:
        stop_pool(pool)  # the workers are gone when this returns
        _finished_meanwhile(futures, reported, done)
        raise
    else:
        pool.shutdown(wait=True)
    finally:
        if reader is not None:
            reader.close()
        keep_alive.close()  # the workers are gone: nobody reads it
        alive.close()


class _Activity:
    """A thread that copies what pool workers say they are doing into a dict."""

    def __init__(self, queue, into: dict):
        self.queue, self.into = queue, into
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, name="simpro-activity", daemon=True)
        self._thread.start()

    def _read(self) -> None:
        import queue as queues

        while not self._stop.is_set():
            try:
                worker, label, phase, since = self.queue.get(timeout=0.2)
            except queues.Empty:
                continue
            except (EOFError, OSError, ValueError):  # the queue closed under us
                return
            if label is None:
                self.into.pop(worker, None)
            else:
                self.into[worker] = (label, phase, since)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.into.clear()
        self.queue.cancel_join_thread()  # nothing of ours waits to be sent
        self.queue.close()


def dask_module():
    """``dask.distributed``, or a one-line :class:`UserInputError` naming the extra."""
    try:
        import distributed  # the optional extra simpro-sim[cluster]: imported on use
    except ImportError as exc:
        raise UserInputError(
            "missing package at --scheduler: dask.distributed is not installed; allowed: "
            "pip install 'simpro-sim[cluster]'"
        ) from exc
    return distributed


#: Seconds allowed to connect to a ``--scheduler`` and for its first bytes (a Dask
#: scheduler sends its handshake at once; Dask's own default waits 30 s, and for a
#: server that accepts and never answers, forever).
CONNECT_S = 5.0
#: Largest first message accepted from a scheduler (bytes): its handshake is ~60.
MAX_HANDSHAKE_BYTES = 1_000_000


def probe_scheduler(address: str, timeout: float | None = None) -> None:
    """Check that ``tcp://HOST:PORT`` answers like a Dask scheduler, within bounds.

    Connects with a timeout of :data:`CONNECT_S` and reads the first 8 bytes of
    the handshake a Dask scheduler sends on accepting (the little-endian length
    of its first message) within the same time; refuses a closed port, a
    server that accepts and stays silent, and one whose first bytes are not a
    plausible Dask message (an HTTP server's reply read as a length asked Dask
    for exabytes). ``inproc://`` (a scheduler in this process) is left to Dask;
    other schemes (``tls://``, ``ucx://``...) are refused.

    Raises
    ------
    UserInputError
        One line naming ``--scheduler`` and what was found.
    """
    import socket
    import struct

    timeout = CONNECT_S if timeout is None else timeout
    scheme, _, rest = address.rpartition("://")
    allowed = "allowed: a running Dask scheduler address (tcp://host:8786) or 'local'"
    if scheme == "inproc":  # a scheduler in this process (the tests'): nothing to probe
        return
    if scheme not in ("", "tcp"):  # tls needs certificates, ucx a UCX build: neither passed
        raise UserInputError(
            f"invalid value at --scheduler: {address[:200]!r}: the scheme {scheme[:20]!r} is "
            f"not supported (TLS needs certificates, UCX its own build); {allowed}"
        )
    host, sep, port_text = rest.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise UserInputError(f"invalid value at --scheduler: {address!r}; {allowed}")
    try:
        sock = socket.create_connection((host, int(port_text)), timeout=timeout)
    except OSError as exc:
        why = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise UserInputError(
            f"no scheduler at --scheduler {address}: {why} (within {timeout:g} s); {allowed}"
        ) from None
    data = b""
    try:
        sock.settimeout(timeout)
        deadline = time.monotonic() + timeout
        while len(data) < 8 and time.monotonic() < deadline:
            chunk = sock.recv(8 - len(data))
            if not chunk:
                break
            data += chunk
    except OSError:
        pass  # timed out or reset: judged below
    finally:
        sock.close()
    if len(data) < 8:
        said = f" after {data!r}" if data else ""
        raise UserInputError(
            f"not a Dask scheduler at --scheduler {address}: it accepted the connection but "
            f"sent no handshake within {timeout:g} s{said}; {allowed}"
        )
    (length,) = struct.unpack("<Q", data)
    if not 0 < length <= MAX_HANDSHAKE_BYTES:
        raise UserInputError(
            f"not a Dask scheduler at --scheduler {address}: it answered {data!r}; {allowed}"
        )


class NoWorkers(RuntimeError):
    """The Dask cluster had no live worker for :data:`NO_WORKERS_S` seconds."""


def run_dask(
    tasks: list[tuple[int, dict]],
    scheduler: str,
    jobs: int,
    done: Callback,
    no_workers_s: float | None = None,
    *,
    fn: Worker,
) -> None:
    """The tasks on a Dask scheduler (``"local"``: a local cluster of ``jobs`` workers)."""
    distributed = dask_module()
    cluster = None
    try:
        if scheduler == "local":
            cluster = distributed.LocalCluster(
                n_workers=min(jobs, len(tasks)),  # never more workers than tasks
                threads_per_worker=1,
                processes=True,
                # a free loopback port: None still takes 8787, and a second cluster
                # on the machine (another batch, a parallel test) warns and moves
                dashboard_address="127.0.0.1:0",
                silence_logs=logging.ERROR,
            )
            client = distributed.Client(cluster)
        else:
            probe_scheduler(scheduler)  # bounded: refused, silent, or not Dask
            client = distributed.Client(scheduler, timeout=2 * CONNECT_S)
    except UserInputError:
        raise
    except (OSError, TimeoutError, ValueError) as exc:
        if cluster is not None:
            cluster.close()
        raise UserInputError(
            f"no scheduler at --scheduler {scheduler}: {one_line(exc, with_type=True)}; "
            "allowed: a running "
            "Dask scheduler address (tcp://host:8786) or 'local'"
        ) from exc
    limit = NO_WORKERS_S if no_workers_s is None else no_workers_s
    futures: dict = {}
    try:
        for key, task in tasks:
            fut = client.submit(fn, dict(task, ship=True), pure=False)
            futures[fut] = key
        signal_ready("batch")
        pending = set(futures)
        seen_worker = time.monotonic()
        while pending:
            try:
                finished = distributed.wait(
                    list(pending), timeout=min(1.0, limit), return_when="FIRST_COMPLETED"
                ).done
            except (TimeoutError, distributed.TimeoutError):
                finished = set()
            pending -= set(finished)
            _collect(finished, futures, done, set(), stop=False)
            if finished or client.scheduler_info().get("workers"):
                seen_worker = time.monotonic()
            elif time.monotonic() - seen_worker > limit:
                raise NoWorkers(
                    f"no live Dask worker for {limit:g} s at --scheduler {scheduler}: "
                    f"{len(pending)} variant(s) not run (cancelled); allowed: a scheduler "
                    "with workers (dask worker ADDRESS), or --scheduler local"
                )
    except BaseException:
        client.cancel(list(futures), force=True)
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
