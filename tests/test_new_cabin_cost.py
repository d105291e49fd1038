"""benchmarks/new_cabin_cost.py: its refusals and the consistency of its parts.

No speed thresholds: the figures are what the script measures on its machine.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "new_cabin_cost.py"


def _module():
    spec = importlib.util.spec_from_file_location("new_cabin_cost", SCRIPT)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("argv", [["--variant", "mc200"], ["--warm", "x"], ["--warm", "mc004"]])
def test_a_variant_not_in_the_sweep_is_refused_in_one_line(argv):
    r = subprocess.run([sys.executable, str(SCRIPT), *argv], capture_output=True, text=True,
                       timeout=60)  # fmt: skip
    assert r.returncode == 2 and r.stdout == ""
    (line,) = r.stderr.splitlines()
    assert line.startswith("error: invalid value at --variant/--warm") and "mc199" in line


@pytest.mark.slow  # two new cabins identified and run (about 8 s of CPU)
def test_the_parts_fit_inside_the_variant(monkeypatch, tmp_path):
    monkeypatch.setenv("SIMPRO_CACHE_DIR", str(tmp_path))  # restored after the test
    r = _module().measure("mc004", "mc005")
    # the experiment and the fits are inside the identification, all inside the variant
    assert r["total"] >= r["identification"] >= r["experiment"] + r["fit"] > 0.0
    assert r["total"] >= r["identification"] + r["run"] + r["result_folder"]
    assert r["result_folder"] >= r["timeseries_csv"] > 0.0  # each part found by its name
    assert r["experiment_us_per_step"] > 0.0 and r["run_us_per_step"] > 0.0
    assert r["status"] in ("ok", "not_settled", "limit_cycle")
