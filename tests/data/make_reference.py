"""Regenerate ``tests/data/reference_metrics.json`` (issue 7's behaviour lock).

Runs the shipped scenarios (:data:`SCENARIOS`) with :func:`simpro_mj.sim.simulate`
and :func:`simpro_mj.metrics.compute_metrics` and stores, per scenario:

* ``metrics``: the whole metrics document (numbers only, as computed);
* ``sim``: the deterministic part of ``SimResult.sim`` (steps, worst loop-closure error);
* ``series``: per logged column its sum, sum of squares, final value and a
  SHA-256 of the raw float64 bytes (bit-identity check).

Run from the repository root, *only* when a change of behaviour is intended
and reviewed::

    python tests/data/make_reference.py

``tests/test_reference_metrics.py`` re-runs the scenarios and compares.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
OUT = Path(__file__).resolve().parent / "reference_metrics.json"


def fingerprint(name: str) -> dict:
    """Metrics and time-series fingerprint of one shipped scenario."""
    sys.path.insert(0, str(ROOT))
    from simpro_mj.metrics import compute_metrics
    from simpro_mj.scenario import load_scenario
    from simpro_mj.sim import simulate

    scenario = load_scenario(name)
    res = simulate(scenario)
    metrics = compute_metrics(res.columns, scenario)
    metrics["status"] = res.status
    series = {}
    for col, v in res.columns.items():
        v = np.ascontiguousarray(v, dtype=np.float64)
        series[col] = {
            "sum": float(v.sum()),
            "sumsq": float(np.dot(v, v)),
            "final": float(v[-1]),
            "sha256": hashlib.sha256(v.tobytes()).hexdigest(),
        }
    return {
        "metrics": metrics,
        "sim": {
            "steps": res.sim["steps"],
            "max_loop_closure_error_m": res.sim["max_loop_closure_error_m"],
        },
        "series": series,
    }


#: The shipped co-simulation scenarios of ``scenarios/`` when the reference was taken.
SCENARIOS = ("step_all", "step_heave", "step_pitch", "step_roll", "track_sines")


def main() -> None:
    import mujoco

    doc = {
        "generated_with": {"numpy": np.__version__, "mujoco": mujoco.__version__},
        "scenarios": {name: fingerprint(name) for name in SCENARIOS},
    }
    OUT.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
