import os
import subprocess
import sys

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")
# headless MuJoCo rendering (tests/test_render.py): MuJoCo reads this when first imported
os.environ.setdefault("MUJOCO_GL", "egl")
# one BLAS thread per test process: the analyses' matrices are small (at most 65
# states), and OpenBLAS's threads, spinning against a loaded 2-core machine, made the
# preflight's lifted loop take 455 s instead of 23 s; set before numpy is imported
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# the session writes the bytecode of what it imports, whatever the shell asks: the
# install then compiles only the package itself (.ci/run), and each module the ~90
# processes of a run import (numpy, scipy, numba, matplotlib, dask: a fraction of each)
# is compiled once, by the first process to import it, instead of every module of every
# dependency at install (26 s of a quiet 2-core machine's 300 s budget)
sys.dont_write_bytecode = False
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)

try:
    from hypothesis import settings
except ImportError:  # pragma: no cover - hypothesis is in the [test] extra
    pass
else:
    # CI and plain `pytest` draw the same examples every run (a failure found
    # once is found again, and CI is not flaky); HYPOTHESIS_PROFILE=explore
    # draws new ones each run to look for more.
    settings.register_profile("ci", derandomize=True)
    settings.register_profile("explore", derandomize=False)
    settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


def pytest_sessionstart(session):
    """Under xdist, the controller starts compiling the step at once, in a process of
    its own, while the workers collect and run the tests that do not need it.

    A fresh clone has no compiled step: each worker's first simulation (and each
    command a test starts) would compile the same half minute of CPU at once. The
    compile holds the step's cache folder (:func:`simpro_mj.sim.numba_cache.first_compile`),
    so whoever needs the step meanwhile waits for it and then loads the cache.
    """
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", 0):
        return
    if os.environ.get("SIMPRO_KERNEL", "auto") == "python":
        return
    code = (
        "import os\n"
        "from simpro_mj.sim import compiling, numba_cache, step\n"
        "if not os.path.exists(os.path.join(step.compiled().cache_folder, numba_cache.COMPLETE)):\n"
        "    compiling.prepare_step()\n"
    )
    config._simpro_compile = subprocess.Popen(  # noqa: SIM115 - ended in sessionfinish
        [sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )


#: Test files that never step the compiled step, the dearest first (mypy without its
#: cache: about 20 s of CPU on a fresh clone; loading and validating every shipped
#: scenario). They run first, on the first worker (xdist hands each worker a contiguous
#: share of the list), while the controller compiles the step: on a fresh clone the
#: workers' first simulations would otherwise both wait for that compile, and one core
#: would stand idle. A warm tree runs the same tests in another order.
WHILE_THE_STEP_COMPILES = (
    "test_annotations.py",
    "test_scenario.py",
    "test_scenario_hashes.py",
    "test_scenario_messages.py",
    "test_imports.py",
    "test_cli_help.py",
    "test_results_yaml.py",
)


def pytest_collection_modifyitems(session, config, items):
    """:data:`WHILE_THE_STEP_COMPILES` first (the same order in every worker: xdist
    requires one collection)."""
    rank = {name: i for i, name in enumerate(WHILE_THE_STEP_COMPILES)}
    first = sorted((i for i in items if i.path.name in rank), key=lambda i: rank[i.path.name])
    items[:] = first + [i for i in items if i.path.name not in rank]


def pytest_sessionfinish(session):
    """The controller's compile is over by the end (a short selection of tests that
    never needed the step may end first: it is stopped, and numba keeps no half files)."""
    proc = getattr(session.config, "_simpro_compile", None)
    if proc is not None and proc.poll() is None:
        proc.terminate()
        proc.wait(60)


def _recorded_run(folder, rows: int = 50):
    """A result folder as ``run`` writes it, without simulating: the plant's 13
    joints at rest in ``qpos.npz`` and the columns a replay draws."""
    import numpy as np

    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.report.results import write_results
    from simpro_mj.report.scene import replay_model
    from simpro_mj.sim.result import qpos_names

    sc = load_scenario("step_pitch", ["duration_s=0.2"])
    names = qpos_names(replay_model(sc)[0])
    t = np.arange(rows) * 1e-3
    cols = {"time_s": t}
    for c in ("roll_ref_rad", "pitch_ref_rad", "heave_ref_m", "roll_rad", "pitch_rad", "heave_m",
              "u1_v", "u2_v", "u3_v"):  # fmt: skip
        cols[c] = np.zeros_like(t)
    rec = {"time_s": t, "qpos": np.zeros((rows, len(names))), "qpos_names": np.array(names)}
    write_results(folder, cols, {}, sc, {"plots": False}, arrays={"qpos.npz": rec})
    return folder


@pytest.fixture
def recorded_run():
    """``recorded_run(folder, rows=50)``: a replayable result folder (no simulation)."""
    return _recorded_run


@pytest.fixture
def fake_identify(monkeypatch):
    """The identification experiment replaced: each call recorded (its tree), models
    scaled by the payload returned (the real experiment is tested in
    tests/test_autoident.py)."""
    import simpro_mj.identification.identify as ident

    calls = []

    def fake(tree, legs=(1, 2, 3), records=None):
        calls.append(tree)
        m = tree["model"]["payload"]["mass_kg"]
        return {f"actuator{i}": ident.Fit(b=10.0 + i, a1=20.0, a0=100.0 + m) for i in legs}

    monkeypatch.setattr(ident, "identify", fake)
    return calls
