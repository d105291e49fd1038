"""Running one scenario into a result folder: the job behind ``simpro-sim run``.

:func:`execute` builds a :class:`simpro_mj.job.run.Run` (the design plants,
the compiled plant and the set-points, once), runs it (the preflight, the
co-simulation, the metrics) and writes what it returns
(:func:`simpro_mj.report.results.write_folder`). ``run``, ``compare``,
``batch``, ``bench --video`` and the Python API call it; it lives here,
outside the command modules, so that none of them imports another command
(imports run one way, see docs/architecture.md).

The preflight refuses a payload the cylinders cannot hold (exit 2) and warns
about outer gains above the analysed stability limit. Warnings go to stderr
as ``warning: ...`` lines and into ``metrics.json`` (``warnings``, figures
under ``preflight``). With ``SIMPRO_READY_FILE`` set, the file is written
once the simulation has taken its first step under the signal handlers
(:mod:`simpro_mj.sim.readiness`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from simpro_mj.config.models import Scenario, as_scenario
from simpro_mj.core.interrupts import writing
from simpro_mj.core.rates import PHYSICS_DT_S
from simpro_mj.job.run import Run
from simpro_mj.report.marker import TIMESERIES_WRITTEN
from simpro_mj.report.results import write_folder
from simpro_mj.sim.readiness import signal_ready

#: Exit status of an interrupted run (128 + SIGINT, the shell's convention).
EXIT_INTERRUPTED = 130


def execute(
    scenario: Scenario | Mapping,
    out: Path,
    plots: bool = True,
    *,
    quiet: bool = False,
    model=None,
    progress: bool = False,
    label: str | None = None,
    stop=None,
    timeseries=True,
    more=None,
):
    """Run a resolved scenario and write its result folder.

    Parameters
    ----------
    scenario : Scenario or mapping
        A resolved scenario, typed or its dict.
    out : path
        The result folder.
    plots : bool
        Write the PNG figures.
    quiet : bool
        Do not print warnings on stderr (they are still in ``metrics.json``).
    model : mujoco.MjModel, optional
        The scenario's compiled plant, when the caller has it (a comparison).
    progress : bool
        A tqdm bar of the simulated seconds on stderr (``label`` before it).
    stop : threading.Event, optional
        The run's stop token (:meth:`simpro_mj.sim.loop.CoSimulation.run`).
    timeseries : bool or callable
        Write ``timeseries.csv`` (:func:`~simpro_mj.report.results.write_results`); a
        callable is asked with the run's outcome (:class:`simpro_mj.job.run.RunOutcome`).
    more : callable, optional
        The outcome -> more keys for ``metrics.json``, written with the folder.

    Returns
    -------
    (SimResult, dict)
        The result (``folder``: where it was written, ``out`` or, for an
        interrupted run that would have replaced a complete result,
        ``<out>.partial``) and what ``metrics.json`` holds, so ``--json``
        prints exactly the file's content.

    Raises
    ------
    UserInputError
        From the preflight checks (payload too heavy for the supply pressure).
    KeyboardInterrupt
        If the simulation does not hand back a partial result on Ctrl-C.
    """
    spec = as_scenario(scenario)
    bar = _Bar(spec, label) if progress else None
    run = Run(scenario, model=model)
    try:
        if bar is None:
            outcome = run.execute(quiet=quiet, stop=stop)
        else:
            outcome = run.execute(quiet=quiet, progress=bar.step, bar=True, stop=stop)
    finally:
        if bar is not None:
            bar.close()
    res = outcome.result
    res.folder = None
    with writing(lambda: kept_line(res)):  # a folder is always written whole
        extra = dict(outcome.extra(), plots=plots, **(more(outcome) if more is not None else {}))
        if not (timeseries(outcome) if callable(timeseries) else timeseries):
            extra[TIMESERIES_WRITTEN] = False
        res.folder, doc = write_folder(
            Path(out), res.columns, outcome.metrics, scenario, extra, recording(res)
        )
    return res, doc


def kept_line(res) -> str:
    """What a signal during the write left on disk, in one line."""
    if res.folder is None:
        return "no result was written"
    return f"the {res.status} result in {res.folder} is kept, written whole"


class _Bar:
    """The simulated seconds as a tqdm bar (stderr), updated every 1000 steps; the
    readiness file once the run has steps to keep, as without a bar."""

    def __init__(self, spec: Scenario, label: str | None):
        from tqdm import tqdm

        self.tqdm = tqdm(
            total=float(spec.duration_s),
            unit="sim s",
            desc=label or spec.name,
            leave=False,
            bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.1f}/{total:.1f} sim s "
            "[{elapsed}<{remaining}]",
        )

    def step(self, k: int) -> None:
        if k > 0:
            signal_ready("stepping")
        self.tqdm.n = min(k * PHYSICS_DT_S, self.tqdm.total)
        self.tqdm.refresh()

    def close(self) -> None:
        self.tqdm.close()


def recording(res) -> dict:
    """``qpos.npz`` of a result folder: what ``simpro-sim render`` replays."""
    if res.qpos is None:
        return {}
    return {
        "qpos.npz": {
            "time_s": res.columns["time_s"],
            "qpos": res.qpos,
            "qpos_names": np.array(res.qpos_names, dtype=str),
        }
    }


def interrupted_message(res, out) -> str:
    written = Path(res.folder) if res.folder is not None else Path(out)
    kept = ""
    if written.absolute() != Path(out).expanduser().absolute():
        kept = f"; the complete result in {out} is kept"
    return (
        f"interrupted at t = {res.sim.get('simulated_s', 0.0):.3f} s of "
        f"{res.scenario['duration_s']:g} s: partial results in {written} "
        f"(status interrupted, PARTIAL){kept}"
    )
