"""Running one scenario into a result folder: the job behind ``simpro-sim run``.

:func:`execute` is what ``run``, ``compare``, ``batch``, ``render --bench``
and the Python API call; it lives here, outside the command modules, so that
none of them imports another command (imports run one way, see
docs/architecture.md).

Before stepping, :func:`simpro_mj.analysis.preflight.preflight` refuses a payload the
cylinders cannot hold (exit 2) and warns about outer gains above the analysed
stability limit. Warnings go to stderr as ``warning: ...`` lines and into
``metrics.json`` (``warnings``, figures under ``preflight``). With
``SIMPRO_READY_FILE`` set, the file is written once the simulation has taken
its first step under the signal handlers (:mod:`simpro_mj.sim.readiness`).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from simpro_mj.analysis.metrics import compute_metrics
from simpro_mj.analysis.preflight import preflight
from simpro_mj.core.interrupts import held_signals
from simpro_mj.plant.faults import flag_series
from simpro_mj.report.results import write_results
from simpro_mj.sim.readiness import signal_ready

__all__ = [
    "EXIT_INTERRUPTED",
    "execute",
    "measure",
    "warn",
    "interrupted_message",
]

#: Exit status of an interrupted run (128 + SIGINT, the shell's convention).
EXIT_INTERRUPTED = 130


def warn(lines, quiet: bool) -> None:
    """Print warnings on stderr as ``warning: ...`` lines, unless ``quiet``."""
    if not quiet:
        for line in lines:
            sys.stderr.write(f"warning: {line}\n")


def _end_stop_warnings(columns, scenario) -> tuple[list[str], list[dict]]:
    """Slides that reached an end stop while no fault was scheduled.

    The shipped scenarios keep every slide well inside its stroke; reaching a
    stop without a fault means the loop is unstable or the set-point too
    aggressive, which a plot of the pose alone would not tell.
    """
    t = columns.get("time_s")
    if t is None or not len(t):
        return [], []
    quiet = flag_series(scenario, t) == 0
    stroke = 0.5  # slide range of models/simpro_platform.xml (DNC-125-500)
    hits = []
    for i in (1, 2, 3):
        q = columns.get(f"q{i}_m")
        if q is None:
            continue
        for name, at in (("lower", q <= 0.0), ("upper", q >= stroke)):
            idx = np.flatnonzero(at & quiet)
            if idx.size:
                hits.append({"leg": i, "stop": name, "time_s": float(t[idx[0]])})
    lines = [
        f"leg {h['leg']} reached its {h['stop']} end stop at t = {h['time_s']:.3f} s with no "
        "fault scheduled: the closed loop is probably unstable (see the gain warnings) or "
        "the set-point too aggressive"
        for h in hits
    ]
    return lines, hits


def execute(scenario: dict, out: Path, plots: bool = True, *, quiet: bool = False):
    """Run a resolved scenario and write its result folder.

    Parameters
    ----------
    scenario : dict
        A resolved scenario.
    out : path
        The result folder.
    plots : bool
        Write the PNG figures.
    quiet : bool
        Do not print warnings on stderr (they are still in ``metrics.json``).

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
    out = Path(out)
    res, metrics, extra = measure(scenario, quiet=quiet)
    extra["plots"] = plots
    with held_signals():  # a folder is always written whole
        res.folder = write_results(
            out, res.columns, metrics, scenario, extra, arrays=recording(res)
        )
    return res, json.loads((res.folder / "metrics.json").read_text(encoding="utf-8"))


def measure(scenario: dict, *, quiet: bool = False):
    """Preflight, simulate and measure a resolved scenario, writing nothing.

    Returns
    -------
    (SimResult, dict, dict)
        The result, its metrics (with ``status``, ``reason``,
        ``sensor_floor``) and the rest of ``metrics.json``: ``sim`` (with the
        end-stop hits), ``warnings`` and ``preflight``. Warnings go to stderr
        unless ``quiet``.
    """
    # the loop loads MuJoCo: when a run starts, not when a command that refuses bad
    # input within a second imports the runner
    from simpro_mj.sim import loop as sim_module

    warnings, figures = preflight(scenario)
    warn(warnings, quiet)
    res = sim_module.simulate(scenario, progress=_stepping)
    metrics = compute_metrics(res.columns, scenario)
    metrics["status"] = res.status
    metrics["reason"] = res.reason
    metrics["sensor_floor"] = res.sensor_floor
    stop_lines, hits = _end_stop_warnings(res.columns, scenario)
    warn(stop_lines, quiet)
    extra = {
        "sim": dict(res.sim, end_stop_hits=hits),
        "warnings": warnings + stop_lines,
        "preflight": figures,
    }
    return res, metrics, extra


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


def _stepping(k: int) -> None:
    """Progress callback (every 1000 steps): readiness once the run has steps to keep.

    Not at k = 0: a signal sent the moment the file appears must still find
    a partial result with at least one logged second to write.
    """
    if k > 0:
        signal_ready("stepping")


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
