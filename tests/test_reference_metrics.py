"""Behaviour lock of issue 7: the shipped scenarios give the stored figures.

``tests/data/reference_metrics.json`` was written by
``tests/data/make_reference.py`` *before* the hot path was optimised. Every
shipped scenario is re-run and compared:

* metrics and per-column sums, sums of squares and final values: relative
  1e-9, absolute 1e-12 (SI units; 1e-12 m or rad is far below any sensor
  LSB). The optimised loop keeps the floating-point operation order of the
  original, so the runs are in fact bit-identical; the tolerance only leaves
  room for a BLAS or libm that rounds differently on another machine.
  It is *not* loose enough to hide a real change: the loops feed back
  quantised sensors (14-bit potentiometers, 10 um encoder), so a change in the
  last bit that flips one ADC count grows into differences far above 1e-9.
* bit identity (SHA-256 of every logged column): asserted only when numpy
  and MuJoCo have the versions the reference was generated with.

Regenerate (only for an intended, reviewed change of behaviour) with
``python tests/data/make_reference.py``.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simpro_mj.metrics import compute_metrics
from simpro_mj.scenario import load_scenario
from simpro_mj.sim import simulate

REF_PATH = Path(__file__).resolve().parent / "data" / "reference_metrics.json"
REF = json.loads(REF_PATH.read_text(encoding="utf-8"))
RTOL, ATOL = 1e-9, 1e-12
SAME_LIBS = REF["generated_with"] == {"numpy": np.__version__, "mujoco": mujoco.__version__}


def _compare(got, want, path: str, bad: list) -> None:
    """Walk two JSON-like trees; collect mismatches as strings in ``bad``."""
    if isinstance(want, dict):
        # keys added to the metrics later are not a change of behaviour
        if not isinstance(got, dict) or not set(want) <= set(got):
            bad.append(f"{path}: keys {sorted(got) if isinstance(got, dict) else got!r}")
            return
        for k in want:
            _compare(got[k], want[k], f"{path}.{k}", bad)
    elif isinstance(want, list):
        if not isinstance(got, list | tuple) or len(got) != len(want):
            bad.append(f"{path}: {got!r} != {want!r}")
            return
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            _compare(g, w, f"{path}[{i}]", bad)
    elif isinstance(want, float) and not isinstance(want, bool):
        g = float(got) if isinstance(got, int | float) else math.nan
        if math.isnan(want):
            if not math.isnan(g):
                bad.append(f"{path}: {g!r} != nan")
        elif not math.isclose(g, want, rel_tol=RTOL, abs_tol=ATOL):
            bad.append(f"{path}: {g!r} != {want!r}")
    elif got != want:
        bad.append(f"{path}: {got!r} != {want!r}")


@pytest.fixture(scope="module", params=sorted(REF["scenarios"]))
def run(request):
    name = request.param
    scenario = load_scenario(name)
    res = simulate(scenario)
    metrics = compute_metrics(res.columns, scenario)
    metrics["status"] = res.status
    return name, res, json.loads(json.dumps(metrics))  # same float/None forms as stored


def test_metrics_equal_reference(run):
    name, res, metrics = run
    want = REF["scenarios"][name]
    bad: list[str] = []
    _compare(metrics, want["metrics"], "metrics", bad)
    _compare(
        {
            "steps": res.sim["steps"],
            "max_loop_closure_error_m": res.sim["max_loop_closure_error_m"],
        },
        want["sim"],
        "sim",
        bad,
    )
    for col, ref in want["series"].items():
        v = res.columns[col]
        got = {"sum": float(v.sum()), "sumsq": float(np.dot(v, v)), "final": float(v[-1])}
        _compare(got, {k: ref[k] for k in got}, f"series.{col}", bad)
    assert not bad, f"{name}: {len(bad)} differences, first: " + "; ".join(bad[:5])


@pytest.mark.skipif(not SAME_LIBS, reason="reference generated with other numpy/MuJoCo versions")
def test_series_bit_identical(run):
    name, res, _ = run
    want = REF["scenarios"][name]["series"]
    bad = [
        col
        for col, ref in want.items()
        if hashlib.sha256(np.ascontiguousarray(res.columns[col]).tobytes()).hexdigest()
        != ref["sha256"]
    ]
    assert not bad, f"{name}: columns not bit-identical: {bad}"
