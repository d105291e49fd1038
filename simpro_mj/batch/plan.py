"""A batch's plan: its inputs expanded into rows (variants to run, or invalid entries).

Each PATH is a scenario file, a shipped scenario name or a folder (its
``*.yaml``/``*.yml`` files, sorted). A file's ``sweep:`` block
(:mod:`simpro_mj.config.sweep`) expands into variants; a file without one is one
variant named ``base``. ``--set`` overrides apply to the base of every variant.
A PATH that names nothing (no file, folder or shipped scenario) is the
command line's mistake (:func:`scenario_files` raises); an invalid file or
variant is a row with ``error`` set. Nothing runs here.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from simpro_mj.config.scenario import find_scenario
from simpro_mj.config.sweep import MAX_VARIANTS
from simpro_mj.config.variants import load_sweep
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import parse_set
from simpro_mj.core.messages import one_line

__all__ = ["GAIN_PATH", "Job", "Plan", "plan", "scenario_files"]

#: The swept path whose sweeps get a stability-limit table.
GAIN_PATH = "controller.outer.gains"


@dataclass
class Job:
    """One row of the batch: a variant to run (``scenario``) or an invalid entry."""

    index: int
    file: str
    scenario_name: str
    variant: str
    folder: str  # relative to OUT
    values: dict
    sample: int | None
    seed: int | None
    scenario: dict | None
    error: str | None = None
    gain_sweep: bool = False
    grid_paths: tuple = ()
    mc: bool = False


@dataclass
class Plan:
    """Everything the batch will do, in row order."""

    jobs: list[Job]
    paths: list[str]  # swept paths over all files, first appearance order
    files: list[dict]  # per file: path, scenario, folder, grid paths, mc, error


def scenario_files(paths: Iterable[str]) -> list[tuple[str, str | None]]:
    """(path or name, error) per input; folders expand to their YAML files.

    Raises
    ------
    UserInputError
        A path that is neither a file, a folder nor a shipped scenario name.
    """
    out: list[tuple[str, str | None]] = []
    seen = set()
    for p in paths:
        path = Path(p).expanduser()
        if path.is_dir():
            files = sorted(x for x in path.iterdir() if x.suffix in (".yaml", ".yml"))
            if not files:
                out.append((str(path), f"no scenario files at {path}: allowed: *.yaml files"))
            for f in files:
                key = str(f.resolve())
                if key not in seen:
                    seen.add(key)
                    out.append((str(f), None))
        else:
            if not path.is_file():
                # a path that names nothing is the command line's mistake (exit 2),
                # not a scenario file's: refuse before anything runs

                find_scenario(str(p))  # raises UserInputError listing the shipped names
            key = str(path.resolve()) if path.is_file() else str(p)
            if key not in seen:
                seen.add(key)
                out.append((str(p), None))
    return out


def _safe_folder(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._,+=-]", "-", name) or "scenario"


def plan(paths: Iterable[str], sets: Iterable[str] = ()) -> Plan:
    """Load and expand every input into rows (no run).

    Invalid files and variants become rows with ``error`` set; only a
    malformed ``--set`` (the same for every file) raises.
    """

    sets = list(sets or ())
    for expr in sets:
        parse_set(expr)  # a malformed --set is the command's mistake, not a file's
    jobs: list[Job] = []
    all_paths: list[str] = []
    files: list[dict] = []
    used: dict[str, int] = {}
    for entry, error in scenario_files(paths):
        sweep_file = None
        if error is None:
            try:
                sweep_file = load_sweep(entry, sets)
            except UserInputError as exc:
                error = one_line(exc)
        stem = Path(entry).stem if entry.endswith((".yaml", ".yml")) else Path(entry).name
        sname = sweep_file.scenario_name if sweep_file else stem
        folder = _safe_folder(sname)
        used[folder] = used.get(folder, 0) + 1
        if used[folder] > 1:
            folder = f"{folder}-{used[folder]}"
        spec = sweep_file.spec if sweep_file else None
        grid = tuple(spec.grid) if spec else ()
        mc = bool(spec and spec.samples)
        files.append(
            {
                "file": sweep_file.path if sweep_file else entry,
                "scenario": sname,
                "folder": folder,
                "grid_paths": list(grid),
                "mc_paths": [d.path for d in spec.parameters] if spec else [],
                "monte_carlo": mc,
                "error": error,
            }
        )
        if sweep_file is None:
            jobs.append(
                Job(len(jobs), entry, sname, "-", folder, {}, None, None, None, error=error)
            )
            continue
        for p in spec.paths if spec else ():
            if p not in all_paths:
                all_paths.append(p)
        for v in sweep_file.variants:
            jobs.append(
                Job(
                    index=len(jobs),
                    file=sweep_file.path,
                    scenario_name=sname,
                    variant=v.name,
                    folder=f"{folder}/{v.name}",
                    values=v.values,
                    sample=v.sample,
                    seed=v.seed,
                    scenario=v.scenario,
                    error=v.error,
                    gain_sweep=GAIN_PATH in grid,
                    grid_paths=grid,
                    mc=mc,
                )
            )
        if len(jobs) > MAX_VARIANTS:
            raise UserInputError(
                f"too many variants at {entry}: {len(jobs):,} so far in this batch; allowed: at "
                f"most {MAX_VARIANTS:,} variants per batch"
            )
    return Plan(jobs=jobs, paths=all_paths, files=files)
