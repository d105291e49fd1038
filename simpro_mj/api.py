"""The Python API: run scenarios from a script or a notebook.

>>> import simpro_mj as s
>>> r = s.run("step_pitch", {"duration_s": 2})
>>> r.metrics["axes"]["pitch"]["overshoot_pct"]        # doctest: +SKIP
>>> r.columns["pitch_rad"]                            # 1 ms log, SI units
>>> both = s.compare("step_all", {"duration_s": 4})   # joint-only vs task-space
>>> both["task_space"].to_frame()                     # pandas, if installed
>>> r.plot("task_space")                              # a matplotlib Figure (Fig. 16)
>>> s.sweep("sweep_outer_gain", jobs=2).rows()        # one row per variant

``docs/examples/quickstart.py`` runs all of it (``tests/test_api.py`` runs it too).

A scenario is a shipped name (``"step_pitch"``), a path to a YAML file or a
mapping (a scenario document). Overrides are a mapping of dotted keys to
values, ``{"controller.outer.gains": [3, 3, 3], "duration_s": 5}``, with the
meaning and the checks of the command line's ``--set KEY=VALUE``: a mistake
raises :class:`~simpro_mj.core.errors.UserInputError` (a ``ValueError``) whose
one-line message names the key and what is allowed.

Nothing is written to disk unless ``out`` is given; then the result folder is
the one ``simpro-sim run --out`` writes.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simpro_mj.config.models import Scenario, as_scenario
from simpro_mj.config.variants import load_sweep
from simpro_mj.core.errors import SweepError, UserInputError
from simpro_mj.core.keys import closest


@dataclass(frozen=True)
class Result:
    """One co-simulation.

    Attributes
    ----------
    scenario : Scenario
        The resolved scenario, typed (every default filled in).
    columns : dict of str to ndarray
        The logged time series, SI units, names as in ``timeseries.csv``.
    metrics : dict
        What ``metrics.json`` holds: per-axis step/tracking figures,
        ``status``, ``reason``, ``sensor_floor``, ``sim`` and ``warnings``.
    out : pathlib.Path or None
        The result folder, if one was written.
    """

    scenario: Scenario
    columns: dict
    metrics: dict
    out: Path | None = None

    @property
    def status(self) -> str:
        """``ok``, ``diverged`` or ``interrupted``."""
        return self.metrics["status"]

    @property
    def reason(self) -> str | None:
        """Why the run stopped early, or None."""
        return self.metrics.get("reason")

    def to_frame(self):
        """The time series as a :class:`pandas.DataFrame` indexed by ``time_s``.

        Raises
        ------
        ImportError
            If pandas is not installed (``pip install pandas``).
        """
        try:
            import pandas as pd
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError("Result.to_frame needs pandas: pip install pandas") from exc
        return pd.DataFrame(self.columns).set_index("time_s")

    def plot(self, which: str = "task_space", path: str | Path | None = None):
        """A figure of the run, as ``simpro-sim run --plots`` draws it.

        Parameters
        ----------
        which : str
            ``task_space`` (desired vs output, roll/pitch in deg, height in mm:
            Figs. 14/16), ``joints``, ``valves`` or ``pressures``
            (:data:`simpro_mj.report.plots.RUN_FIGURES`).
        path : path, optional
            Also save the figure there (PNG).

        Returns
        -------
        matplotlib.figure.Figure
            Drawn without a display (no pyplot state): ``fig.savefig(...)``, or
            show it in a notebook by leaving it last in a cell.

        Raises
        ------
        UserInputError
            ``which`` is not one of the run's figures.
        """
        # matplotlib is loaded when a figure is asked for, not by ``import simpro_mj``
        from simpro_mj.report.figures import DPI
        from simpro_mj.report.plots import RUN_FIGURES, run_figures

        figures = run_figures(self.columns, self.scenario, only=which)
        if which not in figures:
            allowed = [n for n in RUN_FIGURES if n in run_figures(self.columns, self.scenario)]
            raise UserInputError(
                f"invalid figure {which!r}; allowed: {', '.join(allowed)}"
                + closest(str(which), allowed)
            )
        fig = figures[which]
        if path is not None:
            fig.savefig(path, dpi=DPI)
        return fig


def _sets(overrides: Mapping | None) -> list[str]:
    """Overrides as ``--set`` expressions (JSON is YAML, so values keep their types)."""
    if overrides is None:
        return []
    if not isinstance(overrides, Mapping):
        raise UserInputError(
            f"invalid overrides: {type(overrides).__name__}; allowed: a mapping of dotted "
            "keys to values, e.g. {'duration_s': 2}"
        )
    out = []
    for key, value in overrides.items():
        if not isinstance(key, str) or not key:
            raise UserInputError(f"invalid override key {key!r}; allowed: a dotted key string")
        try:
            text = json.dumps(value, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise UserInputError(
                f"invalid value at {key}: {value!r}; allowed: numbers, strings, lists and "
                "mappings of them"
            ) from exc
        out.append(f"{key}={text}")
    return out


def load(scenario: str | Path | Mapping | Scenario, overrides: Mapping | None = None) -> Scenario:
    """Resolve a scenario: a shipped name, a YAML path or a mapping, plus overrides.

    Returns
    -------
    Scenario
        The resolved scenario, typed; its ``model_dump()`` is what ``scenario.yaml``
        of a result folder holds.
    """
    from simpro_mj.config.scenario import load_scenario, resolve

    if isinstance(scenario, Scenario):
        scenario = scenario.model_dump()
    if isinstance(scenario, Mapping):
        return resolve(copy.deepcopy(dict(scenario)), _sets(overrides))
    return load_scenario(str(scenario), _sets(overrides))


#: :func:`load` by the name the command line's modules use.
load_scenario = load


def run(
    scenario: str | Path | Mapping | Scenario,
    overrides: Mapping | None = None,
    *,
    out: str | Path | None = None,
    plots: bool = False,
) -> Result:
    """Run one co-simulation.

    Parameters
    ----------
    scenario : str, path or mapping
        A shipped name, a YAML path or a scenario document.
    overrides : mapping, optional
        Dotted keys to values, as ``--set``.
    out : path, optional
        Write the result folder there (as ``simpro-sim run --out``).
    plots : bool
        With ``out``: write the PNG figures too.

    Returns
    -------
    Result
    """
    resolved = load(scenario, overrides)
    if out is not None:
        from simpro_mj.report.runner import execute

        res, metrics = execute(resolved, Path(out), plots=plots, quiet=True)
        return Result(resolved, res.columns, metrics, res.folder)
    return _measure(resolved)


def compare(
    scenario: str | Path | Mapping | Scenario, overrides: Mapping | None = None
) -> dict[str, Result]:
    """The same plant and seed with joint-only and with task-space control (Fig. 15 a/b).

    Returns
    -------
    dict
        ``{"joint_only": Result, "task_space": Result}``.
    """
    from simpro_mj.config.scenario import scenario_with

    base = load(scenario, overrides)
    out: dict[str, Any] = {}
    for mode in ("joint_only", "task_space"):
        out[mode] = run(scenario_with(base, {"controller.mode": mode}))
    return out


@dataclass(frozen=True)
class SweepResult:
    """The variants of a sweep file, run.

    Attributes
    ----------
    file : str
        The sweep file's path.
    results : dict of str to Result
        Each valid variant's run, by variant name, in expansion order.
    values : dict of str to dict
        Each variant's swept values (dotted key to value).
    errors : dict of str to str
        Each invalid variant's one-line reason (it did not run).
    """

    file: str
    results: dict
    values: dict
    errors: dict

    def rows(self) -> list[dict]:
        """One row per variant: ``variant``, the swept keys, ``status``, and per axis
        ``<axis>_overshoot_pct``, ``<axis>_settling_time_s``, ``<axis>_iae``,
        ``<axis>_steady_state_error`` (SI: rad, m)."""
        out = []
        for name, vals in self.values.items():
            res = self.results.get(name)
            status = res.status if res is not None else "invalid"
            row: dict[str, Any] = {"variant": name, **vals, "status": status}
            axes = res.metrics.get("axes", {}) if res is not None else {}
            for axis in ("roll", "pitch", "heave"):
                m = axes.get(axis) or {}
                for key in SWEEP_ROW_METRICS:
                    row[f"{axis}_{key}"] = m.get(key)
            out.append(row | {"error": self.errors.get(name)})
        return out

    def to_frame(self):
        """:meth:`rows` as a :class:`pandas.DataFrame` indexed by ``variant``."""
        try:
            import pandas as pd  # optional extra ("simpro-sim[frame]")
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError("SweepResult.to_frame needs pandas: pip install pandas") from exc
        return pd.DataFrame(self.rows()).set_index("variant")


#: The per-axis metrics of a :meth:`SweepResult.rows` row.
SWEEP_ROW_METRICS = ("overshoot_pct", "settling_time_s", "iae", "steady_state_error")


def _measure(scenario: Scenario | Mapping, stop=None) -> Result:
    """One resolved scenario measured without writing anything (:func:`run`, :func:`sweep`)."""
    # MuJoCo is loaded when a plant is built, not by ``import simpro_mj``
    from simpro_mj.job.run import Run
    from simpro_mj.report.results import jsonable

    outcome = Run(scenario).execute(quiet=True, stop=stop)
    metrics = dict(outcome.metrics, **outcome.extra())
    return Result(as_scenario(scenario), outcome.result.columns, jsonable(metrics), None)


def _measured(task: Mapping) -> dict:
    """A :func:`sweep` variant's task (here, on a thread or in a pool worker: top level,
    it pickles by name): its ``status`` and its ``result``."""
    result = _measure(task["scenario"], task.get("stop"))
    return {"status": result.status, "result": result}


def sweep(
    scenario_file: str | Path,
    overrides: Mapping | None = None,
    *,
    jobs: int = 1,
    processes: bool = False,
) -> SweepResult:
    """Run every variant of a sweep file (a scenario with a ``sweep:`` block).

    As ``simpro-sim batch`` plans it, without writing anything: each variant is
    resolved and checked first; an invalid one is reported in ``errors`` and the
    others run.

    Parameters
    ----------
    scenario_file : str or path
        A shipped name (``"sweep_outer_gain"``) or a YAML path.
    overrides : mapping, optional
        Dotted keys to values applied to the base of every variant (``--set``).
    jobs : int
        Variants at once (1: here, one after the other): on threads of this
        process, as ``simpro-sim batch --jobs`` runs them (the compiled step
        releases the GIL inside ``mj_step``; the results are those of the
        serial run).
    processes : bool
        With ``jobs > 1``: spawned worker processes instead of threads
        (``batch --processes``).

    Returns
    -------
    SweepResult

    Raises
    ------
    UserInputError
        A mistake in the file, ``overrides`` or ``jobs``.
    SweepError
        No variant could run (a worker pool that broke). With ``processes`` the
        workers are spawned processes; they do not import a calling script
        (:func:`simpro_mj.sim.workers.main_not_imported`), but a program started
        with ``python -m`` is imported by them and keeps its work under
        ``if __name__ == "__main__":``.
    """
    from simpro_mj.sim.executors import MAX_JOBS, run_tasks  # no MuJoCo until a plant is built

    if not isinstance(jobs, int) or isinstance(jobs, bool) or not 1 <= jobs <= MAX_JOBS:
        raise UserInputError(f"invalid jobs: {jobs!r}; allowed: an integer 1..{MAX_JOBS}")
    if not isinstance(processes, bool):
        raise UserInputError(f"invalid processes: {processes!r}; allowed: True or False")
    sw = load_sweep(str(scenario_file), _sets(overrides))
    if sw.error:
        raise UserInputError(sw.error)
    values = {v.name: dict(v.values) for v in sw.variants}
    errors = {v.name: v.error for v in sw.variants if v.scenario is None}
    valid = [v for v in sw.variants if v.scenario is not None]
    tasks = [(i, {"scenario": v.scenario}) for i, v in enumerate(valid)]
    done: dict[int, dict] = {}
    run_tasks(tasks, lambda key, out: done.__setitem__(key, out), fn=_measured, jobs=jobs,
              threads=not processes)  # fmt: skip
    results = {}
    for i, v in enumerate(valid):
        out = done.get(i) or {}
        if "result" in out:
            results[v.name] = out["result"]
        else:  # a worker that died fails its variant only
            errors[v.name] = out.get("reason") or "the worker ended without a result"
    if valid and not results:
        reason = next(iter(errors[v.name] for v in valid)) or ""
        hint = ""
        if processes and jobs > 1 and ("BrokenProcessPool" in reason or "bootstrapping" in reason):
            hint = (
                "; with jobs > 1 the workers are spawned processes: a program run with "
                "python -m keeps its work under if __name__ == '__main__':"
            )
        raise SweepError(f"sweep {sw.path}: every variant failed: {reason}{hint}")
    return SweepResult(sw.path, results, values, errors)
