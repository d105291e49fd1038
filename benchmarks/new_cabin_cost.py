"""Where a new cabin's CPU time goes: one variant of a Monte Carlo, profiled.

    python benchmarks/new_cabin_cost.py [--variant mc004] [--warm mc005] [--as-shipped] [--plots]
        [--identify auto|reduced] [--timeseries all|failing|none]

Runs two variants of ``scenarios/sweep_robustness.yaml`` with ``--set
controller.inner.identify=auto`` (each draw's joint loops placed on its own
identified plant) in this process as a batch's worker does
(:func:`simpro_mj.batch.worker.run_variant`), each a plant not seen before (an
empty identification cache in a temporary folder): first
``--warm`` (imports, numba's cache of the compiled step, MuJoCo's callback),
then ``--variant`` under cProfile with a CPU timer (``time.process_time``), and
prints one JSON document, CPU seconds:

* ``total``: the variant (identification, design, analysis, run, result folder);
* ``identification``: the Fig. 12 experiment on its three legs with their fits,
  of which ``experiment`` (the stepping, :func:`simpro_mj.sim.experiment.step_experiment`)
  and ``fit`` (:func:`simpro_mj.identification.identify.fit_eq19`); with
  ``--identify reduced`` the experiment on the reduced chain
  (:func:`simpro_mj.identification.reduced_experiment.identify_reduced`), its records
  (``run_reduced``) and fits (:func:`simpro_mj.identification.sensitivity_fit.fit_sensitivity`);
* ``stability_limit`` (the loop analysis), ``run`` (the run's own stepping,
  ``CoSimulation.run``), ``result_folder`` (writing it);
* ``figures`` (the run's PNGs, :func:`simpro_mj.report.plots.plot_run`: with
  ``--plots`` only) and ``timeseries_csv`` (writing it), parts of ``result_folder``,
  and ``stability`` (the batch's measured stability, from the run's columns in memory
  rounded as ``timeseries.csv`` holds them) beside it;
* ``experiment_us_per_step`` and ``run_us_per_step``;
* ``cpu_s``: the variant's CPU time measured again unprofiled (a third variant,
  ``mc006`` or ``mc007``, the same way).

``--as-shipped``: the sweep as shipped (the cabin's one controller on every draw,
no experiment): what outside the step a sweep's variant costs. ``--plots``: with
its figures, as ``simpro-sim batch --plots all`` draws them. ``--timeseries``: the
batch's (``simpro-sim batch --timeseries``; default ``all``).

cProfile counts Python calls, so it inflates a loop of many small calls more
than one ``mj_step`` of many steps: read the parts against each other, and the
unprofiled ``cpu_s`` of ``summary.json`` for a variant's cost. A speed figure:
here, not in a timed test. Meaningful on a quiet machine only.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import re
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "sweep_robustness.yaml"
#: every variant's joint loops placed on its own plant's identified models
AUTO = "controller.inner.identify=auto"
#: the parts under ``--identify reduced``: the reduced experiment's
REDUCED = {
    "identification": ("identification/reduced_experiment.py", "identify_reduced"),
    "experiment": ("identification/reduced_experiment.py", "run_reduced"),
    "fit": ("identification/sensitivity_fit.py", "fit_sensitivity"),
}

#: The parts, as (a path's ending, function name) of the function whose cumulative
#: time is the part's.
PARTS = {
    "total": ("batch/worker.py", "run_variant"),
    "identification": ("identification/identify.py", "identify"),
    "experiment": ("sim/experiment.py", "step_experiment"),
    "fit": ("identification/identify.py", "fit_eq19"),
    "stability_limit": ("analysis/preflight.py", "stability_limit"),
    "run": ("sim/loop.py", "run"),
    "result_folder": ("report/results.py", "write_folder"),
    "figures": ("report/plots.py", "plot_run"),
    "timeseries_csv": ("report/results.py", "write_timeseries"),
    "stability": ("batch/stability.py", "stability_of"),
}


def measure(
    variant: str = "mc004",
    warm: str = "mc005",
    as_shipped: bool = False,
    plots: bool = False,
    identify: str = "auto",
    timeseries: str = "all",
) -> dict:
    """Profile ``variant`` after ``warm`` (module docstring); the figures."""
    with tempfile.TemporaryDirectory(prefix="simpro-cabin-cost-") as tmp:
        os.environ["SIMPRO_CACHE_DIR"] = str(Path(tmp) / "cache")
        from simpro_mj.batch.plan import plan
        from simpro_mj.batch.worker import run_variant

        # each draw's loops placed on its own identification (the shipped sweep runs
        # the cabin's one controller on every draw)
        sets = [] if as_shipped else [AUTO.replace("=auto", f"={identify}")]
        jobs = {j.variant: j for j in plan([str(SCENARIO)], sets).jobs}
        from simpro_mj.identification.auto import experiment_s

        if not as_shipped and identify == "auto" and not experiment_s(jobs[variant].scenario) > 0:
            raise RuntimeError(f"{variant} would run no identification experiment")

        def task(v):
            return {"scenario": jobs[v].scenario, "out": f"{tmp}/{v}", "plots": plots,
                    "label": v, "timeseries": timeseries}  # fmt: skip

        run_variant(task(warm))
        prof = cProfile.Profile(time.process_time)
        prof.enable()
        result = run_variant(task(variant))
        prof.disable()
        again = next(v for v in ("mc006", "mc007") if v not in (variant, warm))
        cpu_s = run_variant(task(again))["cpu_s"]
    stats = pstats.Stats(prof).stats  # type: ignore[attr-defined]  # pstats' own table
    out: dict = {"variant": variant, "status": result["status"], "as_shipped": as_shipped,
                 "plots": plots, "identify": identify, "timeseries": timeseries}  # fmt: skip
    parts = PARTS | (REDUCED if identify == "reduced" else {})
    for part, (path, name) in parts.items():
        out[part] = sum(v[3] for (f, _, n), v in stats.items() if n == name and f.endswith(path))
    scenario = jobs[variant].scenario
    from simpro_mj.identification.auto import plant_tree

    ip = plant_tree(scenario)["identify"]
    steps = 3 * round((ip["settle_s"] + ip["duration_s"]) * 1000)
    out["experiment_us_per_step"] = 1e6 * out["experiment"] / steps if not as_shipped else None
    out["run_us_per_step"] = 1e6 * out["run"] / round(scenario["duration_s"] * 1000)
    out["cpu_s"] = cpu_s
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--variant", default="mc004")
    p.add_argument("--warm", default="mc005")
    p.add_argument("--as-shipped", action="store_true", help="the one controller, no experiment")
    p.add_argument("--plots", action="store_true", help="with the run's figures")
    p.add_argument("--identify", choices=["auto", "reduced"], default="auto")
    p.add_argument("--timeseries", choices=["all", "failing", "none"], default="all")
    a = p.parse_args(argv)
    samples = int(re.search(r"samples: (\d+)", SCENARIO.read_text()).group(1))  # type: ignore[union-attr]
    names = {f"mc{i:03d}" for i in range(samples)}
    if a.variant not in names or a.warm not in names or a.variant == a.warm:
        print(
            f"error: invalid value at --variant/--warm: {a.variant}/{a.warm}; allowed: two "
            f"different names mc000..mc{samples - 1:03d}",
            file=sys.stderr,
        )
        return 2
    figures = measure(a.variant, a.warm, a.as_shipped, a.plots, a.identify, a.timeseries)
    print(json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
