"""A batch's pool workers start clean, with the run's modules loaded, in the batch's
environment.

The workers are forked from a forkserver (:func:`simpro_mj.sim.executors.pool_context`)
that the batch starts before it plans (:func:`~simpro_mj.sim.executors.start_early`)
and that has loaded the run's modules, the compiled step and the identification's
compiled functions (:mod:`simpro_mj.batch.warm`). Checked in a fresh interpreter, so
that this test process's own forkserver (started by whichever test came first) plays
no part: a probe task reports what a worker holds when its task starts.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from simpro_mj.plant.kernels import kernel_choice

ROOT = Path(__file__).resolve().parents[1]

#: What the probe's forkserver imports: the batch worker's own list.
PRELOAD = ("simpro_mj.batch.warm",)


def probe(task: dict) -> dict:
    """A pool task (top level: it pickles by name): what this worker holds."""
    import threading

    import mujoco

    return {
        "status": "ok",
        "reason": None,
        "threads": sorted(t.name for t in threading.enumerate()),
        "callbacks": [
            name
            for name in ("control", "passive", "time", "act_gain", "act_bias", "sensor")
            if getattr(mujoco, f"get_mjcb_{name}")() is not None
        ],
        "loaded": [m for m in task["modules"] if m in sys.modules],
        "compiled": _compiled_overloads(),
        "env": os.environ.get("SIMPRO_PROBE"),
        "pid": os.getpid(),
    }


def _compiled_overloads() -> list[int]:
    """How many signatures of the identification's compiled functions this process
    holds (none until a call, or the forkserver's preload, loads them)."""
    from simpro_mj.identification import reduced_experiment, sensitivity_fit

    if kernel_choice() != "numba":
        return []
    return [len(f.overloads) for f in (reduced_experiment._stepper(),
                                       *sensitivity_fit._functions())]  # fmt: skip


_SCRIPT = """
import copy, json, os, sys
import mujoco
from simpro_mj.config.scenario import load_scenario
from simpro_mj.identification.auto import plant_tree
from simpro_mj.identification.reduced_experiment import identify_reduced
from simpro_mj.sim import executors
from test_pool_workers import probe

# the identification's compiled functions in numba's cache (compiled here if not yet)
tree = copy.deepcopy(plant_tree(load_scenario("step_pitch", [])))
tree["identify"]["duration_s"] = 1.0
identify_reduced(tree)
executors.start_early(probe)  # the server starts with this environment...
os.environ["SIMPRO_PROBE"] = "set after the server started"  # ...and this comes later
mujoco.set_mjcb_control(None)
modules = ["simpro_mj.sim.callback", "simpro_mj.sim.loop",
           "simpro_mj.identification.reduced_experiment", "scipy.signal"]
got = {}
executors.run_tasks([(i, {"modules": modules}) for i in range(4)],
                    lambda key, result: got.__setitem__(key, result), fn=probe, jobs=2)
print(json.dumps({"workers": [got[i] for i in range(4)]}))
"""


def test_a_worker_starts_clean_with_the_runs_modules_and_the_batchs_environment():
    """The probe's process first identifies a plant on the reduced chain (which fills
    numba's cache of the identification's functions), then runs four probe tasks on
    two workers."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests")]))
    env.pop("SIMPRO_PROBE", None)
    out = subprocess.run([sys.executable, "-c", _SCRIPT], env=env, capture_output=True,
                         text=True, timeout=300, cwd=ROOT)  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    doc = json.loads(out.stdout.strip().splitlines()[-1])
    results = doc["workers"]
    assert len({r["pid"] for r in results}) <= 2  # two workers took the four tasks
    for r in results:
        assert r["status"] == "ok"
        # its own watchdog only: none of the batch's threads, none from the imports
        assert r["threads"] == ["MainThread", "simpro-parent-watch"], r
        assert r["callbacks"] == [], r  # no MuJoCo callback set before a run sets its own
        assert r["env"] == "set after the server started"
        # imported by the server before the worker was forked (the step from numba's
        # cache when the step runs compiled)
        want = ["simpro_mj.sim.loop", "simpro_mj.identification.reduced_experiment", "scipy.signal"]
        if kernel_choice() == "numba":
            want.insert(0, "simpro_mj.sim.callback")
        assert r["loaded"] == want, r
        # and the identification's compiled functions, from numba's cache
        assert r["compiled"] == ([1, 1, 1] if kernel_choice() == "numba" else []), r
