"""A batch's throughput: variants per minute and the ratio to the step's own cost.

    python benchmarks/batch_throughput.py [--samples 20] [--jobs 2] [--keep-cache] [--threads]
        [--identify auto|reduced] [--timeseries all|failing|none]

Runs a Monte Carlo of ``--samples`` new cabins (``scenarios/sweep_robustness.yaml``
with its sample count replaced: every variant a plant not seen before) as
``simpro-sim batch --jobs J --no-plots`` runs it (:func:`simpro_mj.batch.runner.run_batch`,
worker processes; ``--threads``: threads, as ``simpro-sim batch --threads``), with
an empty identification cache unless ``--keep-cache``, and prints one JSON document.
Each cabin's joint loops are placed on its own models: ``--identify auto`` (the
default, the Fig. 12 experiment in MuJoCo) or ``reduced`` (the same experiment on
the reduced chain, :mod:`simpro_mj.identification.reduced_experiment`).
``--timeseries`` is the batch's (``simpro-sim batch --timeseries``: whose
``timeseries.csv`` the variants write; default ``all``).

Before the clock starts one cabin of another draw runs in this process, so that
numba's cache holds the compiled step (a change of the step's sources costs a
compile of about a minute, once, not a batch's figure).

* ``wall_s``, ``variants_per_min``: the batch's wall time (planning, the
  identification of every new plant, the runs, their folders, the summary;
  not the summary plots) and variants finished per minute;
* ``stepping_s``: the variants' own stepping time, the sum over the variants
  of ``duration_s / realtime_factor`` (each run's stepping loop, measured in
  the same batch, so under the same load);
* ``ratio``: ``wall_s`` over ``stepping_s / jobs``, what the batch costs per
  unit of the step's own cost on the same workers (1: nothing but stepping);
* ``cpu_s_per_variant``: the mean of the variants' worker-thread CPU time
  (``cpu_s`` in summary.json, identification included; a worker's imports are in it
  when the worker makes them, not when its forkserver made them before) and
  ``cpu_ratio`` = their sum over ``stepping_s``: process CPU is less inflated
  than wall time by other work on a shared machine;
* ``cpu_s_total`` (Linux): the CPU time of every process of the batch, this one's
  (planning, the summary), its spawned children's and its workers' forkserver's with
  the workers forked from it (read from ``/proc``): what the batch costs in all, less
  inflated by other work than ``wall_s``.

A speed figure: here, not in a timed test. Meaningful on a quiet machine only.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def measure(
    samples: int = 20,
    jobs: int = 2,
    keep_cache: bool = False,
    processes: bool = True,
    identify: str = "auto",
    timeseries: str = "all",
) -> dict:
    """Run the batch and return the figures of the module docstring."""
    with tempfile.TemporaryDirectory(prefix="simpro-throughput-") as tmp:
        tmp = Path(tmp)
        if not keep_cache:
            os.environ["SIMPRO_CACHE_DIR"] = str(tmp / "cache")
        text = (ROOT / "scenarios" / "sweep_robustness.yaml").read_text()
        text = text.replace("samples: 200", f"samples: {samples}")
        # every draw a new cabin whose loops are placed on its own identification (the
        # shipped sweep runs the cabin's one controller on every draw)
        text = text.replace("inner: {identify: preset}", f"inner: {{identify: {identify}}}")
        assert f"identify: {identify}" in text, "sweep_robustness.yaml no longer names identify"
        (tmp / "throughput.yaml").write_text(text)
        from simpro_mj.batch.runner import run_batch

        # one cabin of another draw first, its identification in a cache of its own: the
        # compiled step and the experiment's actuator step are in numba's cache (compiled
        # there once per set of sources, about a minute) before the clock starts
        warm = text.replace(f"samples: {samples}", "samples: 1").replace("seed: 2025", "seed: 7")
        (tmp / "warm.yaml").write_text(warm)
        cache_dir = os.environ.get("SIMPRO_CACHE_DIR")
        os.environ["SIMPRO_CACHE_DIR"] = str(tmp / "warm-cache")
        run_batch([str(tmp / "warm.yaml")], tmp / "warm", plots=False, summary_plots=False)
        if cache_dir is None:
            del os.environ["SIMPRO_CACHE_DIR"]
        else:
            os.environ["SIMPRO_CACHE_DIR"] = cache_dir

        cpu0 = _cpu_s()
        wall0 = time.perf_counter()
        report = run_batch([str(tmp / "throughput.yaml")], tmp / "out", jobs=jobs,
                           plots=False, summary_plots=False, processes=processes,
                           timeseries=timeseries)  # fmt: skip
        wall = time.perf_counter() - wall0
        cpu_total = _cpu_s(cpu0[2])[0] - cpu0[0] if cpu0[1] else None
    rows = [r for r in report.rows if r.realtime_factor]
    duration = float(text.split("duration_s:")[1].split()[0])
    stepping = sum(duration / r.realtime_factor for r in rows)
    cpu = [r.cpu_s for r in rows if r.cpu_s is not None]
    return {
        "samples": samples,
        "jobs": jobs,
        "identify": identify,
        "timeseries": timeseries,
        "processes": processes,
        "finished": len(rows),
        "counts": {k: v for k, v in report.counts.items() if v},
        "notices": report.notices,
        "wall_s": wall,
        "variants_per_min": 60.0 * len(rows) / wall if wall > 0 else None,
        "stepping_s": stepping,
        "ratio": wall / (stepping / jobs) if stepping > 0 else None,
        "cpu_s_per_variant": sum(cpu) / len(cpu) if cpu else None,
        "cpu_ratio": sum(cpu) / stepping if stepping > 0 and cpu else None,
        "cpu_s_total": cpu_total,
    }


def _cpu_s(server_pid: int | None = None) -> tuple[float, bool, int | None]:
    """``(seconds, read, forkserver pid)``: the CPU time so far of this process, of its
    children it has waited for, and of the workers' forkserver (``server_pid``, or the
    one running now) with its own waited-for children (the workers), from ``/proc``;
    ``read`` False where there is no ``/proc``."""
    import resource

    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
    if server_pid is None:
        from multiprocessing import forkserver

        server_pid = getattr(forkserver._forkserver, "_forkserver_pid", None)
    if server_pid is not None:
        try:
            fields = Path(f"/proc/{server_pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            return total, False, server_pid
        # utime, stime, cutime, cstime: the 14th-17th fields of stat (after pid, comm)
        ticks = sum(int(x) for x in fields[11:15])
        total += ticks / os.sysconf("SC_CLK_TCK")
    return total, Path("/proc/self/stat").exists(), server_pid


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--samples", type=int, default=20)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--keep-cache", action="store_true")
    p.add_argument("--threads", action="store_true", help="threads instead of worker processes")
    p.add_argument("--identify", choices=["auto", "reduced"], default="auto")
    p.add_argument("--timeseries", choices=["all", "failing", "none"], default="all")
    a = p.parse_args(argv)
    if not (1 <= a.samples <= 1000 and 1 <= a.jobs <= 64):
        print("error: invalid value at --samples/--jobs: allowed 1..1000 / 1..64", file=sys.stderr)
        return 2
    figures = measure(a.samples, a.jobs, a.keep_cache, not a.threads, a.identify, a.timeseries)
    print(json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
