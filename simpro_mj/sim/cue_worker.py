"""The cueing law in its own process: its solves off the pacing thread, one period late.

The MPC's quadratic programme takes milliseconds (p99 about 5 ms, more on a
busy machine) and OSQP holds Python's interpreter lock while it solves, so a
thread would not take it off the pacing path. :class:`CueWorker` runs the
law's stream (:meth:`controllers.mpc_cueing.ModelPredictiveCueing.stream`) in
a child process instead and talks to it through a pipe, one message each way
per washout period (10 ms):

* at period ``n`` the pacer hands the vehicle input ``(f_n, w_n)`` to the
  child and plays the set-point the child computed from ``(f_(n-1), w_(n-1))``:
  **one period of latency**, always the same;
* if that result is not back yet (a solve longer than a period, or a child
  the machine did not run in time), the last set-point is held and the
  period is counted in ``late`` (``realtime.cue.late_results``), and the
  most inputs waiting for the child in ``max_behind``
  (``realtime.cue.max_behind_periods``); the child catches up in order, the
  newest result is used.

The pacing thread thus never waits for a solve: it sends and polls, a few
tens of microseconds. The child ignores SIGINT and SIGTERM (the session ends
it), and ends by itself when its pipe closes.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal

import numpy as np

#: Longest wait for the child to build the law (s): imports and matrices, on a busy machine.
START_TIMEOUT_S = 120.0


def _serve(conn, params, geometry, period: float, cpus=None) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if cpus:  # every thread of this process (the interpreter's, BLAS's) on cpus
        with contextlib.suppress(OSError, AttributeError):
            os.sched_setaffinity(0, cpus)  # threads started from now on inherit it
            for tid in os.listdir("/proc/self/task"):
                with contextlib.suppress(OSError, ValueError):
                    os.sched_setaffinity(int(tid), cpus)
    from controllers.mpc_cueing import ModelPredictiveCueing

    law = ModelPredictiveCueing(params, geometry=geometry)
    stream = law.stream(period)
    conn.send(("ready", stream.box))
    try:
        while True:
            msg = conn.recv()
            if msg is None:
                break
            conn.send(("pose", stream.step(*msg)))
        conn.send(("done", list(law.solve_times), list(law.status), list(law.iterations)))
    except (EOFError, OSError, KeyboardInterrupt):
        pass
    finally:
        conn.close()


class CueWorker:
    """A law's stream in a child process, with the attributes a live session reads of a
    washout (``step``, ``box``, ``geometry``, ``last_rate_limited``, ``last_softened``).

    Parameters
    ----------
    params : MpcParams
        With ``preview = 0`` (a stream knows only the past).
    geometry : PlatformGeometry
    period : float
        The stream's step (s): the washout period of the session.
    cpus : set of int, optional
        The cores the child and its threads run on (the pacer's kept free of its
        solves); None: wherever the kernel puts them.
    """

    def __init__(self, params, geometry, period: float, cpus=None):
        ctx = multiprocessing.get_context("spawn")  # no fork of a process holding MuJoCo
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(
            target=_serve,
            args=(child, params, geometry, period, None if cpus is None else set(cpus)),
            daemon=True,
            name="cue-law",
        )
        self._proc.start()
        child.close()
        if not self._conn.poll(START_TIMEOUT_S):
            self.close()
            raise RuntimeError(f"the cueing law's process did not start in {START_TIMEOUT_S} s")
        kind, self.box = self._conn.recv()
        self.pid = self._proc.pid
        self.geometry = geometry
        self.last_rate_limited = self.last_softened = False
        self._pose = np.asarray(geometry.home, float)
        self._pending = 0
        self.periods = self.late = self.max_behind = 0
        self.solve_times: list = []
        self.status: list = []
        self.iterations: list = []

    def step(self, f, w) -> np.ndarray:
        """Hand ``(f, w)`` to the child; the set-point of the previous period's input."""
        self.settle(0.0)
        self.periods += 1
        if self._pending:
            self.late += 1
            self.max_behind = max(self.max_behind, self._pending)
        self._conn.send((tuple(map(float, f)), tuple(map(float, w))))
        self._pending += 1
        return self._pose

    def settle(self, timeout_s: float = 30.0) -> bool:
        """Wait (bounded) until the child has answered every input handed to it; True if so.
        A session never waits; a test does, to compare with the law run inline."""
        while self._pending and self._conn.poll(timeout_s):
            _, self._pose = self._conn.recv()
            self._pending -= 1
        return self._pending == 0

    def close(self, timeout_s: float = 10.0) -> None:
        """End the child, keeping its solve times (:attr:`solve_times`, :attr:`status`)."""
        try:
            self._conn.send(None)
            while self._conn.poll(timeout_s):
                msg = self._conn.recv()
                if msg[0] == "done":
                    self.solve_times, self.status, self.iterations = msg[1], msg[2], msg[3]
                    break
        except (EOFError, OSError, BrokenPipeError):
            pass
        finally:
            self._conn.close()
            self._proc.join(timeout_s)
            if self._proc.is_alive():
                self._proc.terminate()
                self._proc.join(timeout_s)
