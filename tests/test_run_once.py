"""A run does each piece of work once (simpro_mj.job.run.Run).

A plain ``simpro-sim run SCENARIO --no-plots`` compiles the MJCF once (the
preflight's static solves and the loop share the model), evaluates the
set-points once on the 1 ms grid (preflight and loop share them), places the
design plants once, and imports no renderer. Counted in a fresh interpreter
by wrapping MuJoCo's compilers and the set-point evaluation before the
command runs.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from simpro_mj.config.scenario import load_scenario

#: Run in a fresh interpreter: the counters wrap MuJoCo's compilers, the set-points and
#: the design plants, then ``simpro-sim run`` runs as from the shell.
_PROBE = r"""
import json, sys
import mujoco
counts = {"compile": 0, "from_xml": 0, "setpoints": 0, "with_identified": 0}

def counted(fn, key, static=False):
    def wrapper(*args, **kwargs):
        counts[key] += 1
        return fn(*args, **kwargs)
    return staticmethod(wrapper) if static else wrapper

mujoco.MjSpec.compile = counted(mujoco.MjSpec.compile, "compile")
for name in ("from_xml_path", "from_xml_string", "from_binary_path"):
    setattr(mujoco.MjModel, name, counted(getattr(mujoco.MjModel, name), "from_xml", True))
import simpro_mj.config.reference as ref
import simpro_mj.identification.auto as auto
import simpro_mj.sim.build as build
build.reference = counted(ref.reference, "setpoints")
auto_fn = auto.with_identified
auto.with_identified = counted(auto_fn, "with_identified")
from simpro_mj.commands.main import main
code = main()
counts["renderer"] = sorted(
    m for m in sys.modules if m in ("simpro_mj.report.render", "simpro_mj.report.scene",
                                    "simpro_mj.report.viewer", "imageio", "matplotlib.pyplot")
)
print("COUNTS " + json.dumps(counts))
sys.exit(code)
"""


def _probe(tmp_path, *argv) -> dict:
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run(
        [sys.executable, "-c", _PROBE, *argv, "--out", str(tmp_path / "out"), "--no-plots"],
        capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300,
    )  # fmt: skip
    # a run of a few tenths of a second ends before the pose has settled from its start:
    # the verdict may say so (exit 1); what is counted here is the work, not the response
    status = json.loads((tmp_path / "out" / "metrics.json").read_text())["status"]
    assert status in ("ok", "not_settled"), proc.stderr[-2000:]
    assert proc.returncode == (0 if status == "ok" else 1), proc.stderr[-2000:]
    (line,) = [x for x in proc.stdout.splitlines() if x.startswith("COUNTS ")]
    return json.loads(line[len("COUNTS ") :])


def test_a_plain_run_compiles_once_and_imports_no_renderer(tmp_path):
    counts = _probe(tmp_path, "run", "step_pitch.yaml", "--set", "duration_s=0.3")
    assert counts["compile"] + counts["from_xml"] == 1, counts
    assert counts["setpoints"] == 1, counts
    assert counts["with_identified"] == 1, counts
    assert counts["renderer"] == [], counts
    doc = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert doc["preflight"]["payload"]["poses_checked"] >= 1


def test_a_run_designed_on_identified_models_compiles_once(tmp_path):
    """``design_plant: identified`` (the preset's identified models as given): the
    design plants are resolved once and the plant compiled once."""
    sets = ["--set", "duration_s=0.2", "--set", "controller.inner.design_plant=identified",
            "--set", "controller.inner.identify=preset"]  # fmt: skip
    counts = _probe(tmp_path, "run", "step_pitch.yaml", *sets)
    assert counts["compile"] + counts["from_xml"] == 1, counts
    assert counts["with_identified"] == 1 and counts["setpoints"] == 1, counts


def test_the_run_shares_its_plant_and_set_points_with_the_preflight():
    """The preflight's poses are read from the run's set-point grid: the same
    figures as evaluating the profile at the checked times."""
    from simpro_mj.analysis.preflight import check_payload
    from simpro_mj.job.run import Run

    sc = load_scenario("step_all", ["duration_s=2"])
    run = Run(sc)
    shared = check_payload(run.scenario, run.model, (run.t, run.ref))
    alone = check_payload(run.scenario)
    assert shared["poses_checked"] == alone["poses_checked"]
    assert shared["max_payload_kg"] == pytest.approx(alone["max_payload_kg"], rel=1e-9)
    assert shared["utilisation"] == pytest.approx(alone["utilisation"], rel=1e-9)
    # the model's payload mass is restored after the static solves
    body = run.model.body("payload").id
    assert run.model.body_mass[body] == pytest.approx(sc.plant.payload.mass_kg)
    assert run.stroke() == [(0.0, 0.5)] * 3  # the DNC-125-500 stroke, from the MJCF


@pytest.mark.parametrize(("given", "used"), [(None, "1"), ("3", "3")])
def test_the_command_runs_blas_on_one_thread_unless_told(tmp_path, given, used):
    """numpy is not loaded before ``main`` sets ``OPENBLAS_NUM_THREADS``; a user's value wins."""
    code = (
        "import os, sys\n"
        "import simpro_mj.commands.main as m\n"
        "assert 'numpy' not in sys.modules\n"
        "m.main(['run', 'nosuch.yaml'])\n"
        "print(os.environ.get('OPENBLAS_NUM_THREADS'))"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=tmp_path, env=env, timeout=120)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == used, proc.stdout + proc.stderr
