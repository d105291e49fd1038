"""The machine fingerprint: what decides the last bits of a run.

Bit-identical results hold only on one machine. numpy dispatches its
vectorised loops (``tanh``, ``dot``, ...) on the CPU's instruction sets at run
time (and ``NPY_DISABLE_CPU_FEATURES`` turns some off), MuJoCo compiles several
code paths, numba compiles for the host CPU, and the closed loop with quantised
sensors grows a difference in the last bit into one ADC count. A result can be
compared bit for bit only with one made under the same fingerprint; across
fingerprints, at a stated tolerance (``tests/test_reference_metrics.py``).

The fingerprint holds the library versions, the kernel choice
(``SIMPRO_KERNEL``), the CPU's instruction-set flags that change floating-point
code paths and numpy's enabled SIMD features.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import platform
from functools import cache
from importlib import metadata

import numpy as np

from simpro_mj.plant.kernels import kernel_label

#: CPU flags (``/proc/cpuinfo``) that select floating-point code paths: vector
#: widths and fused multiply-add. Other flags (virtualisation, power) do not
#: change a result and would split identical machines.
_FP_FLAGS = (
    "sse2",
    "pni",  # SSE3, as /proc/cpuinfo names it
    "ssse3",
    "sse4_1",
    "sse4_2",
    "avx",
    "avx2",
    "fma",
    "f16c",
    "avx512f",
    "avx512dq",
    "avx512vl",
    "avx512bw",
    "avx512_fp16",
    "amx_tile",
    "asimd",  # aarch64
    "sve",
    "sve2",
)


def _cpuinfo(*keys: str) -> str | None:
    """The value of the first line of ``/proc/cpuinfo`` keyed by one of ``keys``, or None."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() in keys:
                    return value.strip()
    except OSError:
        pass
    return None


@cache  # the CPU's flags do not change within a process
def _cpu_flags() -> list[str]:
    have = _cpuinfo("flags", "Features")
    if have is None:
        return [platform.processor() or "unknown"]
    return [flag for flag in _FP_FLAGS if flag in have.split()]


def _numpy_simd() -> list[str]:
    # numpy's own extension, loaded with numpy (numpy >= 2, then numpy < 2)
    for name in ("numpy._core._multiarray_umath", "numpy.core._multiarray_umath"):
        try:
            features = importlib.import_module(name).__cpu_features__
        except (ImportError, AttributeError):
            continue
        return sorted(k for k, on in features.items() if on)
    return []


@cache  # read once per process: every result folder records them (0.03 s a read)
def dist_version(name: str) -> str | None:
    """The installed version of distribution ``name``, or None."""
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def machine_fingerprint() -> dict:
    """What decides the last bits of a co-simulation on this machine.

    Returns
    -------
    dict
        ``machine`` (``platform.machine()``), ``cpu_flags`` (the instruction-set
        flags of :data:`_FP_FLAGS` the CPU has), ``numpy_simd`` (numpy's
        enabled SIMD features, after ``NPY_DISABLE_CPU_FEATURES``), the
        versions of Python, numpy and MuJoCo, and ``kernels`` (the
        kernel choice of ``SIMPRO_KERNEL``, with numba's version).
    """
    return {
        "machine": platform.machine(),
        "cpu_flags": list(_cpu_flags()),
        "numpy_simd": _numpy_simd(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "mujoco": dist_version("mujoco"),
        "kernels": kernel_label(),  # "python" or "numba <version>"
    }


def fingerprint_id(fingerprint: dict | None = None) -> str:
    """A short stable name of a fingerprint (12 hex digits of its SHA-256)."""
    fp = machine_fingerprint() if fingerprint is None else fingerprint
    text = json.dumps(fp, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:12]


def describe_machine() -> dict:
    """CPU model, logical cores and the versions that set a benchmark's figures."""
    import mujoco  # its version: loaded by the bench that asks, not by every result

    return {
        "cpu": _cpuinfo("model name") or platform.processor() or platform.machine(),
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "kernels": kernel_label(),
    }
