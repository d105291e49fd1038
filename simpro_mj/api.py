"""The Python API: run scenarios from a script or a notebook.

>>> import simpro_mj as s
>>> r = s.run("step_pitch", {"duration_s": 2})
>>> r.metrics["axes"]["pitch"]["overshoot_pct"]        # doctest: +SKIP
>>> r.columns["pitch_rad"]                            # 1 ms log, SI units
>>> both = s.compare("step_all", {"duration_s": 4})   # joint-only vs task-space
>>> both["task_space"].to_frame()                     # pandas, if installed

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

from simpro_mj.core.errors import UserInputError

__all__ = ["Result", "load", "run", "compare"]


@dataclass(frozen=True)
class Result:
    """One co-simulation.

    Attributes
    ----------
    scenario : dict
        The resolved scenario (every default filled in).
    columns : dict of str to ndarray
        The logged time series, SI units, names as in ``timeseries.csv``.
    metrics : dict
        What ``metrics.json`` holds: per-axis step/tracking figures,
        ``status``, ``reason``, ``sensor_floor``, ``sim`` and ``warnings``.
    out : pathlib.Path or None
        The result folder, if one was written.
    """

    scenario: dict
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


def load(scenario: str | Path | Mapping, overrides: Mapping | None = None) -> dict:
    """Resolve a scenario: a shipped name, a YAML path or a mapping, plus overrides.

    Returns
    -------
    dict
        The resolved scenario, as ``scenario.yaml`` of a result folder holds it.
    """
    from simpro_mj.config.scenario import load_scenario, resolve_scenario

    if isinstance(scenario, Mapping):
        return resolve_scenario(copy.deepcopy(dict(scenario)), _sets(overrides))
    return load_scenario(str(scenario), _sets(overrides))


def run(
    scenario: str | Path | Mapping,
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
    from simpro_mj.report.results import _jsonable
    from simpro_mj.report.runner import measure

    res, metrics, extra = measure(resolved, quiet=True)
    metrics.update(extra)
    return Result(resolved, res.columns, _jsonable(metrics), None)


def compare(scenario: str | Path | Mapping, overrides: Mapping | None = None) -> dict[str, Result]:
    """The same plant and seed with joint-only and with task-space control (Fig. 15 a/b).

    Returns
    -------
    dict
        ``{"joint_only": Result, "task_space": Result}``.
    """
    base = load(scenario, overrides)
    out: dict[str, Any] = {}
    for mode in ("joint_only", "task_space"):
        sc = copy.deepcopy(base)
        sc["controller"]["mode"] = mode
        out[mode] = run(sc)
    return out
