"""The identification's own seed spread, the default experiment against its options.

    python benchmarks/excitation_spread.py [--seeds 1 2 3] [--options all_legs record_10s]

On the 450/750 N cabin (``heavy_cabin`` with 450 N of Coulomb friction and 750 N
of breakaway on every leg's seals), the experiment a run of ``step_pitch``
identifies for its own plant (:func:`simpro_mj.identification.auto.plant_tree`:
the preset's 20 s record, 1 s settling, the joint loops' 2 V dither) is run as
``one_leg`` (the default, the paper's Fig. 12: three records) and as each of
``--options`` (:data:`OPTIONS`: ``all_legs``, one record exciting the three legs;
``record_10s``, one period of a 9-bit sequence on the same 20 ms clock, 10.2 s a
leg; ``levenberg_marquardt``, the default record fitted by that solver), at each
``--seed`` of the sequence. Then
``step_pitch`` and ``step_all`` run with the joint loops placed on each model set
(``controller.inner.identify: preset`` with those models; the run's own seed 1).
Prints one JSON document:

* ``models``: per option, per leg, the range over the seeds of b, a1, a0
  and the fit (%), and the CPU seconds of each identification;
* ``fits``: per option and seed, each leg's b, a1, a0 and fit;
* ``responses``: per option, per scenario and axis, the range over the seeds
  of the overshoot (%) and the 2 % settling time (s) of ``metrics.json``, and the
  statuses.

An option whose ranges lie inside the default's keeps the
identification's answer; outside, it changes what the loops are placed on.
CPU seconds are process time; meaningful on a quiet machine only.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import tempfile
import time
from pathlib import Path

CABIN = [
    "plant.preset=heavy_cabin",
    "actuator.pneumatics.cylinder.coulomb_friction_n=[450,450,450]",
    "actuator.pneumatics.cylinder.breakaway_friction_n=[750,750,750]",
]
#: The experiment's settings compared (``identify.*`` over the run's own plant_tree):
#: the default and its options.
OPTIONS = {
    "one_leg": {},
    "all_legs": {"excitation": "all_legs"},
    "record_10s": {"duration_s": 10.0, "prbs_bits": 9},
    "levenberg_marquardt": {"fit_method": "levenberg_marquardt"},
}
KEYS = ("b", "a1", "a0", "fit_percent")


def _span(values) -> list:
    values = [v for v in values if v is not None]
    return [min(values), max(values)] if values else [None, None]


def measure(seeds=(1, 2, 3), options=("all_legs",)) -> dict:
    """Run the experiments and the step responses (module docstring)."""
    names = ("one_leg", *(o for o in options if o != "one_leg"))
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.identification.auto import plant_tree
    from simpro_mj.identification.identify import identify
    from simpro_mj.report.runner import execute

    tree0 = plant_tree(load_scenario("step_pitch", CABIN))
    fits: dict = {}
    cpu: dict = {e: [] for e in names}
    for exc in names:
        for seed in seeds:
            tree = copy.deepcopy(tree0)
            tree["identify"].update(OPTIONS[exc], seed=seed)
            c0 = time.process_time()
            got = identify(tree)
            cpu[exc].append(time.process_time() - c0)
            fits[exc, seed] = {a: {k: float(getattr(got[a], k)) for k in KEYS} for a in got}
    responses: dict = {}
    with tempfile.TemporaryDirectory(prefix="simpro-excitation-") as tmp:
        for (exc, seed), models in fits.items():
            sets = [*CABIN, "controller.inner.identify=preset"]
            sets += [
                f"controller.inner.identified.{a}.{k}={m[k]!r}"
                for a, m in models.items()
                for k in ("b", "a1", "a0")
            ]
            for name in ("step_pitch", "step_all"):
                _, doc = execute(
                    load_scenario(name, sets), Path(tmp) / f"{name}-{exc}-{seed}",
                    plots=False, quiet=True,
                )  # fmt: skip
                responses[name, exc, seed] = doc
    out: dict = {"seeds": list(seeds), "models": {}, "responses": {}, "fits": {}}
    for exc in names:
        per = out["models"][exc] = {"cpu_s": cpu[exc]}
        out["fits"][exc] = {s: fits[exc, s] for s in seeds}
        for a in fits[exc, seeds[0]]:
            per[a] = {k: _span(fits[exc, s][a][k] for s in seeds) for k in KEYS}
        res = out["responses"][exc] = {}
        for name in ("step_pitch", "step_all"):
            docs = [responses[name, exc, s] for s in seeds]
            res[name] = {"status": [d["status"] for d in docs]}
            for axis in ("roll", "pitch", "heave"):
                m = [d["axes"].get(axis) or {} for d in docs]
                if any(x.get("overshoot_pct") is not None for x in m):
                    res[name][axis] = {
                        "overshoot_pct": _span(x.get("overshoot_pct") for x in m),
                        "settling_s": _span(x.get("settling_time_s") for x in m),
                    }
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    p.add_argument("--options", nargs="+", default=["all_legs"])
    a = p.parse_args(argv)
    if any(o not in OPTIONS for o in a.options):
        print(
            f"error: invalid value at --options: {a.options}; allowed: {', '.join(OPTIONS)}",
            file=sys.stderr,
        )
        return 2
    if len(a.seeds) < 2 or any(not 0 <= s < 2**31 for s in a.seeds):
        print("error: invalid value at --seeds: allowed: two or more of 0..2^31-1", file=sys.stderr)
        return 2
    print(json.dumps(measure(tuple(a.seeds), tuple(a.options)), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
