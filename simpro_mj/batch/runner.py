"""A batch: many runs, sweeps, Monte Carlo, in parallel (``simpro-sim batch PATH...``).

Each PATH is a scenario file, a shipped scenario name or a folder (its
``*.yaml``/``*.yml`` files, sorted). A file's ``sweep:`` block
(:mod:`simpro_mj.config.sweep`) expands into variants; a file without one is one
variant named ``base``. ``--set`` overrides apply to the base of every variant.

The batch is planned (:mod:`.plan`), run by workers (:mod:`.worker`) on an
executor (:mod:`simpro_mj.sim.executors`), judged (:mod:`.stability`) and
summarised (:mod:`.summary`, :mod:`.tables`, :mod:`.plots`); :func:`run_batch`
does all of it.

Execution
---------
Every variant runs headless in a worker: :func:`simpro_mj.batch.worker.run_variant` gets the
resolved scenario (plain JSON data) and its folder, builds its own MuJoCo
model, runs, writes a normal result folder (:func:`simpro_mj.report.runner.execute`,
atomic) and returns a small dict. No model is ever pickled.

* ``--jobs N`` (default ``os.cpu_count()``, at most :data:`MAX_JOBS`): N
  worker processes (a ``ProcessPoolExecutor``), never more than the
  variants to run. They are forked from a forkserver that the batch starts before
  it plans, which imports the run's modules and loads numba's cache of the compiled
  step once, while the batch plans (:mod:`simpro_mj.batch.warm`,
  :func:`simpro_mj.sim.executors.pool_context`: no MuJoCo or thread state of any
  process is inherited). Each worker then pays the rest of its start-up (MuJoCo's
  callback) once and takes variant after variant; a variant's figures, its
  ``timeseries.csv`` and its analysis run in Python and hold a process's GIL, so
  processes keep every core busy where threads would wait on each other.
  ``--threads``: N threads of this process instead (no process starts, nothing
  is pickled; the compiled step runs inside ``mj_step``, which releases the GIL,
  but the rest of a variant does not).
  ``--jobs 1``, or a batch of one variant to run, runs in this process.
* ``--scheduler ADDRESS``: the same tasks on a running Dask distributed
  scheduler; ``--scheduler local`` starts a ``LocalCluster`` of ``--jobs``
  single-threaded worker processes (no more than the variants to run). The
  worker writes into a temporary folder and sends the files back, so the
  results land in the same layout here whether or not the workers share this
  file system
  (``pip install 'simpro-sim[cluster]'``).
* Per-variant figures (``--plots``, :data:`PLOTS`): ``examples`` (default) draws
  the figures of each file's first variant (a file without a ``sweep:`` block is one
  variant: its run's figures, as ``simpro-sim run`` draws them); ``failing`` also
  those of every variant whose status is not ``ok``; ``all`` every variant's;
  ``none`` (``--no-plots``) none. A run's four figures cost several times its
  stepping, so a sweep draws only what is asked. The batch's own figures
  (``OUT/plots``) are always drawn. A variant without figures can be drawn again
  with ``simpro-sim run OUT/<scenario>/<variant>/scenario.yaml`` (the same run: its
  seed is in the file).
* Per-variant time series (``--timeseries``, :data:`TIMESERIES`): ``all`` (default)
  writes every variant's ``timeseries.csv``, so every folder is a whole run result
  (``analyze``, ``compare``, ``render`` and the responses figure read it); ``failing``
  only those whose status is not ``ok``; ``none`` none. Writing it costs about two
  thirds of a 15 s run's stepping, which a Monte Carlo of hundreds of variants, read
  through its summary, need not pay. A folder without it is complete all the same
  (its ``metrics.json`` says the file was not asked for, and holds the measured
  stability its row is rebuilt from); the same run writes it again from its
  ``scenario.yaml``.
* The variants start in order of their expected cost, the dearest first (a
  long tail of one dear variant on one worker while the others idle is what
  file order gives): :func:`expected_cost`, the simulated seconds of the run and
  of the identification experiment a new plant needs, the latter weighted by
  :data:`EXPERIMENT_WEIGHT`. Rows stay in expansion order.
* A progress bar (tqdm, stderr; off with ``--quiet`` or when stderr is not a
  terminal) shows ok/not ok/left, the expected time left and, on threads,
  what each worker is doing (its variant, ``identifying`` or ``simulating``,
  for how long; not on Dask). While threads run, BLAS is held to one thread (the
  parallelism is the workers'; BLAS threads would only spin against them).
* A line a run would print (the identification's) is printed once at the
  end with the number of variants that said it (:mod:`simpro_mj.core.notices`).
  Each row of ``summary.json`` carries the variant's ``wall_s`` and ``cpu_s``
  (the worker thread's CPU time).

Statuses
--------
``ok``; ``diverged`` (the run's physics check stopped it, results kept);
``interrupted`` (Ctrl-C during the run, partial results kept);
``failed`` (an exception in the worker: its one-line reason); ``invalid``
(the file, its sweep block or this variant failed validation); ``cancelled``
(not finished: the batch was stopped before it ended; a variant stopped while
running leaves its partial folder, marked ``PARTIAL``).

A PATH that names nothing (no file, folder or shipped scenario) is the
command line's mistake: exit 2 before anything runs. One bad variant or file
never stops the others;
``--strict`` instead refuses the whole batch (exit 2, one line naming the
file) before anything runs if any file or variant is invalid. Exit code: 0
when every variant is ``ok``, 1 otherwise.

Stopping
--------
SIGINT (Ctrl-C) and SIGTERM stop the batch the same way: variants not started
are cancelled, running ones get SIGTERM in their worker (the simulation hands
back what it computed and the folder is written marked ``PARTIAL``; Dask
tasks are cancelled), the workers are waited for (SIGKILL after
:data:`simpro_mj.sim.workers.GRACE_S`), ``summary.csv``/``summary.json`` are
written for what finished with the rest ``cancelled`` (``stopped`` says why),
one line ``error: batch stopped: ...`` and exit 130. Workers never outlive
the batch: each polls its parent (:mod:`simpro_mj.sim.workers`) and ends itself
when the batch is gone, even after a ``kill -9``. A Dask cluster with no live
worker for :data:`NO_WORKERS_S` seconds ends the batch the same way with
``error: batch stopped: no live Dask worker ...`` and exit 1.
``SIMPRO_READY_FILE`` (:mod:`simpro_mj.sim.readiness`) is written once the
handlers are installed and the variants submitted.

``--resume`` skips a variant whose folder is complete
(:func:`simpro_mj.report.marker.is_complete`: the result marker, ``metrics.json``
with status ``ok`` or ``diverged``, a non-empty ``timeseries.csv`` unless it was not
asked for, no ``PARTIAL``) and whose ``scenario.hash`` equals the variant's
:func:`~simpro_mj.config.scenario.scenario_hash`; its row's measured stability is the
one ``metrics.json`` holds (a folder of an earlier batch without it: read from its
``timeseries.csv``). Anything else is recomputed.

``--out`` must be new, empty or an earlier batch's folder (its
``.simpro-result`` marker of kind ``batch``); anything else is refused (exit
2) before anything runs, and a second batch writing the same ``--out`` at the
same time is refused (:func:`simpro_mj.report.folders.claim`). The row of a skipped
variant is rebuilt from its files, so the summary is complete and the same as a fresh run's.

Layout
------
``OUT/<scenario>/<variant>/`` result folders, ``OUT/summary.csv`` (one row
per variant, expansion order), ``OUT/summary.json`` (the rows with full
precision, the stability-limit table, counts) and ``OUT/plots/*.png``
(:mod:`simpro_mj.batch.plots`).

The columns of ``summary.csv``: :mod:`simpro_mj.batch.summary`; the stability
criterion and limit: :mod:`simpro_mj.batch.stability`.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Iterable, Mapping
from pathlib import Path

from simpro_mj.batch.plan import plan, scenario_files
from simpro_mj.batch.robustness import robustness_table
from simpro_mj.batch.stability import Stability, stability_of_folder
from simpro_mj.batch.summary import Report, Row, summary_row, write_summary
from simpro_mj.batch.tables import monte_carlo_table, stability_table
from simpro_mj.batch.worker import ACTIVITY, MEASURED_STABILITY, TIMESERIES, install, run_variant
from simpro_mj.config.scenario import scenario_hash
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.safe_files import read_text
from simpro_mj.report.folders import check_free, check_out, claim
from simpro_mj.report.marker import MAX_METRICS_BYTES, is_complete, record
from simpro_mj.sim import executors as _executors
from simpro_mj.sim.executors import (
    MAX_JOBS,
    NoWorkers,
    Progress,
    dask_module,
    probe_scheduler,
    run_tasks,
)

__all__ = [
    "EXPERIMENT_WEIGHT",
    "MAX_JOBS",
    "NO_WORKERS_S",
    "PLOTS",
    "SUMMARY_FILES",
    "TIMESERIES",
    "expected_cost",
    "run_batch",
]

#: Cost of one simulated second of the identification experiment against one of a
#: run, its fit and set-up included: both step on the compiled step, the experiment
#: with a simpler law but a least-squares fit per leg after it (cProfile, CPU time,
#: a new heavy-cabin plant: 2.1 s for the experiment's 3 x 21 simulated seconds with
#: their fits against 0.39 s for a 15 s run, a ratio near 1.3).
EXPERIMENT_WEIGHT = 1.3

#: The choices of ``--plots``: whose run figures a batch draws (module docstring).
PLOTS = ("examples", "failing", "all", "none")

#: What a batch writes at the top of ``--out`` (its variants are result folders).
SUMMARY_FILES = ("summary.csv", "summary.json", "plots")

#: A Dask batch whose cluster has had no live worker this long (s) ends with an error
#: (read at each batch: tests shorten it).
NO_WORKERS_S = _executors.NO_WORKERS_S


def run_batch(
    paths: Iterable[str],
    out: Path,
    sets: Iterable[str] = (),
    jobs: int = 1,
    resume: bool = False,
    strict: bool = False,
    scheduler: str | None = None,
    plots: bool | str = "examples",
    progress: bool = False,
    summary_plots: bool = True,
    processes: bool = True,
    timeseries: str = "all",
) -> Report:
    """Plan, run and summarise a batch (see the module docstring).

    ``plots`` is one of :data:`PLOTS` (``True``: ``all``, ``False``: ``none``);
    ``processes``: ``jobs > 1`` variants in worker processes, else on threads;
    ``timeseries`` one of :data:`TIMESERIES`.

    Raises
    ------
    UserInputError
        ``--strict`` with an invalid file or variant, a malformed ``--set``,
        or ``--scheduler`` without dask or without a reachable scheduler; an
        ``out`` that is not a batch folder or is being written by another batch.
    """

    wall0 = time.perf_counter()
    out = Path(out)
    plots = {True: "all", False: "none"}.get(plots, plots) if isinstance(plots, bool) else plots
    if plots not in PLOTS:
        raise UserInputError(f"invalid value at --plots: {plots!r}; allowed: {', '.join(PLOTS)}")
    if timeseries not in TIMESERIES:
        raise UserInputError(
            f"invalid value at --timeseries: {timeseries!r}; allowed: {', '.join(TIMESERIES)}"
        )
    inputs = [f for f, _ in scenario_files(paths)]

    if scheduler is not None:  # before the output folder is made
        dask_module()  # say so before anything runs
        if scheduler != "local":
            probe_scheduler(scheduler)  # a closed, silent or foreign server: refused now
    with claim(out, "batch", inputs=inputs, writes=SUMMARY_FILES):
        args = (paths, out, sets, jobs, resume, strict, scheduler, plots, progress, summary_plots)
        return _run_batch(*args, wall0, processes, timeseries)


def _run_batch(
    paths, out, sets, jobs, resume, strict, scheduler, plots, progress, summary_plots, wall0,
    processes=False, timeseries="all",
) -> Report:  # fmt: skip

    if processes and scheduler is None and jobs > 1:
        _executors.start_early(run_variant)  # the workers' imports while this plans
    p = plan(paths, sets)
    if strict:
        for job in p.jobs:
            if job.error:
                which = f" (variant {job.variant})" if job.variant != "-" else ""
                raise UserInputError(f"invalid scenario at {job.file}{which}: {job.error}")
    rows: list[Row | None] = [None] * len(p.jobs)
    tasks: list[tuple[int, dict]] = []
    skipped = 0
    examples = _examples(p.jobs)
    for job in p.jobs:
        if job.scenario is None:
            rows[job.index] = summary_row(job, None)
            continue
        folder = out / job.folder
        doc = _complete(folder, job.scenario) if resume else None
        if doc is not None:
            result = {
                "status": doc["status"],
                "reason": doc.get("reason"),
                "metrics": doc,
                "stability": _stability(folder, doc),
            }
            rows[job.index] = summary_row(job, result, skipped=True)
            skipped += 1
            continue
        try:  # a variant folder not ours to replace, or being written: refused before it runs
            check_out(folder, "run")
            check_free(folder)
        except UserInputError as exc:
            rows[job.index] = summary_row(
                job, {"status": "invalid", "reason": str(exc), "metrics": None}
            )
            continue
        draw = _draw(plots, job.index in examples)
        task = {"scenario": job.scenario, "out": str(folder), "plots": draw,
                "label": job.variant, "timeseries": timeseries}  # fmt: skip
        tasks.append((job.index, task))
    if skipped and progress:
        sys.stderr.write(f"resume: {skipped} complete variant(s) skipped\n")
    # the dearest first (stable: equal costs keep file order)
    tasks.sort(key=lambda t: -expected_cost(t[1]["scenario"]))
    if scheduler is None:  # one variant to run: no worker to start
        jobs = max(1, min(jobs, len(tasks)))
    threaded = scheduler is None and not processes and jobs > 1
    watched = scheduler is None and jobs > 1  # the workers' phases (Dask's are its own)
    bar = Progress(
        len(tasks), progress, activity=ACTIVITY if watched else None, workers=min(jobs, len(tasks))
    )
    shown = watched and bar.bar is not None  # a pool's workers then say their phases
    said: dict[str, int] = {}

    def done(key: int, result: dict) -> None:
        files = result.pop("files", None)
        if files is not None:
            install(files, out / p.jobs[key].folder)
        for text, count in (result.pop("notices", None) or {}).items():
            said[text] = said.get(text, 0) + count
        row = rows[key] = summary_row(p.jobs[key], result)
        bar.update(row.status, result.get("wall_s"))

    out.mkdir(parents=True, exist_ok=True)
    record(out, SUMMARY_FILES, "batch", pending=True)
    stopped = None
    try:
        # one BLAS thread each: the batch's parallelism is its workers
        with _blas_limited(threaded):
            run_tasks(
                tasks, done, jobs=jobs, scheduler=scheduler, fn=run_variant,
                no_workers_s=NO_WORKERS_S, threads=not processes,
                activity=ACTIVITY if shown and processes else None,
            )  # fmt: skip
    except KeyboardInterrupt as exc:  # SIGINT, or SIGTERM (commands.main: interruptible)
        stopped = f"interrupted ({exc})" if str(exc) else "interrupted"
    except NoWorkers as exc:
        stopped = str(exc)
    finally:
        bar.close()
        # what finished is recorded, the rest is 'cancelled'; also on an error. A variant
        # whose complete folder is on disk finished, even if its worker was stopped before
        # its result came back
        final = [r if r is not None else _finished_row(p.jobs[i], out) for i, r in enumerate(rows)]
        report = Report(out=out, rows=final, paths=p.paths, files=p.files, skipped=skipped)
        report.stability = stability_table(report.rows, p.jobs)
        report.monte_carlo = monte_carlo_table(report.rows, p.jobs)
        report.robustness = [
            t
            for t in (robustness_table(report.rows, f["scenario"]) for f in p.files)
            if t is not None
        ]
        report.stopped = stopped
        report.notices = said
        for row in report.rows:
            if stopped and row.status == "cancelled" and not row.reason:
                row.reason = f"not finished: batch stopped: {stopped}"
        report.wall_s = time.perf_counter() - wall0
        write_summary(report)
        if stopped is not None:
            record(out, SUMMARY_FILES, "batch")
    if stopped is not None:
        return report  # no summary plots: the user asked to stop, or the cluster is gone
    if summary_plots:
        # matplotlib only when the figures are drawn: a batch refused for a bad path or
        # --strict answers within a second
        from simpro_mj.batch.plots import plot_summary

        report.plots = [str(x) for x in plot_summary(report, p.jobs)]
    report.wall_s = time.perf_counter() - wall0
    write_summary(report)
    record(out, SUMMARY_FILES, "batch")
    return report


def _examples(jobs) -> set[int]:
    """The row index of each file's first variant to run (expansion order)."""
    first: dict[str, int] = {}
    for job in jobs:
        if job.scenario is not None:
            first.setdefault(job.file, job.index)
    return set(first.values())


