"""The compiled step as MuJoCo's control callback (numba; imported only when it runs).

:func:`entry` is a C function ``entry(mjData address, registry*)`` compiled once
and kept in numba's on-disk cache: it finds the run registered for that
``mjData`` (:data:`simpro_mj.sim.step.REGISTRY`, keyed by the struct's
address), views its arrays and MuJoCo's (``numba.carray`` on the addresses
and sizes in its slot) and runs :func:`simpro_mj.sim.step.callback_step`
compiled. It does nothing for any other ``mjData``.

MuJoCo calls ``mjcb_control(const mjModel*, mjData*)``. The registry's
address differs in every process, so the function MuJoCo holds is a
two-instruction trampoline, ``mjcb(m, d) = entry(d, registry)``, written in
LLVM IR and compiled by llvmlite (numba's own back end) in milliseconds,
where a numba ``cfunc`` holding the address as a constant could not be
cached and would take about a second to compile in every process.

While a run steps, MuJoCo's profiler clock (``mjcb_time``, read 28 times a
step of this model for ``mjData.timer``) is :func:`frozen_clock`: no run
reads the timers, and the reads cost about 0.6 µs of bare ``mj_step``'s 8 µs
on a 2-core EPYC (``docs/performance.md``).
"""

from __future__ import annotations

import ctypes

import llvmlite.binding as llvm
import numpy as np
from numba import carray, types
from numba.extending import intrinsic

from simpro_mj.sim import step as st
from simpro_mj.sim.numba_cache import cfunc, jit

_body = st.compiled().callback_step
_FOLDER = st.compiled().cache_folder  # the step's cache, passed to each function below


@intrinsic
def _as_ptr(typingctx, addr):
    """An int64 address as a ``void*`` (called with the address alone: numba supplies
    ``typingctx``, which the type checker cannot know, hence the calls' ignores)."""

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.voidptr))

    return types.voidptr(types.int64), codegen


@jit(_FOLDER)
def _flat(a, i):
    """Array ``i`` of a slot (``a``: its (address, size, columns) triples) as 1-D float64."""
    return carray(_as_ptr(a[3 * i]), (a[3 * i + 1],), np.float64)  # type: ignore[call-arg]


@jit(_FOLDER)
def _rows(a, i):
    """Array ``i`` of a slot as rows of float64."""
    n = a[3 * i + 2]
    return carray(_as_ptr(a[3 * i]), (a[3 * i + 1] // n, n), np.float64)  # type: ignore[call-arg]


@cfunc(types.void(types.int64, types.voidptr), _FOLDER)
def entry(key, registry):
    """The step of the run registered for the ``mjData`` at ``key``, if any (module docstring)."""
    reg = carray(registry, (st.N_SLOTS * st.SLOT,), np.int64)
    for s in range(st.N_SLOTS):
        if reg[s * st.SLOT] == key:  # the arrays in the order of step.SLOT_ARRAYS
            a = reg[s * st.SLOT + 1 : (s + 1) * st.SLOT]
            S, C, qpos, qvel = _flat(a, 0), _flat(a, 1), _flat(a, 2), _flat(a, 3)
            xpos, xmat, sd, ctrl = _flat(a, 4), _flat(a, 5), _flat(a, 6), _flat(a, 7)
            warn = carray(_as_ptr(a[24]), (a[25],), np.int32)  # type: ignore[call-arg]
            ref, qj, uff, noise = _rows(a, 9), _rows(a, 10), _rows(a, 11), _rows(a, 12)
            walk, log, qlog, hlog = _rows(a, 13), _rows(a, 14), _rows(a, 15), _rows(a, 16)
            _body(S, C, qpos, qvel, xpos, xmat, sd, ctrl, warn, ref, qj, uff, noise, walk, log,
                  qlog, hlog)  # fmt: skip
            return


@cfunc(types.float64(), _FOLDER)
def frozen_clock():
    """``mjcb_time`` while a run steps: 0, so MuJoCo's timers never read the clock."""
    return 0.0


_PROTO = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)
_engines: list = []  # the trampolines' execution engines, alive with the process


def install_pointer(registry: np.ndarray):
    """The ``mjcb_control`` function for ``registry`` (a ctypes function pointer)."""
    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    ir = f"""
define void @simpro_mjcb(ptr %m, ptr %d) {{
  %f = inttoptr i64 {entry.address} to ptr
  %r = inttoptr i64 {registry.ctypes.data} to ptr
  %k = ptrtoint ptr %d to i64
  call void %f(i64 %k, ptr %r)
  ret void
}}
"""
    mod = llvm.parse_assembly(ir)
    mod.verify()
    tm = llvm.Target.from_default_triple().create_target_machine()
    ee = llvm.create_mcjit_compiler(mod, tm)
    ee.finalize_object()
    _engines.append((ee, registry))
    return _PROTO(ee.get_function_address("simpro_mjcb"))
