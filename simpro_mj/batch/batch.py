"""``simpro-sim batch PATH...``: many runs, sweeps, Monte Carlo, in parallel.

Each PATH is a scenario file, a shipped scenario name or a folder (its
``*.yaml``/``*.yml`` files, sorted). A file's ``sweep:`` block
(:mod:`simpro_mj.config.sweep`) expands into variants; a file without one is one
variant named ``base``. ``--set`` overrides apply to the base of every variant.

Execution
---------
Every variant runs headless in a worker: :func:`run_variant` gets the
resolved scenario (plain JSON data) and its folder, builds its own MuJoCo
model, runs, writes a normal result folder (:func:`simpro_mj.report.runner.execute`,
atomic) and returns a small dict. No model is ever pickled.

* ``--jobs N`` (default ``os.cpu_count()``, at most :data:`MAX_JOBS`): a
  ``ProcessPoolExecutor`` with ``spawn`` workers, never more than the
  variants to run; ``--jobs 1`` runs in this process, one after another.
* ``--scheduler ADDRESS``: the same tasks on a running Dask distributed
  scheduler; ``--scheduler local`` starts a ``LocalCluster`` of ``--jobs``
  single-threaded worker processes (no more than the variants to run). The
  worker writes into a temporary folder and sends the files back, so the
  results land in the same layout here whether or not the workers share this
  file system
  (``pip install 'simpro-sim[cluster]'``).
* A progress bar (tqdm, stderr; off with ``--quiet`` or when stderr is not a
  terminal) shows done/failed/left and the time left.

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
(:func:`simpro_mj.report.results.is_complete`: the result marker, ``metrics.json``
with status ``ok`` or ``diverged``, a non-empty ``timeseries.csv``, no
``PARTIAL``) and whose ``scenario.hash`` equals the variant's
:func:`~simpro_mj.config.scenario.scenario_hash`. Anything else is recomputed.

``--out`` must be new, empty or an earlier batch's folder (its
``.simpro-result`` marker of kind ``batch``); anything else is refused (exit
2) before anything runs, and a second batch writing the same ``--out`` at the
same time is refused (:func:`simpro_mj.report.results.claim`). The row of a skipped
variant is rebuilt from its files, so the summary is complete and the same as a fresh run's.

Layout
------
``OUT/<scenario>/<variant>/`` result folders, ``OUT/summary.csv`` (one row
per variant, expansion order), ``OUT/summary.json`` (the rows with full
precision, the stability-limit table, counts) and ``OUT/plots/*.png``
(:mod:`simpro_mj.batch.plots`).

summary.csv columns: ``variant``, ``scenario``, ``folder`` (relative to
OUT), one column per swept path (the value as declared, or as drawn),
``sample`` (Monte Carlo), ``seed``, ``status``, ``reason``, per axis
``<axis>_ss_err_<u>`` (signed mean error over the final window),
``<axis>_rms_err_<u>``, ``<axis>_max_err_<u>``, ``<axis>_rise_s``,
``<axis>_settling_s``, ``<axis>_overshoot_pct`` with ``u`` = deg (roll,
pitch) or mm (heave), then ``stable``, ``growth_rate_1_s``, for sweeps of
``controller.outer.gains`` ``analytic_limit``, ``analytic_limit_delay_model``
and ``analytic_growth_rate_1_s``, and last ``realtime_factor`` (the only
wall-clock column).

Stability criterion (measured)
------------------------------
From ``timeseries.csv``: per task axis the error ``reference - true pose``
in units of the settling floor (0.02 deg, 0.2 mm: the noise level of the
loop, :data:`simpro_mj.analysis.metrics.SETTLING_FLOOR`), and its peak in blocks of
0.5 s from 1 s after the reference last moves (the last half of the run if
it moves until less than 1.5 s before the end).

* ``growth_rate_1_s``: the envelope's growth rate, the largest over the axes
  of the least-squares slope of ln(peak) against time over the blocks above
  the noise (peak > 3 floors; at least 3 such blocks and one above 10
  floors; ``None`` if no axis has them: the run settled at noise level).
  Negative: decaying. It compares with ``analytic_growth_rate_1_s``.
* A run is **unstable** (``stable = False``) if it diverged, or the growth
  rate exceeds 0.1 1/s (the envelope grows by > 10 %/s), or on an axis whose
  envelope does not decay faster than 0.1 1/s the error's largest deviation
  from a straight line fitted over the last half of the run (an offset or a
  slow drift is not an oscillation) exceeds both 10 floors and half the
  largest reference excursion: an oscillation that saturation or the end
  stops keep from growing further, or one on the limit.

Stability limit (sweeps of ``controller.outer.gains``)
------------------------------------------------------
For every combination of the other grid values, over the variants with a
common gain g = K K_I on the three axes: the simulated limit lies between
the largest stable and the smallest unstable g; its estimate is where the
measured growth rate crosses zero (linear interpolation between those two
variants; the midpoint if their rates do not bracket zero). The analytic
limit is :func:`controllers.analysis.real_inner_limit` for the variant's
outer type, period, ``pi_zero``, inner variant and discretisation on the
paper's plants with the IK Jacobian at home (``analytic_limit``; ``None``
if the joint loops are designed on the identified plants or the mode is
joint-only), and ``analytic_limit_delay_model`` the one-sample-delay model
of eq. (21). The analysis is linear: it describes ``actuator.model:
linear``; the table notes when the plant is the nonlinear one.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import shutil
import sys
import tempfile
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from simpro_mj.sim import executors as _executors
from simpro_mj.sim.executors import NoWorkers, Progress, dask_module, run_tasks
from simpro_mj.sim.executors import one_line as _one_line

#: Variant statuses, and those a finished run can have.
STATUSES = ("ok", "diverged", "interrupted", "failed", "invalid", "cancelled")
RUN_STATUSES = ("ok", "diverged")
GAIN_PATH = "controller.outer.gains"
#: A Dask batch whose cluster has had no live worker this long (s) ends with an error
#: (read at each batch: tests shorten it).
NO_WORKERS_S = _executors.NO_WORKERS_S

#: Stability criterion (module docstring).
BLOCK_S = 0.5
GROWTH_LIMIT_1_S = 0.1
AMPLITUDE_FLOORS = 10.0
NOISE_FLOORS = 3.0
SETTLE_AFTER_S = 1.0
HELD_FRACTION = 0.5

_AXES = (("roll", "deg", 180.0 / math.pi), ("pitch", "deg", 180.0 / math.pi), ("heave", "mm", 1e3))
#: (column suffix, metrics.json key, scaled to the axis unit?)
_METRICS = (
    ("ss_err", "steady_state_error", True),
    ("rms_err", "rms_error", True),
    ("max_err", "max_abs_error", True),
    ("rise_s", "rise_time_s", False),
    ("settling_s", "settling_time_s", False),
    ("overshoot_pct", "overshoot_pct", False),
)
_TS_COLUMNS = {
    "roll": ("roll_ref_rad", "roll_rad"),
    "pitch": ("pitch_ref_rad", "pitch_rad"),
    "heave": ("heave_ref_m", "heave_m"),
}


def metric_columns() -> list[str]:
    """Per-axis metric column names of summary.csv (units in the names)."""
    out = []
    for axis, unit, _ in _AXES:
        for suffix, _, scaled in _METRICS:
            out.append(f"{axis}_{suffix}_{unit}" if scaled else f"{axis}_{suffix}")
    return out


# ------------------------------------------------------------------ planning


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


def _scenario_files(paths: Iterable[str]) -> list[tuple[str, str | None]]:
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
                from simpro_mj.config.scenario import _find

                _find(str(p))  # raises UserInputError listing the shipped names
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
    from simpro_mj.config.sweep import MAX_VARIANTS
    from simpro_mj.config.variants import load_sweep
    from simpro_mj.core.errors import UserInputError
    from simpro_mj.core.keys import parse_set

    sets = list(sets or ())
    for expr in sets:
        parse_set(expr)  # a malformed --set is the command's mistake, not a file's
    jobs: list[Job] = []
    all_paths: list[str] = []
    files: list[dict] = []
    used: dict[str, int] = {}
    for entry, error in _scenario_files(paths):
        sweep_file = None
        if error is None:
            try:
                sweep_file = load_sweep(entry, sets)
            except UserInputError as exc:
                error = " ".join(str(exc).split())
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


# ------------------------------------------------------------------ worker


def run_variant(task: Mapping) -> dict:
    """Run one variant (worker side; top level so that it pickles by name).

    Parameters
    ----------
    task : mapping
        ``scenario`` (resolved, plain data), ``out`` (its folder), ``plots``
        (bool), ``ship`` (bool: write into a temporary folder and return the
        files' bytes, for workers that may not share this file system).

    Returns
    -------
    dict
        ``status``, ``reason``, ``metrics`` (the ``metrics.json`` document,
        ``None`` if the run failed), ``stability`` (:func:`stability_of_folder`)
        and, when shipping, ``files`` (name -> bytes).
    """
    from simpro_mj.core.errors import UserInputError

    ship = bool(task.get("ship"))
    tmp = Path(tempfile.mkdtemp(prefix="simpro-batch-")) if ship else None
    try:
        from simpro_mj.report.runner import execute

        folder = tmp / "variant" if ship else Path(task["out"])
        # warnings go to metrics.json only: many workers on one stderr would be noise
        res, doc = execute(
            task["scenario"], folder, plots=bool(task.get("plots", True)), quiet=True
        )
        folder = res.folder
        out = {
            "status": doc.get("status", "ok"),
            "reason": doc.get("reason"),
            "metrics": doc,
            "stability": stability_of_folder(folder, doc.get("status")),
        }
        if ship:
            out["files"] = {p.name: p.read_bytes() for p in sorted(folder.iterdir())}
        return out
    except UserInputError as exc:  # a value only the plant checks
        return {"status": "invalid", "reason": " ".join(str(exc).split()), "metrics": None}
    except Exception as exc:  # noqa: BLE001 - any failure is this variant's, not the batch's
        return {"status": "failed", "reason": _one_line(exc), "metrics": None}
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def _install(files: Mapping[str, bytes], out: Path) -> None:
    """Write shipped files as a result folder, atomically (as results.write_results)."""
    from simpro_mj.report.results import install_folder

    def fill(tmp: Path) -> None:
        for name, data in files.items():
            (tmp / Path(name).name).write_bytes(data)

    install_folder(out, fill)


# ------------------------------------------------------------------ stability


def stability_of(columns: Mapping, status: str | None = "ok") -> dict:
    """Measured stability of a run from its time series (criterion: module docstring).

    Returns
    -------
    dict
        ``stable`` (bool), ``growth_rate_1_s`` (float or None),
        ``oscillation_floors`` and ``reference_floors`` (largest detrended
        error and reference excursion, in settling floors) and ``why`` (None
        or the reason it is unstable).
    """
    import numpy as np

    from simpro_mj.analysis.metrics import SETTLING_FLOOR

    out = {
        "stable": True,
        "growth_rate_1_s": None,
        "oscillation_floors": None,
        "reference_floors": None,
        "why": None,
    }
    if status == "diverged":
        out.update(stable=False, why="diverged")
    t = np.asarray(columns.get("time_s", []), dtype=float)
    if t.size < 2:
        return out
    ok = np.isfinite(t)
    errs, refs = {}, 0.0
    for axis, (ref_name, true_name) in _TS_COLUMNS.items():
        floor = SETTLING_FLOOR[axis]
        ref = np.asarray(columns[ref_name], dtype=float)
        errs[axis] = (ref - np.asarray(columns[true_name], dtype=float)) / floor
        ok &= np.isfinite(errs[axis])
        fin = ref[np.isfinite(ref)]
        if fin.size:
            refs = max(refs, float(np.max(np.abs(fin - fin[0]))) / floor)
    n = t.size if ok.all() else int(np.argmin(ok))  # a diverged run: its finite part
    t = t[:n]
    out["reference_floors"] = refs
    if n < 2:
        return out
    start = _settled_from(columns, t)
    edges = np.arange(start, t[-1] + 1e-9, BLOCK_S)
    late = t >= t[0] + 0.5 * (t[-1] - t[0])
    rates, osc, held = [], [], []
    for err in errs.values():
        e = err[:n]
        peaks, centres = [], []
        for a in edges[:-1]:
            sel = (t >= a) & (t < a + BLOCK_S)
            if sel.any():
                peaks.append(float(np.abs(e[sel]).max()))
                centres.append(a + 0.5 * BLOCK_S)
        # the envelope above the noise: blocks of more than NOISE_FLOORS
        loud = np.asarray(peaks) > NOISE_FLOORS
        rate = None
        if loud.sum() >= 3 and max(peaks) > AMPLITUDE_FLOORS:
            x, y = np.asarray(centres)[loud], np.log(np.asarray(peaks)[loud])
            rate = float(np.polyfit(x, y, 1)[0])
            rates.append(rate)
        # the oscillation about a straight line: an offset or a slow drift is not one
        tl, el = t[late], e[late]
        amp = 0.0
        if tl.size >= 3:
            amp = float(np.abs(el - np.polyval(np.polyfit(tl - tl[0], el, 1), tl - tl[0])).max())
        osc.append(amp)
        if (
            amp > AMPLITUDE_FLOORS
            and amp > HELD_FRACTION * refs
            and (rate is None or rate > -GROWTH_LIMIT_1_S)
        ):
            held.append(amp)
    out["oscillation_floors"] = max(osc) if osc else None
    out["growth_rate_1_s"] = max(rates) if rates else None
    if out["why"] is None:
        if rates and max(rates) > GROWTH_LIMIT_1_S:
            out.update(stable=False, why=f"error envelope grows at {max(rates):.3g} 1/s")
        elif held:
            out.update(
                stable=False,
                why=f"held oscillation of {max(held):.3g} floors (reference {refs:.3g} floors)",
            )
    return out


def _settled_from(columns: Mapping, t) -> float:
    """Start of the envelope fit: 1 s after the reference last moves, else the last half."""
    import numpy as np

    n = t.size
    moving = np.zeros(max(n - 1, 0), dtype=bool)
    for ref_name, _ in _TS_COLUMNS.values():
        ref = np.asarray(columns[ref_name], dtype=float)[:n]
        moving |= np.abs(np.diff(ref)) > 1e-12
    half = float(t[0] + 0.5 * (t[-1] - t[0]))
    if not moving.any():
        return float(t[0])
    start = float(t[int(np.flatnonzero(moving)[-1]) + 1]) + SETTLE_AFTER_S
    return start if t[-1] - start >= 3 * BLOCK_S else half


def stability_of_folder(folder: Path, status: str | None = "ok") -> dict:
    """:func:`stability_of` of a result folder's ``timeseries.csv``."""
    from simpro_mj.report.results import read_timeseries

    return stability_of(read_timeseries(Path(folder) / "timeseries.csv"), status)


@lru_cache(maxsize=64)
def _lifted(period: float, variant: str, method: str, zeta: float, wn: float, filt=None):
    from controllers import analysis as an

    spec = {"zeta": zeta, "wn": wn} if variant == "redesigned" else None
    return an.lifted_inner(period, variant=variant, method=method, spec=spec, setpoint_filter=filt)


@lru_cache(maxsize=64)
def _jacobian_home():
    from controllers.geometry import nominal_geometry
    from controllers.kinematics import jacobian

    return jacobian(nominal_geometry().home)


@lru_cache(maxsize=64)
def _limits(
    kind, period, variant, method, pi_zero, zeta, wn, delay, filt=None
) -> tuple[float, float]:
    from controllers import analysis as an

    spec = {"zeta": zeta, "wn": wn} if variant == "redesigned" else None
    real = an.real_inner_limit(
        kind,
        period,
        variant=variant,
        method=method,
        jac=_jacobian_home(),
        pi_zero=pi_zero,
        spec=spec,
        setpoint_filter=filt,
    )
    try:
        delay_lim = an.closed_form_limit(kind, period, delay, pi_zero)
    except NotImplementedError:
        delay_lim = an.stability_limit(*an.outer_polynomials(kind, period, delay, pi_zero))
    return float(real), float(delay_lim)


def analytic(scenario: Mapping) -> dict:
    """The analysis' view of a variant's outer loop (module docstring).

    Returns
    -------
    dict
        ``analytic_limit`` (real inner loops), ``analytic_limit_delay_model``
        and ``analytic_growth_rate_1_s`` (ln of the closed loop's spectral
        radius per outer period, at the variant's gains); ``None`` values when
        the analysis does not apply (joint-only, identified design plants).
    """
    none = {
        "analytic_limit": None,
        "analytic_limit_delay_model": None,
        "analytic_growth_rate_1_s": None,
    }
    c = scenario["controller"]
    if c["mode"] != "task_space" or c["inner"]["design_plant"] != "paper":
        return none
    from controllers import analysis as an

    o, i = c["outer"], c["inner"]
    period = o["period_ms"] * 1e-3
    sf = c["setpoint_filter"]
    # Fig. 13's filter, in the analysis: (kind, per-leg times) hashable for the caches
    filt = (sf["type"], tuple(t * 1e-3 for t in sf["time_ms"]))  # validated: 3 per-leg times
    key = (
        period, i["variant"], i["discretisation"], float(i["zeta"]), float(i["wn_rad_s"]), filt
    )  # fmt: skip
    from controllers.task_space import outer_law

    law, pi_zero = outer_law(o["type"], o["integrator"], o["pi_zero"])
    real, delay = _limits(law, *key[:3], pi_zero, *key[3:5], int(o["delay_samples"]), filt)
    f = an.outer_closed_loop(
        law, list(o["gains"]), period, _lifted(*key), _jacobian_home(), pi_zero
    )[0]
    rho = an.spectral_radius(f)
    return {
        "analytic_limit": real,
        "analytic_limit_delay_model": delay,
        "analytic_growth_rate_1_s": math.log(rho) / period if rho > 0 else None,
    }


# ------------------------------------------------------------------ rows


def _sim_rt(doc: Mapping) -> float | None:
    sim = doc.get("sim") or {}
    rt = sim.get("realtime_factor")
    if rt is None:
        rt = (sim.get("wall_clock") or {}).get("realtime_factor")
    return rt


def _row(job: Job, result: Mapping | None, skipped: bool = False) -> dict:
    """One summary row (SI converted to the column units)."""
    row: dict[str, Any] = {
        "variant": job.variant,
        "scenario": job.scenario_name,
        "folder": job.folder if job.scenario is not None else "",
        "file": job.file,
        "values": dict(job.values),
        "sample": job.sample,
        "seed": job.seed,
        "status": "invalid" if job.error else "cancelled",
        "reason": job.error,
        "skipped": skipped,
    }
    for col in metric_columns():
        row[col] = None
    row.update(stable=None, growth_rate_1_s=None, stability_note=None)
    if job.gain_sweep:
        row.update(
            analytic_limit=None, analytic_limit_delay_model=None, analytic_growth_rate_1_s=None
        )
    row["realtime_factor"] = None
    if job.scenario is not None and job.gain_sweep:
        row.update(analytic(job.scenario))
    if result is None:
        return row
    row["status"] = result.get("status", "failed")
    row["reason"] = result.get("reason")
    doc = result.get("metrics")
    if doc:
        axes = doc.get("axes") or {}
        for axis, unit, scale in _AXES:
            m = axes.get(axis) or {}
            for suffix, key, scaled in _METRICS:
                v = m.get(key)
                row[f"{axis}_{suffix}_{unit}" if scaled else f"{axis}_{suffix}"] = (
                    None if v is None else float(v) * (scale if scaled else 1.0)
                )
        row["realtime_factor"] = _sim_rt(doc)
        cue = doc.get("cueing") or (doc.get("metrics") or {}).get("cueing")
        if cue:  # issue 16
            from simpro_mj.config.cueing import summary_columns

            row.update(summary_columns(cue))
    stab = result.get("stability")
    if stab:
        row["stable"] = stab["stable"]
        row["growth_rate_1_s"] = stab["growth_rate_1_s"]
        row["stability_note"] = stab["why"]
    return row


def _complete(folder: Path, scenario: Mapping) -> dict | None:
    """The metrics.json document of a complete result folder for ``scenario``, else None.

    Complete is :func:`simpro_mj.report.results.is_complete` (the one documented
    check), and the folder's scenario hash must be the variant's.
    """
    from simpro_mj.config.scenario import scenario_hash
    from simpro_mj.report.results import is_complete

    if not is_complete(folder):
        return None
    try:
        doc = json.loads((folder / "metrics.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if (doc.get("scenario") or {}).get("hash") != scenario_hash(scenario):
        return None
    return doc


# ------------------------------------------------------------------ executors


# ------------------------------------------------------------------ the batch


@dataclass
class Report:
    """What a batch did: rows in expansion order, the stability table, files written."""

    out: Path
    rows: list[dict]
    paths: list[str]
    files: list[dict]
    stability: list[dict] = field(default_factory=list)
    monte_carlo: list[dict] = field(default_factory=list)
    plots: list[str] = field(default_factory=list)
    skipped: int = 0
    wall_s: float = 0.0
    #: why the batch stopped before its end (a signal, no Dask workers), else None
    stopped: str | None = None

    @property
    def counts(self) -> dict:
        c = {s: 0 for s in STATUSES}
        for r in self.rows:
            c[r["status"]] = c.get(r["status"], 0) + 1
        return c

    @property
    def all_ok(self) -> bool:
        return bool(self.rows) and all(r["status"] == "ok" for r in self.rows)

    def document(self) -> dict:
        from simpro_mj.report.results import _jsonable

        return _jsonable(
            {
                "out": str(self.out),
                "summary_csv": str(self.out / "summary.csv"),
                "counts": self.counts,
                "skipped": self.skipped,
                "wall_s": self.wall_s,
                "stopped": self.stopped,
                "swept_paths": self.paths,
                "files": self.files,
                "stability": self.stability,
                "monte_carlo": self.monte_carlo,
                "plots": self.plots,
                "variants": self.rows,
            }
        )


def run_batch(
    paths: Iterable[str],
    out: Path,
    sets: Iterable[str] = (),
    jobs: int = 1,
    resume: bool = False,
    strict: bool = False,
    scheduler: str | None = None,
    plots: bool = True,
    progress: bool = False,
    summary_plots: bool = True,
) -> Report:
    """Plan, run and summarise a batch (see the module docstring).

    Raises
    ------
    UserInputError
        ``--strict`` with an invalid file or variant, a malformed ``--set``,
        or ``--scheduler`` without dask or without a reachable scheduler; an
        ``out`` that is not a batch folder or is being written by another batch.
    """
    from simpro_mj.report.results import claim

    wall0 = time.perf_counter()
    out = Path(out)
    inputs = [f for f, _ in _scenario_files(paths)]
    from simpro_mj.report.runner import sigterm_as_interrupt

    with claim(out, "batch", inputs=inputs), sigterm_as_interrupt():
        return _run_batch(
            paths, out, sets, jobs, resume, strict, scheduler, plots, progress, summary_plots, wall0
        )


def _run_batch(
    paths, out, sets, jobs, resume, strict, scheduler, plots, progress, summary_plots, wall0
) -> Report:
    from simpro_mj.core.errors import UserInputError
    from simpro_mj.report.results import write_marker

    p = plan(paths, sets)
    if strict:
        for job in p.jobs:
            if job.error:
                which = f" (variant {job.variant})" if job.variant != "-" else ""
                raise UserInputError(f"invalid scenario at {job.file}{which}: {job.error}")
    if scheduler is not None:
        dask_module()  # say so before anything runs
    rows: list[dict | None] = [None] * len(p.jobs)
    tasks: list[tuple[int, dict]] = []
    skipped = 0
    for job in p.jobs:
        if job.scenario is None:
            rows[job.index] = _row(job, None)
            continue
        folder = out / job.folder
        doc = _complete(folder, job.scenario) if resume else None
        if doc is not None:
            result = {
                "status": doc["status"],
                "reason": doc.get("reason"),
                "metrics": doc,
                "stability": stability_of_folder(folder, doc["status"]),
            }
            rows[job.index] = _row(job, result, skipped=True)
            skipped += 1
            continue
        tasks.append((job.index, {"scenario": job.scenario, "out": str(folder), "plots": plots}))
    if skipped and progress:
        sys.stderr.write(f"resume: {skipped} complete variant(s) skipped\n")
    bar = Progress(len(tasks), progress)

    def done(key: int, result: dict) -> None:
        files = result.pop("files", None)
        if files is not None:
            _install(files, out / p.jobs[key].folder)
        rows[key] = _row(p.jobs[key], result)
        bar.update(rows[key]["status"])

    out.mkdir(parents=True, exist_ok=True)
    write_marker(out, "batch")
    stopped = None
    try:
        run_tasks(
            tasks, done, jobs=jobs, scheduler=scheduler, fn=run_variant, no_workers_s=NO_WORKERS_S
        )
    except KeyboardInterrupt as exc:  # SIGINT, or SIGTERM (sigterm_as_interrupt)
        stopped = f"interrupted ({exc})" if str(exc) else "interrupted"
    except NoWorkers as exc:
        stopped = str(exc)
    finally:
        bar.close()
        # what finished is recorded, the rest is 'cancelled'; also on an error
        final = [r if r is not None else _row(p.jobs[i], None) for i, r in enumerate(rows)]
        report = Report(out=out, rows=final, paths=p.paths, files=p.files, skipped=skipped)
        report.stability = stability_table(report.rows, p.jobs)
        report.monte_carlo = monte_carlo_table(report.rows, p.jobs)
        report.stopped = stopped
        for row in report.rows:
            if stopped and row["status"] == "cancelled" and not row["reason"]:
                row["reason"] = f"not finished: batch stopped: {stopped}"
        report.wall_s = time.perf_counter() - wall0
        write_summary(report)
    if stopped is not None:
        return report  # no summary plots: the user asked to stop, or the cluster is gone
    if summary_plots:
        from simpro_mj.batch.plots import plot_summary

        report.plots = [str(x) for x in plot_summary(report, p.jobs)]
    report.wall_s = time.perf_counter() - wall0
    write_summary(report)
    return report


# ------------------------------------------------------------------ summary


def _gain(values: Mapping) -> float | None:
    """The common K K_I of a variant's swept gains, or None (unequal per-axis gains)."""
    g = values.get(GAIN_PATH)
    if isinstance(g, (int, float)) and not isinstance(g, bool):
        return float(g)
    if isinstance(g, list) and g and len({float(x) for x in g}) == 1:
        return float(g[0])
    return None


def stability_table(rows: list[dict], jobs: list[Job]) -> list[dict]:
    """Analytic vs simulated stability limit per gain sweep group (module docstring)."""
    from simpro_mj.config.sweep import format_value

    groups: dict[tuple, list[tuple[float, dict, Job]]] = {}
    for row, job in zip(rows, jobs, strict=True):
        if not job.gain_sweep or job.mc or row["stable"] is None:
            continue
        g = _gain(job.values)
        if g is None:
            continue
        others = tuple((p, format_value(job.values[p])) for p in job.grid_paths if p != GAIN_PATH)
        groups.setdefault((job.scenario_name, others), []).append((g, row, job))
    table = []
    for (sname, others), members in groups.items():
        members.sort(key=lambda m: m[0])
        gains = [m[0] for m in members]
        stable = [bool(m[1]["stable"]) for m in members]
        unstable_at = [g for g, s in zip(gains, stable, strict=True) if not s]
        hi = min(unstable_at) if unstable_at else None
        below = [m for m in members if m[1]["stable"] and (hi is None or m[0] < hi)]
        lo_m = below[-1] if below else None
        lo = lo_m[0] if lo_m else None
        estimate = None
        if lo is not None and hi is not None:
            hi_m = next(m for m in members if m[0] == hi)
            s_lo, s_hi = lo_m[1]["growth_rate_1_s"], hi_m[1]["growth_rate_1_s"]
            if s_lo is not None and s_hi is not None and s_lo < 0 < s_hi:
                estimate = lo + (hi - lo) * (-s_lo) / (s_hi - s_lo)
            else:
                estimate = 0.5 * (lo + hi)
        first = members[0][2].scenario
        ana = members[0][1].get("analytic_limit")
        note = []
        if first["actuator"]["model"] != "linear":
            note.append("nonlinear pneumatics: the analysis assumes eq. (19) plants")
        if any(s and g > hi for g, s in zip(gains, stable, strict=True) if hi is not None):
            note.append("not monotonic: a stable gain above an unstable one")
        table.append(
            {
                "scenario": sname,
                "group": {p: v for p, v in others},
                "outer_type": first["controller"]["outer"]["type"],
                "period_ms": first["controller"]["outer"]["period_ms"],
                "actuator_model": first["actuator"]["model"],
                "gains": gains,
                "stable": stable,
                "growth_rate_1_s": [m[1]["growth_rate_1_s"] for m in members],
                "largest_stable": lo,
                "smallest_unstable": hi,
                "simulated_limit": estimate,
                "analytic_limit": ana,
                "analytic_limit_delay_model": members[0][1].get("analytic_limit_delay_model"),
                "simulated_over_analytic": (estimate / ana) if estimate and ana else None,
                "note": "; ".join(note) or None,
            }
        )
    return table


def monte_carlo_table(rows: list[dict], jobs: list[Job]) -> list[dict]:
    """Distribution of |steady-state error| per Monte Carlo file and grid combination.

    Per axis the median, 90th percentile and maximum over the variants with
    status ``ok`` (deg, deg, mm as in the summary columns).
    """
    import numpy as np

    from simpro_mj.config.sweep import format_value

    files: dict[str, dict] = {}
    for row, job in zip(rows, jobs, strict=True):
        if not job.mc:
            continue
        f = files.setdefault(job.scenario_name, {"samples": 0, "groups": {}})
        f["samples"] = max(f["samples"], (job.sample or 0) + 1)
        group = ", ".join(
            f"{p.split('.')[-1]}={format_value(job.values[p])}" for p in job.grid_paths
        )
        f["groups"].setdefault(group or "all", []).append(row)
    out = []
    for sname, f in files.items():
        groups = []
        for name, members in f["groups"].items():
            ok = [r for r in members if r["status"] == "ok"]
            axes = {}
            for axis, unit, _ in _AXES:
                v = np.abs(
                    [
                        r[f"{axis}_ss_err_{unit}"]
                        for r in ok
                        if r[f"{axis}_ss_err_{unit}"] is not None
                    ]
                )
                axes[axis] = {
                    "unit": unit,
                    "median": float(np.median(v)) if v.size else None,
                    "p90": float(np.percentile(v, 90)) if v.size else None,
                    "max": float(v.max()) if v.size else None,
                }
            groups.append({"group": name, "n": len(ok), "of": len(members), "axes": axes})
        out.append({"scenario": sname, "samples": f["samples"], "groups": groups})
    return out


def _cell(v: Any) -> str:
    from simpro_mj.config.sweep import format_value

    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, (list, tuple, dict)):
        return format_value(v)
    return str(v)


def csv_columns(report: Report) -> list[str]:
    """summary.csv's columns for this batch (module docstring)."""
    cols = ["variant", "scenario", "folder", *report.paths]
    if any(r["sample"] is not None for r in report.rows):
        cols.append("sample")
    cols += ["seed", "status", "reason", *metric_columns(), "stable", "growth_rate_1_s"]
    if any("analytic_limit" in r for r in report.rows):
        cols += ["analytic_limit", "analytic_limit_delay_model", "analytic_growth_rate_1_s"]
    if any("cue_long_corr" in r for r in report.rows):  # cueing runs (issue 16)
        from simpro_mj.config.cueing import SUMMARY_COLUMNS

        cols += list(SUMMARY_COLUMNS)
    cols.append("realtime_factor")
    return cols


def summary_csv_text(report: Report) -> str:
    cols = csv_columns(report)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in report.rows:
        w.writerow([_cell(r["values"].get(c) if c in report.paths else r.get(c)) for c in cols])
    return buf.getvalue()


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def write_summary(report: Report) -> None:
    """Write ``summary.csv`` and ``summary.json`` into the batch folder (atomically)."""
    report.out.mkdir(parents=True, exist_ok=True)
    _atomic_write(report.out / "summary.csv", summary_csv_text(report))
    text = json.dumps(report.document(), indent=2, allow_nan=False)
    _atomic_write(report.out / "summary.json", text + "\n")


def _num(v: Any, digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}g}"


def print_report(report: Report, file=None) -> None:
    """The human summary: a line per variant, the stability table, counts, paths."""
    file = sys.stdout if file is None else file
    header = (
        f"{'variant':<34} {'status':<9} {'stable':<6} {'roll ss':>9} {'pitch ss':>9} "
        f"{'heave ss':>9} {'growth':>7} {'rt x':>6}"
    )
    last = None
    for r in report.rows:
        if r["scenario"] != last:
            print(f"\n{r['scenario']}  ({r['file']})", file=file)
            print(header + "\n" + "-" * len(header), file=file)
            last = r["scenario"]
        stable = "-" if r["stable"] is None else ("yes" if r["stable"] else "NO")
        print(
            f"{r['variant']:<34} {r['status']:<9} {stable:<6} "
            f"{_num(r['roll_ss_err_deg'], 3):>9} {_num(r['pitch_ss_err_deg'], 3):>9} "
            f"{_num(r['heave_ss_err_mm'], 3):>9} {_num(r['growth_rate_1_s'], 2):>7} "
            f"{_num(r['realtime_factor'], 3):>6}",
            file=file,
        )
        if r["status"] not in ("ok", "diverged") or (r["status"] == "diverged" and r["reason"]):
            print(f"    {r['status']}: {r['reason']}", file=file)
    print(
        "(ss: steady-state error, deg, deg, mm; growth: error envelope, 1/s; "
        "rt x: realtime factor)",
        file=file,
    )
    for m in report.monte_carlo:
        print(
            f"\nMonte Carlo {m['scenario']}, |steady-state error| over {m['samples']} samples "
            "(median / 90th percentile / max):",
            file=file,
        )
        for g in m["groups"]:
            cells = []
            for axis, unit, _ in _AXES:
                st = g["axes"][axis]
                cells.append(
                    f"{axis} {_num(st['median'], 3)} / {_num(st['p90'], 3)} / "
                    f"{_num(st['max'], 3)} {unit}"
                )
            print(f"  {g['group']:<24} n={g['n']:<3} " + "; ".join(cells), file=file)
    if report.stability:
        print("\nstability limit, K K_I (1/s):", file=file)
        print(
            f"{'scenario':<20} {'group':<26} {'analytic':>9} {'delay mdl':>9} "
            f"{'stable <=':>9} {'unstable >=':>11} {'simulated':>9} {'sim/ana':>7}",
            file=file,
        )
        for s in report.stability:
            group = ",".join(f"{k.split('.')[-1]}={v}" for k, v in s["group"].items()) or "-"
            print(
                f"{s['scenario']:<20} {group:<26} {_num(s['analytic_limit']):>9} "
                f"{_num(s['analytic_limit_delay_model']):>9} {_num(s['largest_stable']):>9} "
                f"{_num(s['smallest_unstable']):>11} {_num(s['simulated_limit']):>9} "
                f"{_num(s['simulated_over_analytic'], 3):>7}",
                file=file,
            )
            if s["note"]:
                print(f"    note: {s['note']}", file=file)
    c = report.counts
    counts = ", ".join(f"{k} {v}" for k, v in c.items() if v)
    extra = f", {report.skipped} skipped (complete)" if report.skipped else ""
    print(f"\n{len(report.rows)} variants: {counts}{extra}; {report.wall_s:.1f} s", file=file)
    print(f"summary: {report.out / 'summary.csv'}", file=file)
    for pth in report.plots:
        print(f"plot: {pth}", file=file)
