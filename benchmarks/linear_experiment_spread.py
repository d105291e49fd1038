"""The experiment's linear or reduced model against the identification's own seed spread.

    python benchmarks/linear_experiment_spread.py [--cabins paper heavy c450 c75 sweep8]
        [--seeds 1 2 3] [--responses] [--model linear|reduced]

For each cabin, the Fig. 12 experiment a run of ``step_pitch`` identifies for its own
plant (:func:`simpro_mj.identification.auto.plant_tree`) is run at each ``--seed`` of
the sequence, and the same experiment's linear model
(:func:`simpro_mj.identification.linear_experiment.identify_linear`, the first seed's
sequence) is fitted by the same fit; with ``--model reduced`` the experiment stepped on
the reduced chain with the step's own pneumatics and MuJoCo's friction rows
(:func:`simpro_mj.identification.reduced_experiment.identify_reduced`) at each seed,
and per leg and seed the records' share of steps at rest (|v| < 0.1 mm/s), RMS speed
and RMS voltage deviation beside the experiment's. Cabins (:data:`CABINS`): ``paper`` (the preset),
``heavy`` (``heavy_cabin``), ``c450`` and ``c75`` (``heavy_cabin`` with 450/750 N and
75/250 N of Coulomb/breakaway friction on every leg's seals) and ``sweep8`` (the first
eight cabins of ``sweep_robustness.yaml``, each its own plant). With ``--responses``,
``step_pitch`` and ``step_all`` run with the joint loops placed on each model set
(``design_plant: identified``, ``identify: preset`` with those models, the run's own
seed).

Prints one JSON document, per cabin: per leg and parameter the seeds' range, the
linear model's value and how far outside the range it lies (relative to the nearer
end, 0 inside); the CPU seconds of each; with ``--responses`` per scenario and axis the
range over the seeds of the overshoot (%) and the 2 % settling time (s) and the
linear model's, with the statuses. CPU seconds are process time, meaningful on a
quiet machine only.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import tempfile
import time
from pathlib import Path

HEAVY = ["plant.preset=heavy_cabin"]


def _seals(coulomb: int, breakaway: int) -> list:
    return [
        *HEAVY,
        f"actuator.pneumatics.cylinder.coulomb_friction_n=[{coulomb},{coulomb},{coulomb}]",
        f"actuator.pneumatics.cylinder.breakaway_friction_n=[{breakaway},{breakaway},{breakaway}]",
    ]


#: The cabins by name: ``--set`` lists on ``step_pitch`` (``sweep8`` is expanded apart).
CABINS = {"paper": [], "heavy": HEAVY, "c450": _seals(450, 750), "c75": _seals(75, 250)}
KEYS = ("b", "a1", "a0", "fit_percent")
AXES = ("roll", "pitch", "heave")


def _scenarios(cabin: str) -> list:
    """``[(name, typed scenario of step_pitch's plant, its --set list or None)]``."""
    from simpro_mj.config.scenario import load_scenario

    if cabin != "sweep8":
        return [(cabin, load_scenario("step_pitch", CABINS[cabin]), CABINS[cabin])]
    from simpro_mj.batch.plan import plan
    from simpro_mj.config.models import as_scenario

    jobs = [j for j in plan(["sweep_robustness.yaml"]).jobs if j.error is None][:8]
    return [(f"sweep8/{j.variant}", as_scenario(j.scenario), None) for j in jobs]


def _outside(value: float, lo: float, hi: float) -> float:
    """How far ``value`` lies outside ``[lo, hi]``, relative to the nearer end."""
    if value < lo:
        return (value - lo) / abs(lo)
    if value > hi:
        return (value - hi) / abs(hi)
    return 0.0


def _responses(sc, sets, models: dict, folder: Path) -> dict:
    """``step_pitch`` and ``step_all`` with the joint loops placed on ``models``."""
    from simpro_mj.config.models import Identified
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.report.runner import execute

    out = {}
    for name in ("step_pitch", "step_all"):
        if sets is not None:
            run = load_scenario(name, sets)
        else:  # a sweep cabin: its own scenario, which runs the pitch step
            if name != "step_pitch":
                continue
            run = sc
        run = run.model_copy(deep=True)
        run.controller.inner.design_plant = "identified"
        run.controller.inner.identify = "preset"
        run.controller.inner.identified = Identified.model_validate(models)
        _, doc = execute(run, folder / name, plots=False, quiet=True)
        row = {"status": doc["status"]}
        for axis in AXES:
            m = doc["axes"].get(axis) or {}
            if m.get("overshoot_pct") is not None:
                row[axis] = [m.get("overshoot_pct"), m.get("settling_time_s")]
        out[name] = row
    return out


def _record(u, v) -> list:
    """A leg's record: share of steps at rest, RMS speed (mm/s), RMS voltage swing (V)."""
    import numpy as np

    rest = float(np.mean(np.abs(v) < 1e-4))
    return [rest, float(1e3 * np.sqrt(np.mean(v**2))), float(np.std(u))]


def _timed(identify_fn, tree: dict, seed: int) -> tuple[dict, dict, float]:
    """``identify_fn`` on ``tree`` at sequence ``seed``: its fits, records, CPU seconds."""
    t = copy.deepcopy(tree)
    t["identify"]["seed"] = seed
    recs: dict = {}
    c0 = time.process_time()
    got = identify_fn(t, records=recs)
    return got, recs, time.process_time() - c0


def _model(kind: str, tree: dict, seeds, stats: dict) -> tuple[dict, float]:
    """The model's fits (the first seed's; ``reduced``: per seed, its spread in ``stats``)
    and its CPU seconds (the first seed's)."""
    if kind == "linear":
        from simpro_mj.identification.linear_experiment import identify_linear

        t = copy.deepcopy(tree)
        t["identify"]["seed"] = seeds[0]
        c0 = time.process_time()
        return identify_linear(t), time.process_time() - c0
    from simpro_mj.identification.reduced_experiment import identify_reduced

    first, cpu = None, 0.0
    for seed in seeds:
        got, recs, took = _timed(identify_reduced, tree, seed)
        if first is None:
            first, cpu = got, took
        for a, rec in recs.items():
            j = int(a[-1]) - 1
            row = stats.setdefault(a, {})
            row.setdefault("model_record", []).append(_record(rec.u[:, j], rec.qdot[:, j]))
            seeds_of = row.setdefault("model_seeds", {})
            for k in KEYS:
                seeds_of.setdefault(k, []).append(float(getattr(got[a], k)))
    return first, cpu


def measure(cabins, seeds=(1, 2, 3), responses: bool = False, kind: str = "linear") -> dict:
    """Identify, model and (optionally) run the responses (module docstring)."""
    from simpro_mj.identification.auto import plant_tree
    from simpro_mj.identification.identify import identify

    out: dict = {"seeds": list(seeds), "model": kind, "cabins": {}}
    with tempfile.TemporaryDirectory(prefix="simpro-linear-") as tmp:
        for cabin in cabins:
            for name, sc, sets in _scenarios(cabin):
                tree0 = plant_tree(sc)
                fits, cpu, stats = {}, [], {}
                for seed in seeds:
                    got, recs, took = _timed(identify, tree0, seed)
                    cpu.append(took)
                    fits[seed] = {a: {k: float(getattr(got[a], k)) for k in KEYS} for a in got}
                    for a, rec in recs.items():
                        stats.setdefault(a, {}).setdefault("record", []).append(
                            _record(rec.u, rec.qdot)
                        )
                lin, lin_cpu = _model(kind, tree0, seeds, stats)
                row: dict = {"identify_cpu_s": cpu, f"{kind}_cpu_s": lin_cpu, "legs": {}}
                for a in lin:
                    leg = row["legs"][a] = {}
                    for k in KEYS:
                        vals = [fits[s][a][k] for s in seeds]
                        lo, hi = min(vals), max(vals)
                        v = float(getattr(lin[a], k))
                        leg[k] = {"seeds": [lo, hi], kind: v, "outside": _outside(v, lo, hi)}
                        if kind == "reduced":
                            mine = stats[a]["model_seeds"][k]
                            leg[k]["reduced_seeds"] = [min(mine), max(mine)]
                    if a in stats:
                        leg["record_rest_rms_mm_s_rms_v"] = {
                            "experiment": stats[a].get("record"),
                            kind: stats[a].get("model_record"),
                        }
                if responses:
                    res: dict = {}
                    for seed in seeds:
                        models = {a: {k: fits[seed][a][k] for k in KEYS[:3]} for a in lin}
                        res[f"seed{seed}"] = _responses(
                            sc, sets, models, Path(tmp) / name / f"seed{seed}"
                        )
                    models = {a: {k: float(getattr(lin[a], k)) for k in KEYS[:3]} for a in lin}
                    res[kind] = _responses(sc, sets, models, Path(tmp) / name / kind)
                    if kind == "reduced":  # the reduced model's other seeds
                        for i, seed in enumerate(seeds[1:], 1):
                            models = {
                                a: {k: stats[a]["model_seeds"][k][i] for k in KEYS[:3]} for a in lin
                            }
                            res[f"reduced_seed{seed}"] = _responses(
                                sc, sets, models, Path(tmp) / name / f"reduced{seed}"
                            )
                    row["responses"] = res
                out["cabins"][name] = row
                print(json.dumps({name: row}), file=sys.stderr, flush=True)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    allowed = [*CABINS, "sweep8"]
    p.add_argument("--cabins", nargs="+", default=allowed, choices=allowed)
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    p.add_argument("--responses", action="store_true")
    p.add_argument("--model", choices=["linear", "reduced"], default="linear")
    a = p.parse_args(argv)
    if len(a.seeds) < 2 or any(not 0 <= s < 2**31 for s in a.seeds):
        print("error: invalid value at --seeds: allowed: two or more of 0..2^31-1", file=sys.stderr)
        return 2
    print(json.dumps(measure(a.cabins, tuple(a.seeds), a.responses, a.model), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
