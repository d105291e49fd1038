"""The compiled pneumatics kernel (numba, ``SIMPRO_KERNEL``) equals the Python path.

Measured bit-identical (forces, pressures, spool states on every step, and
whole co-simulations); that is what lets ``SIMPRO_KERNEL=auto`` pick numba
by default without breaking ``tests/test_reference_metrics.py``'s SHA-256
checks, so these tests assert exact equality, not a tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest

from simpro_mj.analysis.metrics import compute_metrics
from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.plant import kernels as pk
from simpro_mj.plant.pneumatics.nonlinear import NonlinearActuators
from simpro_mj.report.results import versions
from simpro_mj.sim.loop import CoSimulation

needs_numba = pytest.mark.skipif(not pk._HAVE_NUMBA, reason="numba not installed")


def _pair(monkeypatch, overrides=None):
    monkeypatch.setenv("SIMPRO_KERNEL", "python")
    a = NonlinearActuators(overrides)
    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    b = NonlinearActuators(overrides)
    assert a._kernel is None and b._kernel is not None
    return a, b


def test_kernel_choice(monkeypatch):
    monkeypatch.setenv("SIMPRO_KERNEL", "python")
    assert pk.kernel_choice() == "python" and versions()["kernels"] == "python"
    assert NonlinearActuators()._kernel is None
    monkeypatch.delenv("SIMPRO_KERNEL")
    assert pk.kernel_choice() == ("numba" if pk._HAVE_NUMBA else "python")
    monkeypatch.setenv("SIMPRO_KERNEL", "x")
    with pytest.raises(UserInputError) as e:
        NonlinearActuators()
    assert str(e.value) == (
        "invalid value at SIMPRO_KERNEL: 'x'; allowed: one of ['auto', 'python', 'numba']"
    )


@needs_numba
def test_versions_name_the_kernel(monkeypatch):
    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    assert versions()["kernels"] == f"numba {pk.numba_version()}"


@needs_numba
@pytest.mark.parametrize(
    "overrides",
    [
        None,
        {"valve": {"spool_order": 2}},
        {"integration": {"substeps": 3}},
        {"valve": {"spool_order": 2, "underlap_fraction": [0.0, 0.05, 0.3]}},
    ],
)
def test_kernel_equals_python_on_random_inputs(monkeypatch, overrides):
    a, b = _pair(monkeypatch, overrides)
    rng = np.random.default_rng(7)
    for k in range(3000):
        u = rng.uniform(-1, 11, 3)  # beyond the 0-10 V range too
        q = rng.uniform(-0.01, 0.51, 3)  # and past the end stops
        qd = rng.normal(0, 0.3, 3)
        if k == 1500:  # supply-drop fault at run time
            a.set_supply_pressure(4.5e5)
            b.set_supply_pressure(4.5e5)
        # arrays and lists (the co-simulation's case) both reach the kernel
        args = (u, q, qd) if k % 2 else (u.tolist(), q.tolist(), qd.tolist())
        fa, fb = a.step(*args, 1e-3), b.step(*args, 1e-3)
        assert np.array_equal(fa, fb), k
        assert np.array_equal(a._z, b._z) and np.array_equal(a.spool, b.spool)
        assert np.array_equal(a.spool_rate, b.spool_rate)
    # a new dt, scalar broadcast and integer inputs take the same path
    assert np.array_equal(a.step(6, 0.25, 0, 2e-3), b.step(6, 0.25, 0, 2e-3))
    assert np.array_equal(a.p1, b.p1) and np.array_equal(a.p2, b.p2)


@needs_numba
def test_kernel_propagates_nan(monkeypatch):
    a, b = _pair(monkeypatch)
    fa = a.step([np.nan, 5.0, 5.0], [0.25] * 3, [0.0] * 3, 1e-3)
    fb = b.step([np.nan, 5.0, 5.0], [0.25] * 3, [0.0] * 3, 1e-3)
    assert np.isnan(fa[0]) and np.array_equal(fa, fb, equal_nan=True)
    assert np.array_equal(a._z, b._z, equal_nan=True)


@needs_numba
def test_cosimulation_bit_identical(monkeypatch):
    """A 3 s pitch step: every logged column and the metrics, both kernels."""
    runs = {}
    for kernel in ("python", "numba"):
        monkeypatch.setenv("SIMPRO_KERNEL", kernel)
        sc = load_scenario("step_pitch", ["duration_s=3"])
        res = CoSimulation(sc).run()
        assert res.status == "ok"
        runs[kernel] = (res.columns, compute_metrics(res.columns, sc))
    (ca, ma), (cb, mb) = runs["python"], runs["numba"]
    assert set(ca) == set(cb)
    for col in ca:
        assert np.array_equal(ca[col], cb[col], equal_nan=True), col
    assert ma == mb
