import os

os.environ.setdefault("MPLBACKEND", "Agg")
# headless MuJoCo rendering (tests/test_render.py): MuJoCo reads this when first imported
os.environ.setdefault("MUJOCO_GL", "egl")
# one BLAS thread per test process: the analyses' matrices are small (at most 65
# states), and OpenBLAS's threads, spinning against a loaded 2-core machine, made the
# preflight's lifted loop take 455 s instead of 23 s; set before numpy is imported
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

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