def _draw(plots: str, example: bool) -> str:
    """A variant's ``plots`` (:data:`simpro_mj.batch.worker.DRAW`) under ``--plots``."""
    if plots == "all" or (example and plots in ("examples", "failing")):
        return "all"
    return "failing" if plots == "failing" else "none"


def _blas_limited(on: bool):
    """One BLAS thread in this process while the batch's threads run (else nothing)."""
    import contextlib

    if not on:
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def expected_cost(scenario: Mapping) -> float:
    """A variant's expected cost in simulated run-seconds (module docstring)."""
    controller = scenario.get("controller")
    inner = controller.get("inner") if isinstance(controller, Mapping) else None
    inner = inner if isinstance(inner, Mapping) else {}
    exp = 0.0
    # no experiment (a preset's models, or the reduced chain's): read from the resolved
    # tree, without importing the identification (MuJoCo) into the batch's process
    if (
        inner.get("design_plant", "identified") == "identified"
        and inner.get("identify", "auto") == "auto"
    ):
        from simpro_mj.identification.auto import experiment_s

        try:
            exp = experiment_s(scenario)
        except (KeyError, TypeError, ValueError):  # the run itself says what is wrong
            exp = 0.0
    return float(scenario.get("duration_s", 0.0)) + EXPERIMENT_WEIGHT * exp


