"""The operating system's side of a paced thread: real-time scheduling, locked memory,
a core of its own with a fine timer slack, the collector out of the way, and the
thread's context switches counted (Linux; elsewhere each asks nothing and says so).

Each helper is a context manager that leaves the process as it found it, so that a
live session (:mod:`simpro_mj.sim.live`) asks for them only for its own duration.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import gc
import os
from pathlib import Path

_PR_SET_TIMERSLACK, _PR_GET_TIMERSLACK = 29, 30  # prctl(2)


def request_realtime(priority: int = 50) -> str:
    """Ask for ``SCHED_FIFO`` and locked memory; one line saying what was granted."""
    parts = []
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        parts.append(f"SCHED_FIFO priority {priority}")
    except (AttributeError, OSError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        return f"--rt: real-time scheduling not permitted ({why}); running at normal priority"
    libc_name = ctypes.util.find_library("c")
    ok = False
    if libc_name:
        with contextlib.suppress(OSError, AttributeError):
            ok = ctypes.CDLL(libc_name, use_errno=True).mlockall(3) == 0  # MCL_CURRENT|FUTURE
    parts.append("memory locked" if ok else "memory not locked (mlockall refused)")
    return "--rt: " + ", ".join(parts)


@contextlib.contextmanager
def realtime_scheduling(wanted: bool, say=None):
    """:func:`request_realtime` for the block (saying what was granted), then the
    process's scheduling as it was."""
    if not wanted:
        yield
        return
    policy = param = None
    with contextlib.suppress(AttributeError, OSError):
        policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    note = request_realtime()
    if say is not None:
        say(note)
    try:
        yield
    finally:
        if policy is not None and param is not None:
            with contextlib.suppress(OSError):
                os.sched_setscheduler(0, policy, param)


@contextlib.contextmanager
def frozen_gc(counts: list | None = None):
    """The objects built so far moved out of the collector's way for the session (and
    those of the first chunk, :class:`Pacer`); ``counts[g]`` counts the collections of
    generation ``g`` made meanwhile (None: not counted)."""
    gc.collect()
    gc.freeze()
    if counts is None:
        counts = [0, 0, 0]

    def count(phase, info):
        if phase == "stop":
            counts[info["generation"]] += 1

    gc.callbacks.append(count)
    try:
        yield
    finally:
        gc.callbacks.remove(count)
        gc.unfreeze()


def cpu_split(allowed) -> tuple[set, set] | None:
    """``(pacer, law)`` cores out of the ``allowed`` ones: the last for the pacing thread,
    the others for the cueing law's process; None with fewer than 2."""
    cpus = sorted(allowed)
    if len(cpus) < 2:
        return None
    return {cpus[-1]}, set(cpus[:-1])


def thread_switches() -> tuple[int, int] | None:
    """The calling thread's voluntary and involuntary context switches so far (Linux's
    ``/proc/thread-self/status``); None where there is none. An involuntary one is a
    preemption: the thread was runnable and another ran on its core instead."""
    try:
        text = Path("/proc/thread-self/status").read_text()
    except OSError:
        return None
    got = dict(line.split(":\t", 1) for line in text.splitlines() if ":\t" in line)
    try:
        return int(got["voluntary_ctxt_switches"]), int(got["nonvoluntary_ctxt_switches"])
    except (KeyError, ValueError):
        return None


@contextlib.contextmanager
def pinned(cpus: set | None):
    """The calling thread on ``cpus`` for the block, with a timer slack of 1 ns (Linux's
    default 50 us lets a sleep's wake-up be delayed to batch timers); then as it was."""
    if cpus is None or not hasattr(os, "sched_setaffinity"):
        yield
        return
    before = os.sched_getaffinity(0)
    os.sched_setaffinity(0, cpus)
    prctl = slack = None
    libc_name = ctypes.util.find_library("c")
    if libc_name:
        with contextlib.suppress(OSError, AttributeError):
            prctl = ctypes.CDLL(libc_name, use_errno=True).prctl
            slack = prctl(_PR_GET_TIMERSLACK, 0, 0, 0, 0)
            prctl(_PR_SET_TIMERSLACK, ctypes.c_ulong(1), 0, 0, 0)
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)
        if prctl is not None and slack is not None and slack > 0:
            prctl(_PR_SET_TIMERSLACK, ctypes.c_ulong(slack), 0, 0, 0)
