"""The cabin's step figures under halved and doubled numerical parameters, over seeds.

    python benchmarks/numerical_spread.py [--seeds 1 .. 10] [--seals 450 750] [--jobs 2]
                                          [--null-seeds 11 .. 20] [--variants shipped ...]
                                          [--loops fixed|reidentified]

Seals that stick make a settling time a discontinuous function of anything that
moves a run by a micrometre: a seal breaks away a step earlier or later, the
slip lands elsewhere within the loops' bands, and the last entry into the 2 %
band moves by seconds. The noise seed moves it as far as a numerical parameter
does (``docs/paper-notes.md``, numerical parameters). So a single run per
setting cannot show whether a figure depends on the step's numerics; its
distribution over seeds can. This runs ``step_pitch`` and ``step_all`` on
``heavy_cabin`` with the given seals on every leg, at each seed, with the
shipped numerics and with each numerical parameter moved as far as MuJoCo
allows (the other way is its own limit, where the shipped value sits):

* ``stick_time_constant_ms`` 2 -> 4 (doubled; 2 ms, two steps, is MuJoCo's
  least);
* ``stick_impedance`` 0.9999 -> 0.9998 (the yield ``1 - d`` doubled; 0.9999 is
  MuJoCo's greatest);
* ``integration.substeps`` 1 -> 2 (the pressure step halved);
* ``stick_noslip_iterations`` 10 -> 5 and 20 (MuJoCo's noslip passes, which stop
  at its tolerance: a bound on the work, halved and doubled).

and, as a control that is not numerics, ``coulomb_plus_1mN`` (``--variants``):
every seal's Coulomb force 1 mN higher (2 ppm of 450 N, far below what any
catalogue or measurement resolves), which shows how far the plant itself
carries a perturbation that small.

The joint loops (``--loops``): ``fixed`` (default) places them once, on the
models Fig. 12's experiment identifies on the plant with the shipped numerics
(``controller.inner.identify: preset`` with those models), and every variant
runs those same loops, as a controller on a real machine stays the same while
one asks how its plant is modelled; ``reidentified`` lets every variant run the
experiment on its own plant and place its own loops (the ``auto`` default of a
scenario). Where seals stick the experiment's record is itself a stick-slip
record, so a 2 ppm change of a seal moves the identified models and with them
every run of that variant at once: ``reidentified`` measures the identification's
sensitivity on top of the step's.

Prints one JSON document: per variant, scenario and axis, the overshoot (%) and
2 % settling time (s) of ``metrics.json`` at every seed, their median, range
and the number of runs that meet the cabin's floors (overshoot <= 10 %,
settling <= 3 s on ``step_pitch`` / 4 s on ``step_all``, status ok); per
scenario the largest swing of the true pose over the last 3 s (roll and pitch
deg, heave mm, peak to peak) and how many runs read ``ok`` while swinging more
than 0.05 deg or 0.5 mm (none should); and for
each variant against the shipped numerics the ratio of the medians and the
two-sided Mann-Whitney U p-value (scipy.stats.mannwhitneyu): a small p says
the numerical parameter moves the figure's distribution beyond the seeds' own
spread. With ``--null-seeds`` the shipped numerics also run at those other
seeds, compared with the shipped runs the same way (``shipped_other_seeds``):
the ratio of medians that the noise seed alone gives, and (``seed_ratio_95``
beside the shipped figures) the range of that ratio over 95 % of random
splits of the pooled shipped runs: the yardstick for the variants' ratios
(a median of ten runs of a two-mode figure moves by more than 10 % with the
seeds drawn). CPU-bound: on two cores 10 seeds take a few minutes.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor

CYL = "actuator.pneumatics.cylinder"
VARIANTS = {
    "shipped": {},
    "stick_time_constant_x2": {f"{CYL}.stick_time_constant_ms": 4.0},
    "stick_yield_x2": {f"{CYL}.stick_impedance": 0.9998},
    "substeps_x2": {"actuator.pneumatics.integration.substeps": 2},
    "noslip_half": {f"{CYL}.stick_noslip_iterations": 5},
    "noslip_x2": {f"{CYL}.stick_noslip_iterations": 20},
}
#: Not numerics: a physical change far below anything measurable, the control that
#: shows how far the plant itself carries a micro-perturbation (1 mN on 450 N: 2 ppm)
CONTROLS = {"coulomb_plus_1mN": 1e-3}
SCENARIOS = {"step_pitch": 3.0, "step_all": 4.0}  # their settling floors, s
OVERSHOOT_FLOOR = 10.0  # %
LAST_S = 3.0  # s: the window whose swing an ok run keeps within SWING
SWING = (0.05, 0.05, 0.5)  # deg, deg, mm peak to peak


def _cabin(coulomb: float, breakaway: float) -> dict:
    """The ``--set`` entries of the cabin with these seals on every leg (N)."""
    return {
        "plant.preset": "heavy_cabin",
        f"{CYL}.coulomb_friction_n": [coulomb] * 3,
        f"{CYL}.breakaway_friction_n": [breakaway] * 3,
    }


def _one(job: tuple) -> tuple:
    """One run: (variant, scenario, seed) -> its figures per stepped axis."""
    variant, name, seed, seals, loops = job
    from simpro_mj.api import run

    numerics = VARIANTS.get(variant, {})  # the null variant: the shipped numerics
    coulomb = seals[0] + CONTROLS.get(variant, 0.0)
    sets = {**_cabin(coulomb, seals[1]), "seed": seed, **numerics, **loops}
    r = run(name, sets)
    m = r.metrics
    axes = {}
    for axis, fig in m["axes"].items():
        if fig.get("step"):
            axes[axis] = (fig["overshoot_pct"], fig["settling_time_s"])
    return variant, name, seed, m["status"], axes, _last_swing(r.columns)


def _last_swing(columns) -> list:
    """Peak to peak of the true roll, pitch (deg) and heave (mm) over the last 3 s."""
    import numpy as np

    t = np.asarray(columns["time_s"])
    last = t >= t[-1] - LAST_S
    return [
        float(np.ptp(np.asarray(columns[c])[last])) * k
        for c, k in (("roll_rad", 180 / np.pi), ("pitch_rad", 180 / np.pi), ("heave_m", 1e3))
    ]


def _summary(runs: list, statuses: list, floor: float) -> dict:
    """One axis over the seeds: ``runs`` (overshoot %, settling s or None) per seed."""
    ov = [r[0] for r in runs]
    st = [r[1] if r[1] is not None else float("inf") for r in runs]
    return {
        "overshoot_pct": ov,
        "settling_s": st,
        "settling_median_s": statistics.median(st),
        "settling_range_s": [min(st), max(st)],
        "overshoot_max_pct": max(ov),
        "meet": sum(
            ok == "ok" and o <= OVERSHOOT_FLOOR and s <= floor
            for ok, o, s in zip(statuses, ov, st, strict=True)
        ),
    }


NULL = "shipped_other_seeds"  # the shipped numerics at the --null-seeds


def fixed_loops(seals) -> dict:
    """The ``--set`` entries that hold every variant's joint loops to the ones placed on
    the models identified on the ``seals`` plant with the shipped numerics."""
    from simpro_mj.api import load
    from simpro_mj.identification.auto import identified_models

    models, _ = identified_models(load("step_pitch", _cabin(*seals)))
    out: dict = {"controller.inner.identify": "preset"}
    for act, m in models.items():
        out.update({f"controller.inner.identified.{act}.{k}": m[k] for k in ("b", "a1", "a0")})
    return out


def measure(
    seeds, seals=(450.0, 750.0), jobs: int = 2, null_seeds=(), variants=None, loops="fixed"
) -> dict:
    """Run every variant (or those named), scenario and seed and summarise."""
    from scipy.stats import mannwhitneyu

    held = fixed_loops(seals) if loops == "fixed" else {}
    chosen = ["shipped", *(v for v in variants or VARIANTS if v != "shipped")]
    todo = [(v, n, s, seals, held) for v in chosen for n in SCENARIOS for s in seeds]
    todo += [(NULL, n, s, seals, held) for n in SCENARIOS for s in null_seeds]
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
        done = list(pool.map(_one, todo))
    names = [*chosen, NULL] if null_seeds else chosen
    out: dict = {"seeds": list(seeds), "null_seeds": list(null_seeds),
                 "seals_n": list(seals), "loops": loops, "held": held,
                 "variants": {}}  # fmt: skip
    for v in names:
        per = out["variants"][v] = {}
        for name, floor in SCENARIOS.items():
            rows = sorted((r for r in done if r[0] == v and r[1] == name), key=lambda r: r[2])
            statuses = [r[3] for r in rows]
            per[name] = {
                "status": statuses,
                "last_3s_pp_max": [max(r[5][k] for r in rows) for k in range(3)],
                "ok_but_swinging": sum(
                    r[3] == "ok" and any(a > b for a, b in zip(r[5], SWING, strict=True))
                    for r in rows
                ),
                "axes": {
                    axis: _summary([r[4][axis] for r in rows], statuses, floor)
                    for axis in rows[0][4]
                },
            }
    base = out["variants"]["shipped"]
    for v in names:
        if v == "shipped":
            continue
        for name in SCENARIOS:
            for axis, fig in out["variants"][v][name]["axes"].items():
                ref = base[name]["axes"][axis]
                fig["settling_median_ratio"] = fig["settling_median_s"] / ref["settling_median_s"]
                fig["settling_p"] = float(mannwhitneyu(fig["settling_s"], ref["settling_s"]).pvalue)
                fig["overshoot_p"] = float(
                    mannwhitneyu(fig["overshoot_pct"], ref["overshoot_pct"]).pvalue
                )
                if v != NULL:  # run by run, the same seed: within 10 % or not
                    fig["per_run_within"] = _per_run(ref, fig)
    if null_seeds:  # the ratio two halves of the shipped runs give, 95 % of the splits
        for name in SCENARIOS:
            for axis, ref in base[name]["axes"].items():
                pool = ref["settling_s"] + out["variants"][NULL][name]["axes"][axis]["settling_s"]
                ref["seed_ratio_95"] = _split_ratios(pool, len(seeds))
    return out


def _per_run(ref: dict, fig: dict) -> list:
    """How many of the runs' figures lie within 10 % of the same seed's shipped run.

    Settling within 10 %; overshoot within 10 % or, under 5 %, within 0.5 points (10 %
    of the 5 % that a step response's overshoot is usually judged against). Returns
    [within, compared].
    """
    n = k = 0
    for a, b in zip(ref["settling_s"], fig["settling_s"], strict=True):
        n, k = n + 1, k + (abs(b - a) <= 0.1 * abs(a))
    for a, b in zip(ref["overshoot_pct"], fig["overshoot_pct"], strict=True):
        tol = 0.5 if max(a, b) < 5.0 else 0.1 * abs(a)
        n, k = n + 1, k + (abs(b - a) <= tol)
    return [k, n]


def _split_ratios(pool: list, n: int, draws: int = 4000) -> list:
    """The 2.5 and 97.5 % points of median(n drawn) / median(the rest) over random splits."""
    import random

    rng, ratios = random.Random(0), []
    for _ in range(draws):
        s = rng.sample(pool, len(pool))
        ratios.append(statistics.median(s[:n]) / statistics.median(s[n:]))
    ratios.sort()
    return [ratios[int(0.025 * draws)], ratios[int(0.975 * draws) - 1]]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, nargs="+", default=list(range(1, 11)))
    p.add_argument("--seals", type=float, nargs=2, default=[450.0, 750.0],
                   metavar=("COULOMB_N", "BREAKAWAY_N"))  # fmt: skip
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--null-seeds", type=int, nargs="*", default=[])
    p.add_argument("--variants", nargs="+", choices=[*VARIANTS, *CONTROLS],
                   default=list(VARIANTS))  # fmt: skip
    p.add_argument("--loops", choices=["fixed", "reidentified"], default="fixed")
    a = p.parse_args(argv)
    if len(a.seeds) < 3 or any(not 0 <= s < 2**31 for s in a.seeds):
        print("error: invalid value at --seeds: allowed: three or more of 0..2^31-1",
              file=sys.stderr)  # fmt: skip
        return 2
    if a.null_seeds and (
        len(a.null_seeds) < 3
        or set(a.null_seeds) & set(a.seeds)
        or any(not 0 <= s < 2**31 for s in a.null_seeds)
    ):
        print("error: invalid value at --null-seeds: allowed: three or more of 0..2^31-1, "
              "none of --seeds", file=sys.stderr)  # fmt: skip
        return 2
    if not 0 <= a.seals[0] <= a.seals[1] <= 5000:
        print("error: invalid value at --seals: allowed: 0 <= Coulomb <= breakaway <= 5000 N",
              file=sys.stderr)  # fmt: skip
        return 2
    if not 1 <= a.jobs <= 64:
        print("error: invalid value at --jobs: allowed: 1..64", file=sys.stderr)
        return 2
    out = measure(tuple(a.seeds), tuple(a.seals), a.jobs, tuple(a.null_seeds), a.variants, a.loops)
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