def _finished_row(job, out: Path) -> Row:
    """The row of a variant with no result back: from its folder if that is complete
    for this variant (as ``--resume`` would skip it), else ``cancelled``."""
    try:
        doc = _complete(out / job.folder, job.scenario) if job.scenario is not None else None
        if doc is None:
            return summary_row(job, None)
        result = {
            "status": doc["status"],
            "reason": doc.get("reason"),
            "metrics": doc,
            "stability": _stability(out / job.folder, doc),
        }
    except (OSError, ValueError):  # unreadable after all: not counted as finished
        return summary_row(job, None)
    return summary_row(job, result)


def _stability(folder: Path, doc: Mapping) -> Stability:
    """A complete folder's measured stability: the one its ``metrics.json`` holds,
    else (a folder written without it) read from its ``timeseries.csv``."""
    held = doc.get(MEASURED_STABILITY)
    if isinstance(held, dict):
        try:
            return Stability(**held)
        except TypeError:  # other fields: read from the file below
            pass
    return stability_of_folder(folder, doc["status"])


def _complete(folder: Path, scenario: Mapping) -> dict | None:
    """The metrics.json document of a complete result folder for ``scenario``, else None.

    Complete is :func:`simpro_mj.report.marker.is_complete` (the one documented
    check), and the folder's scenario hash must be the variant's.
    """

    if not is_complete(folder):
        return None
    try:
        doc = json.loads(read_text(folder / "metrics.json", MAX_METRICS_BYTES, "metrics"))
    except (OSError, ValueError, RecursionError):  # RecursionError: JSON nested too deep
        return None
    if (doc.get("scenario") or {}).get("hash") != scenario_hash(scenario):
        return None
    return doc
