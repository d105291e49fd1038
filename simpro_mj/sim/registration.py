"""One run's arrays registered for MuJoCo's control callback (:mod:`simpro_mj.sim.callback`).

The callback is process-wide in MuJoCo; it acts on the ``mjData`` of the
runs registered in :data:`simpro_mj.sim.step.REGISTRY` only. While it is
installed MuJoCo's profiler clock is frozen too
(:func:`simpro_mj.sim.callback.frozen_clock`; an ``mjcb_time`` set before is
kept), so another model stepping in this process meanwhile reads zero timers.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from simpro_mj.sim import step as st

_reg_lock = threading.Lock()


@dataclass
class _Installed:
    """MuJoCo's process-wide callbacks as we found and set them."""

    cb: Any = None  # our (control, clock) cfuncs, made once
    count: int = 0  # registered runs
    previous: Any = None  # the control callback installed before ours
    previous_time: Any = None  # and the clock


_installed = _Installed()


def _make_callback():
    """The C callbacks (:mod:`simpro_mj.sim.callback`, numba): built once per process,
    ``(control, clock)``. Loaded through :func:`~simpro_mj.sim.compiling.prepare_step`
    (a no-op once a run has loaded it): callers that register without a run (the
    identification experiment) share a first compile with other processes too."""
    from simpro_mj.sim.compiling import prepare_step

    prepare_step()
    from simpro_mj.sim import callback  # numba: imported when a compiled run starts

    return callback.install_pointer(st.REGISTRY), callback.frozen_clock.ctypes


class Registration:
    """One run's arrays registered for the callback, which is installed while any is.

    A context manager: on entry the run's slot is filled (and the callback
    installed if it is the first), on exit the slot is freed and the last one
    out uninstalls the callback (restoring whatever was installed before).
    The arrays must stay alive and unmoved while registered (the object
    holds them; ``mjData``'s arrays keep their addresses for its life).
    """

    def __init__(self, data, S, C, ref, qj, uff, noise, walk, log, qlog, hlog):
        own = (S, C, ref, qj, uff, noise, walk, log, qlog, hlog)
        for a in own:
            if a.dtype != np.float64 or not a.flags.c_contiguous:
                raise ValueError("registered arrays must be C-contiguous float64")
        if qj.shape != ref.shape or uff.shape != ref.shape:
            raise ValueError("q_joint and u_ff must have the set-points' shape")
        if log.shape[1] != st.N_COLS or qlog.shape != (log.shape[0], data.qpos.size):
            raise ValueError("log buffers of the wrong shape")
        d = data
        warn = d.warning.lastinfo  # mjWarningStat {int lastinfo; int number}
        if warn.dtype != np.int32 or warn.strides != (8,):
            raise RuntimeError("mjData.warning laid out otherwise; run with SIMPRO_KERNEL=python")
        mj = (d.qpos, d.qvel, d.site_xpos, d.site_xmat, d.sensordata, d.ctrl)
        self.arrays = (S, C, *mj, warn, *own[2:])  # in the order of step.SLOT_ARRAYS
        slot = np.zeros(st.SLOT, dtype=np.int64)
        slot[0] = int(d._address)
        for i, a in enumerate(self.arrays):
            slot[1 + 3 * i : 4 + 3 * i] = a.ctypes.data, a.size, a.shape[-1]
        i = st.SLOT_ARRAYS.index("warn")
        slot[2 + 3 * i] = 2 * warn.size  # the pairs, as int32
        self.slot = slot
        self.index: int | None = None

    def __enter__(self):
        with _reg_lock:
            if _installed.cb is None:
                _installed.cb = _make_callback()
            free = [s for s in range(st.N_SLOTS) if st.REGISTRY[s * st.SLOT] == 0]
            if not free:
                raise RuntimeError(f"more than {st.N_SLOTS} runs stepping at once in one process")
            s = free[0]
            st.REGISTRY[s * st.SLOT + 1 : (s + 1) * st.SLOT] = self.slot[1:]
            # the key last: the slot is whole when the callback can find it
            st.REGISTRY[s * st.SLOT] = self.slot[0]
            self.index = s
            if _installed.count == 0:
                _installed.previous = mujoco.get_mjcb_control()
                _installed.previous_time = mujoco.get_mjcb_time()
                control, clock = _installed.cb
                mujoco.set_mjcb_control(control)
                if _installed.previous_time is None:
                    mujoco.set_mjcb_time(clock)
            _installed.count += 1
        return self

    def __exit__(self, *exc):
        with _reg_lock:
            s = self.index
            assert s is not None  # entered
            st.REGISTRY[s * st.SLOT : (s + 1) * st.SLOT] = 0
            self.index = None
            _installed.count -= 1
            if _installed.count == 0:
                mujoco.set_mjcb_control(_installed.previous)
                mujoco.set_mjcb_time(_installed.previous_time)
                _installed.previous = _installed.previous_time = None
        return False
