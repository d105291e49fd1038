"""The compiled step as MuJoCo's control callback (numba; imported only when it runs).

:func:`entry` is a C function ``entry(mjData*, registry*)`` compiled once
and kept in numba's on-disk cache: it finds the run registered for that
``mjData`` (:data:`simpro_mj.sim.step.REGISTRY`, keyed by the struct's
address), views its arrays and MuJoCo's (``numba.carray`` on the addresses
read from the ``mjData`` struct at the word offsets found at set-up,
:func:`simpro_mj.sim.step.mjdata_offsets`) and runs
:func:`simpro_mj.sim.step.callback_step` compiled. It does nothing for any
other ``mjData``.

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
from numba import carray, cfunc, types
from numba.extending import intrinsic

from simpro_mj.sim import step as st

__all__ = ["entry", "frozen_clock", "install_pointer"]

_body = st.compiled().callback_step


@intrinsic
def _as_ptr(typingctx, addr):
    """An int64 address as a ``void*``."""

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.voidptr))

    return types.voidptr(types.int64), codegen


@intrinsic
def _as_int(typingctx, ptr):
    """A ``void*`` as an int64 address."""

    def codegen(context, builder, signature, args):
        return builder.ptrtoint(args[0], context.get_value_type(types.int64))

    return types.int64(types.voidptr), codegen


@cfunc(types.void(types.voidptr, types.voidptr), cache=True)
def entry(d, registry):
    """The step of the run registered for ``d``, if any (module docstring)."""
    reg = carray(registry, (st.N_SLOTS * st.SLOT,), np.int64)
    da = _as_int(d)
    b = -1
    for s in range(st.N_SLOTS):
        if reg[s * st.SLOT + st.R_DATA] == da:
            b = s * st.SLOT
            break
    if b < 0:
        return
    f8 = np.float64
    dw = carray(d, (st.MJDATA_WORDS,), np.int64)
    S = carray(_as_ptr(reg[b + st.R_S]), (reg[b + st.R_SN],), f8)
    C = carray(_as_ptr(reg[b + st.R_C]), (reg[b + st.R_CN],), f8)
    nref = reg[b + st.R_NREF]
    ref = carray(_as_ptr(reg[b + st.R_REF]), (nref, 3), f8)
    qj = carray(_as_ptr(reg[b + st.R_QJ]), (nref, 3), f8)
    uff = carray(_as_ptr(reg[b + st.R_UFF]), (nref, 3), f8)
    noise = carray(_as_ptr(reg[b + st.R_NOISE]), (reg[b + st.R_NNOISE], 6), f8)
    nq, nlog = reg[b + st.R_NQ], reg[b + st.R_NLOG]
    log = carray(_as_ptr(reg[b + st.R_LOG]), (nlog, st.N_COLS), f8)
    qlog = carray(_as_ptr(reg[b + st.R_QLOG]), (nlog, nq), f8)
    hlog = carray(_as_ptr(reg[b + st.R_HLOG]), (reg[b + st.R_NHLOG], 6), f8)
    walk = carray(_as_ptr(reg[b + st.R_WALK]), (reg[b + st.R_NWALK], 2), f8)
    qpos = carray(_as_ptr(dw[reg[b + st.R_QPOS]]), (nq,), f8)
    qvel = carray(_as_ptr(dw[reg[b + st.R_QVEL]]), (nq,), f8)
    nx = reg[b + st.R_NXPOS]
    xpos = carray(_as_ptr(dw[reg[b + st.R_XPOS]]), (nx,), f8)
    xmat = carray(_as_ptr(dw[reg[b + st.R_XMAT]]), (3 * nx,), f8)
    ctrl = carray(_as_ptr(dw[reg[b + st.R_CTRL]]), (reg[b + st.R_NU],), f8)
    sd = carray(_as_ptr(dw[reg[b + st.R_SD]]), (reg[b + st.R_NSD],), f8)
    warn = carray(_as_ptr(da + reg[b + st.R_WARN]), (reg[b + st.R_NWARN],), np.int32)
    _body(S, C, qpos, qvel, xpos, xmat, sd, ctrl, warn, ref, qj, uff, noise, walk, log, qlog, hlog)


@cfunc(types.float64(), cache=True)
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
  call void %f(ptr %d, ptr %r)
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
