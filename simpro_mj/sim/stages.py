"""What the loop keeps around the step (:mod:`simpro_mj.sim.step`): the log, the
sensors' noise, scheduled faults, wall time per stage."""

from __future__ import annotations

import time

import numpy as np

from simpro_mj.plant import step_functions as ps
from simpro_mj.plant.faults import FaultSchedule
from simpro_mj.sim import step
from simpro_mj.sim.result import COLUMNS

#: Steps MuJoCo takes between two looks from Python in a compiled run (50 ms at
#: 1 ms): the interrupt, divergence, the live driver and progress are checked there.
CHUNK = 50

if step.N_COLS != len(COLUMNS):  # pragma: no cover - the layouts are edited together
    raise ImportError("simpro_mj.sim.step.record writes a row other than result.COLUMNS")


class Log:
    """The run's log buffers: ``log`` (rows x columns), ``qlog`` (rows x nq), ``hlog`` (rows x 6).

    The step's ``record`` stage fills one row every ``logging.decimation``
    steps (``hlog``, the head sensors, in cueing runs only); the step's state
    counts the rows written (``S[ST.rows]``).
    """

    def __init__(self, n_rows: int, nq: int, head: bool):
        self.log = np.full((n_rows, len(COLUMNS)), np.nan)
        self.qlog = np.zeros((n_rows, nq))
        self.hlog = np.full((n_rows if head else 1, 6), np.nan)
        self.head = head


class NoiseBlock:
    """Standard normal draws, ``width`` per row, row ``i - i0`` for draw number ``i``.

    The sensors use one row of six per step (3 potentiometers, the encoder,
    2 IMU axes; ``i`` is the step), the IMU bias walk one row of two per IMU
    sample from a generator of its own (spawned from the scenario's, so the
    sensor noise is the same with and without it). Rows are drawn from
    ``rng`` in order, ``block`` at a time; when a range reaches past the
    block, the rows not yet used move to the front and the rest is drawn
    anew, so draw ``i`` is always the stream's row ``i`` (numpy's generators
    give the same numbers drawn in pieces or at once). Without a generator
    the block is one row of zeros.
    """

    def __init__(self, rng: np.random.Generator | None, width: int = 6, block: int = 4096):
        self.rng, self.width = rng, int(width)
        if rng is None:
            self.rows = np.zeros((1, self.width))
        else:
            self.rows = rng.standard_normal((int(block), self.width))
        self.i0 = 0

    def ensure(self, i0: int, i1: int) -> int:
        """Rows for draws ``i0 .. i1 - 1`` in the block; returns the block's first draw."""
        n = self.rows.shape[0]
        if self.rng is not None and i1 - self.i0 > n:
            if i1 - i0 > n:
                raise ValueError(f"{i1 - i0} draws at once; the noise block holds {n}")
            keep = self.rows[i0 - self.i0 :].copy()
            self.rows[: keep.shape[0]] = keep
            self.rows[keep.shape[0] :] = self.rng.standard_normal((n - keep.shape[0], self.width))
            self.i0 = i0
        return self.i0


class FaultHooks:
    """Scheduled faults (:class:`~simpro_mj.plant.faults.FaultSchedule`) on the step's state.

    At an event step :meth:`at` brings the schedule to it: a supply change
    goes to the actuators' state (and the log's ``supply_pa``), the flags to
    the log. While a sensor fault acts, :meth:`apply_sensors` replaces what
    the controllers see (``S[ST.yq]``, ``S[ST.yp]``; the sensors' own readings are
    untouched); while a valve is stuck, :meth:`apply_valves` replaces the
    applied volts (``S[ST.ua]``; the controllers keep their own command).
    """

    def __init__(self, schedule: FaultSchedule, S: np.ndarray, actuators):
        self.schedule, self.S, self.actuators = schedule, S, actuators
        self.sensors = self.valves = False

    def at(self, k: int) -> int:
        """Event at step ``k``; returns the next event step."""
        s, S = self.schedule, self.S
        ch = s.at_event(k)
        if ch.supply_pa is not None:
            S[step.ST.ast + ps.ACT.ps] = ch.supply_pa  # what the log's supply_pa shows
            if self.actuators.kind == "linear":
                lo, hi = self.actuators.params.force_range_at(ch.supply_pa)
                S[step.ST.ast + ps.ACT.fmin], S[step.ST.ast + ps.ACT.fmax] = lo, hi
        S[step.ST.flags] = s.flags
        self.sensors, self.valves = s.sensor_active, s.valve_active
        return s.next_event

    def apply_sensors(self, k: int) -> None:
        S = self.S
        q, p = self.schedule.apply_sensors(
            k, S[step.ST.qm : step.ST.qm + 3], S[step.ST.pm : step.ST.pm + 3]
        )
        S[step.ST.yq : step.ST.yq + 3] = q
        S[step.ST.yp : step.ST.yp + 3] = p

    def apply_valves(self) -> None:
        S = self.S
        S[step.ST.ua : step.ST.ua + 3] = self.schedule.apply_valves(S[step.ST.u : step.ST.u + 3])


class Profile:
    """Wall time per stage, by wrapping the stage functions (``CoSimulation.run(profile=)``).

    :meth:`wrap` returns the stage with ``time.perf_counter_ns`` around it,
    adding to the stage's total. The clock calls slow the step down (about
    0.06 us each, two per stage).
    """

    STAGES = ("physics", "sensors", "controllers", "pneumatics", "logging")

    def __init__(self):
        self.ns = dict.fromkeys(self.STAGES, 0)

    def wrap(self, fn, stage: str):
        ns, clock = self.ns, time.perf_counter_ns

        def timed(*args):
            t0 = clock()
            out = fn(*args)
            ns[stage] += clock() - t0
            return out

        return timed
