"""Behaviour lock: the shipped scenarios give the stored figures, on any machine.

``tests/data/reference_metrics.json`` (written by ``tests/data/make_reference.py``)
holds, per shipped scenario, the metrics, per-column statistics of the full
1 ms series and the compared columns sampled every 0.2 s. Two checks:

* :func:`test_behaviour_equals_reference` (every machine): every sampled value,
  every column statistic and every metric within the tolerances stated and
  derived in ``make_reference.py`` (angles 2e-5 rad, lengths 10 um, pressures
  100 Pa, forces 2 N; a quantised signal one count more; metrics through the
  bounds a pointwise tolerance puts on them). Every scenario passes with its
  payload changed by 1e-8 (10^8 times a last-bit difference) and fails with it
  changed by 1 %: :func:`test_a_one_percent_change_fails_the_check` keeps it so.
* :func:`test_series_bit_identical` (same machine only): the SHA-256 of every
  logged column, asserted where the machine fingerprint
  (:mod:`simpro_mj.report.machine`: CPU instruction-set flags, numpy's SIMD dispatch,
  library versions, kernel) has an entry in the file.

Regenerate after an intended, reviewed change of behaviour with
``python tests/data/make_reference.py``; add another machine's bits with
``python tests/data/make_reference.py --add-bits`` run on it.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "data"))
import make_reference as mr  # noqa: E402

from simpro_mj.report.machine import fingerprint_id  # noqa: E402

REF = json.loads(mr.OUT.read_text(encoding="utf-8"))
BITS = REF.get("bits", {}).get(fingerprint_id())


def _close(got, want, tol: float) -> bool:
    if want is None or (isinstance(want, float) and math.isnan(want)):
        return got is None or (isinstance(got, float) and math.isnan(got))
    if not isinstance(got, int | float) or isinstance(got, bool):
        return False
    return abs(got - want) <= tol


def differences(got: dict, want: dict) -> list[str]:
    """Where a run's entry (``make_reference.entry``) leaves the tolerances."""
    bad: list[str] = []
    if got["sim"]["steps"] != want["sim"]["steps"]:
        bad.append(f"sim.steps: {got['sim']['steps']} != {want['sim']['steps']}")
    gm, wm = got["metrics"], want["metrics"]
    if gm.get("status") != wm.get("status"):
        bad.append(f"metrics.status: {gm.get('status')!r} != {wm.get('status')!r}")
    duration = want["sim"]["steps"] * 1e-3
    for axis, wa in wm["axes"].items():
        ga = gm["axes"].get(axis, {})
        for key, w in wa.items():
            if isinstance(w, dict) or isinstance(w, str):
                continue
            if key == "settling_time_s" and w is not None:
                lo, hi = want["settling_windows"][axis]
                g = ga.get(key)
                if not (isinstance(g, float) and lo <= g <= hi):
                    bad.append(f"metrics.{axis}.{key}: {g!r} outside [{lo:.3f}, {hi:.3f}] s")
                continue
            tol = mr.metric_tolerance(axis, key, wa, duration)
            if tol is not None and not _close(ga.get(key), w, tol):
                bad.append(f"metrics.{axis}.{key}: {ga.get(key)!r} != {w!r} (tol {tol:g})")
    for col, ws in want["stats"].items():
        tol = mr.column_tolerance(col)
        for key, w in ws.items():
            g = got["stats"].get(col, {}).get(key)
            if not _close(g, w, tol):
                bad.append(f"stats.{col}.{key}: {g!r} != {w!r} (tol {tol:g})")
    for col, w in want["samples"].items():
        g = got["samples"].get(col, [])
        tol = mr.column_tolerance(col)
        if len(g) != len(w):
            bad.append(f"samples.{col}: {len(g)} samples != {len(w)}")
            continue
        worst = max(
            range(len(w)),
            key=lambda i: abs(g[i] - w[i]) if math.isfinite(g[i] - w[i]) else math.inf,
        )
        if not _close(g[worst], w[worst], tol):
            t = worst * want["sample_every_s"]
            bad.append(f"samples.{col} at t = {t:g} s: {g[worst]!r} != {w[worst]!r} (tol {tol:g})")
    return bad


@pytest.fixture(scope="module", params=sorted(REF["scenarios"]))
def run(request):
    name = request.param
    got, bits = mr.entry(name)
    return name, got, bits


def test_behaviour_equals_reference(run):
    name, got, _ = run
    bad = differences(got, REF["scenarios"][name])
    assert not bad, f"{name}: {len(bad)} differences, first: " + "; ".join(bad[:5])


@pytest.mark.skipif(
    BITS is None,
    reason=f"no bit reference for this machine (fingerprint {fingerprint_id()}); "
    "the tolerance check applies",
)
def test_series_bit_identical(run):
    name, _, bits = run
    want = BITS["scenarios"][name]
    bad = [col for col, sha in want.items() if bits.get(col) != sha]
    assert not bad, f"{name}: columns not bit-identical on this machine: {bad}"


def test_every_logged_column_has_a_stated_tolerance(run):
    name, got, bits = run
    for col in bits:
        mr.column_tolerance(col)  # raises KeyError for a column added without one


def test_a_one_percent_change_fails_the_check(monkeypatch):
    """The tolerances are not loose enough to hide a real change of the plant."""
    import simpro_mj.config.scenario as scenario_module

    load = scenario_module.load_scenario
    plant = load("step_pitch").plant
    mass, moving = plant.payload.mass_kg, plant.payload.mass_kg + plant.platform_mass_kg
    heavier = [f"plant.payload.mass_kg={mass + 0.01 * moving!r}"]  # 1 % of the moving mass
    monkeypatch.setattr(scenario_module, "load_scenario", lambda n, s=None: load(n, heavier))
    got, _ = mr.entry("step_pitch")
    bad = differences(got, REF["scenarios"]["step_pitch"])
    assert any(b.startswith("samples.pitch_rad") for b in bad), bad
    # the heavier cabin needs more force and pressure to hold (heave itself stays within
    # one encoder count: the K K_I = 3 loop holds it)
    assert any(b.startswith("stats.f1_n") for b in bad), bad
    assert any(b.startswith(("samples.p1a_pa", "stats.p1a_pa")) for b in bad), bad
