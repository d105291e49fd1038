"""A batch's worker: one variant run headless into its result folder.

:func:`run_variant` gets the resolved scenario (plain JSON data) and its
folder, builds its own MuJoCo model, runs, writes a normal result folder
(:func:`simpro_mj.report.runner.execute`, atomic) and returns a small dict. No
model is ever pickled; the function is top level so that it pickles by name
to a pool or Dask worker. A worker that may not share this file system writes
into a temporary folder and ships the files back (:func:`install` writes them here).

A variant draws its run's figures (the PNG files of
:func:`simpro_mj.report.plots.plot_run`) as its task says (:data:`DRAW`): ``all``
(inside the folder's atomic write), ``failing`` (only when its status is not
``ok``: drawn after the run into a temporary folder beside the result and moved
in, each file whole) or ``none``.

A variant writes its ``timeseries.csv`` as its task says (:data:`TIMESERIES`):
``all``, ``failing`` (only when its status is not ``ok``) or ``none``; a folder
without it says so in ``metrics.json`` and is complete
(:func:`simpro_mj.report.marker.is_complete`).

A variant's measured stability (:func:`simpro_mj.batch.stability.stability_of`) is
taken from its run's columns in memory, each number rounded as ``timeseries.csv``
writes it (:class:`AsWritten`), and written into ``metrics.json``
(:data:`MEASURED_STABILITY`) with the folder: a resumed batch reads it there, the
same figures as the file's, with or without the file.

The notices a run would print (the identification line) are gathered
(:mod:`simpro_mj.core.notices`) and returned, so the batch says each once with a
count; :data:`ACTIVITY` holds what each worker is doing for the progress line (on
threads of the batch's process directly; a pool worker puts it on its parent's queue,
:func:`simpro_mj.sim.workers.activity_queue`).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import threading
import time
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path

import numpy as np

from simpro_mj.batch.stability import stability_of
from simpro_mj.core import notices
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.messages import one_line
from simpro_mj.report.folders import install_folder
from simpro_mj.report.marker import hidden, record
from simpro_mj.report.results import NUMBER_FORMAT
from simpro_mj.report.runner import execute
from simpro_mj.sim.workers import activity_queue

__all__ = ["ACTIVITY", "DRAW", "MEASURED_STABILITY", "PRELOAD", "TIMESERIES", "AsWritten",
           "install", "run_variant"]  # fmt: skip

#: What a variant's task may ask to draw (``plots``; ``True`` is ``all``, ``False``
#: ``none``): every run's figures, only a run whose status is not ``ok``, or none.
DRAW = ("all", "failing", "none")

#: Whose ``timeseries.csv`` a variant's task may ask for (``timeseries``): every run's,
#: only a run whose status is not ``ok``, or none.
TIMESERIES = ("all", "failing", "none")

#: Key of a variant's ``metrics.json`` holding its measured stability (the fields of
#: :class:`simpro_mj.batch.stability.Stability`).
MEASURED_STABILITY = "measured_stability"

#: What a pool worker process imports before its first variant, besides this module
#: (:func:`simpro_mj.sim.executors.preload_of`): the run's modules and the compiled step.
PRELOAD = ("simpro_mj.batch.warm",)

#: Worker (a thread's name, or ``pid N`` of a pool worker) -> (variant label, phase,
#: time.monotonic() the phase began), of the running variants (the progress line reads
#: it; a pool's are copied here from its queue, :func:`simpro_mj.sim.executors.run_pool`).
ACTIVITY: dict[str, tuple[str, str, float]] = {}


def run_variant(task: Mapping) -> dict:
    """Run one variant (worker side; top level so that it pickles by name).

    Parameters
    ----------
    task : mapping
        ``scenario`` (resolved, plain data), ``out`` (its folder), ``plots``
        (one of :data:`DRAW`, or a bool: ``all``/``none``), ``timeseries`` (one of
        :data:`TIMESERIES`, default ``all``), ``ship`` (bool: write
        into a temporary folder and return the files' bytes, for workers that may
        not share this file system).

    Returns
    -------
    dict
        ``status``, ``reason``, ``metrics`` (the ``metrics.json`` document,
        ``None`` if the run failed), ``stability`` (:func:`stability_of_folder`),
        ``notices`` (text -> count), ``wall_s`` and ``cpu_s`` (this thread's CPU
        time: the variant's own cost, less inflated by other work on the machine)
        and, when shipping, ``files`` (name -> bytes).
    """
    me = threading.current_thread().name
    label = str(task.get("label") or Path(task["out"]).name)
    queue = activity_queue()  # a pool worker's line to its parent, else None
    if queue is not None:
        me = f"pid {os.getpid()}"

    def say(*what) -> None:
        with contextlib.suppress(Exception):  # a line not shown is no failure
            queue.put((me, *what))

    def on_phase(name: str) -> None:
        since = time.monotonic()  # CLOCK_MONOTONIC: one clock for every process here
        if queue is None:
            ACTIVITY[me] = (label, name, since)
        else:
            say(label, name, since)

    wall0, cpu0 = time.perf_counter(), time.thread_time()
    on_phase("preparing")
    try:
        with notices.collecting(on_phase) as said:
            out = _run_variant(task)
    finally:
        if queue is None:
            ACTIVITY.pop(me, None)
        else:
            say(None, None, None)
    out["notices"] = said.counts
    out["wall_s"] = time.perf_counter() - wall0
    out["cpu_s"] = time.thread_time() - cpu0
    return out


def _run_variant(task: Mapping) -> dict:
    ship = bool(task.get("ship"))
    tmp = Path(tempfile.mkdtemp(prefix="simpro-batch-")) if ship else None
    try:
        folder = tmp / "variant" if tmp is not None else Path(task["out"])
        draw = draw_choice(task.get("plots", True))
        series = task.get("timeseries", "all")
        if series not in TIMESERIES:
            raise ValueError(f"invalid timeseries: {series!r}; allowed: {', '.join(TIMESERIES)}")
        measured = []

        def stability(outcome) -> dict:
            # from the columns in memory, each number as timeseries.csv holds it: the
            # same figures as the file read back, written with the folder
            status = outcome.metrics.get("status", "ok")
            measured.append(stability_of(AsWritten(outcome.result.columns), status))
            return {MEASURED_STABILITY: asdict(measured[-1])}

        def keep(outcome) -> bool:
            return series == "all" or (
                series == "failing" and outcome.metrics.get("status", "ok") != "ok"
            )

        # warnings go to metrics.json only: many workers on one stderr would be noise
        res, doc = execute(
            task["scenario"],
            folder,
            plots=draw == "all",
            quiet=True,
            stop=task.get("stop"),
            timeseries=keep,
            more=stability,
        )
        folder = res.folder
        if draw == "failing" and doc.get("status", "ok") not in ("ok", "interrupted"):
            _draw_into(Path(folder), res.columns, task["scenario"])
        out = {
            "status": doc.get("status", "ok"),
            "reason": doc.get("reason"),
            "metrics": doc,
            "stability": measured[-1],
        }
        if ship:
            out["files"] = {p.name: p.read_bytes() for p in sorted(folder.iterdir())}
        return out
    except UserInputError as exc:  # a value only the plant checks
        return {"status": "invalid", "reason": one_line(exc), "metrics": None}
    except Exception as exc:  # noqa: BLE001 - any failure is this variant's, not the batch's
        return {"status": "failed", "reason": one_line(exc, with_type=True), "metrics": None}
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


class AsWritten(Mapping):
    """A run's columns read as ``timeseries.csv`` holds them: each number formatted
    with :data:`simpro_mj.report.results.NUMBER_FORMAT` and parsed back, a column at a
    time as it is first read (the stability reads 7 of the run's columns), each distinct
    value once (the set-points hold a few values for thousands of samples)."""

    def __init__(self, columns: Mapping):
        self._columns = columns
        self._read: dict = {}

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self._read:
            column = np.asarray(self._columns[name], dtype=float).ravel()
            # distinct bit patterns: -0.0 and each NaN kept as they are
            bits, where = np.unique(column.view(np.int64), return_inverse=True)
            values = bits.view(float).tolist()
            text = (NUMBER_FORMAT + "\n") * len(values) % tuple(values)
            self._read[name] = np.array(text.split(), dtype=float)[where.ravel()]
        return self._read[name]

    def __iter__(self):
        return iter(self._columns)

    def __len__(self) -> int:
        return len(self._columns)


def draw_choice(value) -> str:
    """A task's ``plots`` as one of :data:`DRAW` (``True``: ``all``; ``False``, ``None``:
    ``none``).

    Raises
    ------
    ValueError
        Anything else.
    """
    if value is True:
        return "all"
    if value is False or value is None:
        return "none"
    if value not in DRAW:
        raise ValueError(f"invalid plots: {value!r}; allowed: {', '.join(DRAW)}, True or False")
    return str(value)


def _draw_into(folder: Path, columns, scenario: Mapping) -> None:
    """The run's figures into its complete result folder: drawn beside it, listed in its
    marker as ours (:func:`simpro_mj.report.marker.record`), moved in whole."""
    from simpro_mj.report.plots import plot_run  # matplotlib only when a figure is drawn

    tmp = Path(tempfile.mkdtemp(prefix=hidden(folder, "tmp"), dir=folder.parent))
    try:
        names = [path.name for path in plot_run(columns, scenario, tmp)]
        record(folder, names, "run", pending=True)  # a kill from here on leaves them ours
        for name in names:
            os.replace(tmp / name, folder / name)
        record(folder, names, "run")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def install(files: Mapping[str, bytes], out: Path) -> None:
    """Write shipped files as a result folder, atomically (as results.write_results)."""

    def fill(tmp: Path) -> None:
        for name, data in files.items():
            (tmp / Path(name).name).write_bytes(data)

    install_folder(out, fill)
