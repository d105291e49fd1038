"""One run's arrays registered for MuJoCo's control callback (:mod:`simpro_mj.sim.callback`).

The callback is process-wide in MuJoCo; it acts on the ``mjData`` of the
runs registered in :data:`simpro_mj.sim.step.REGISTRY` and on nothing else.
The first registration installs it, the last one out uninstalls it. While
it is installed MuJoCo's profiler clock is frozen (``mjcb_time`` returns 0,
:func:`simpro_mj.sim.callback.frozen_clock`), unless another ``mjcb_time``
was set before: ``mjData.timer`` is not read by a run, and the clock's reads
are about 7 % of ``mj_step``. The callbacks are process-wide, so another
model stepping in this process meanwhile reads zero timers as well.
"""

from __future__ import annotations

import threading

import numpy as np

from simpro_mj.sim import step as st

__all__ = ["Registration"]

_reg_lock = threading.Lock()
_installed = {"cb": None, "count": 0, "previous": None, "previous_time": None}


def _make_callback():
    """The C callbacks (:mod:`simpro_mj.sim.callback`, numba): built once per process,
    ``(control, clock)``."""
    from simpro_mj.sim import callback  # numba: imported when a compiled run starts

    return callback.install_pointer(st.REGISTRY), callback.frozen_clock.ctypes


class Registration:
    """One run's arrays registered for the callback, which is installed while any is.

    A context manager: on entry the run's slot is filled (and the callback
    installed if it is the first), on exit the slot is freed and the last one
    out uninstalls the callback (restoring whatever was installed before).
    The arrays must stay alive and unmoved while registered (the object
    holds them).
    """

    def __init__(self, model, data, S, C, ref, qj, uff, noise, walk, log, qlog, hlog):
        import mujoco

        self._mujoco = mujoco
        self.arrays = (S, C, ref, qj, uff, noise, walk, log, qlog, hlog)
        for a in self.arrays:
            if a.dtype != np.float64 or not a.flags.c_contiguous:
                raise ValueError("registered arrays must be C-contiguous float64")
        if model.nv != model.nq:
            raise ValueError("the callback expects nq == nv (1-DOF joints only)")
        off = st.mjdata_offsets(data)
        slot = np.zeros(st.SLOT, dtype=np.int64)
        slot[st.R_DATA] = int(data._address)
        slot[st.R_S], slot[st.R_SN] = S.ctypes.data, S.size
        slot[st.R_C], slot[st.R_CN] = C.ctypes.data, C.size
        slot[st.R_REF], slot[st.R_NREF] = ref.ctypes.data, ref.shape[0]
        slot[st.R_QJ], slot[st.R_UFF] = qj.ctypes.data, uff.ctypes.data
        if qj.shape != ref.shape or uff.shape != ref.shape:
            raise ValueError("q_joint and u_ff must have the set-points' shape")
        slot[st.R_NOISE], slot[st.R_NNOISE] = noise.ctypes.data, noise.shape[0]
        slot[st.R_LOG], slot[st.R_NLOG] = log.ctypes.data, log.shape[0]
        slot[st.R_QLOG], slot[st.R_NQ] = qlog.ctypes.data, model.nq
        slot[st.R_HLOG], slot[st.R_NHLOG] = hlog.ctypes.data, hlog.shape[0]
        slot[st.R_WALK], slot[st.R_NWALK] = walk.ctypes.data, walk.shape[0]
        if log.shape[1] != st.N_COLS or qlog.shape != (log.shape[0], model.nq):
            raise ValueError("log buffers of the wrong shape")
        slot[st.R_QPOS], slot[st.R_QVEL] = off["qpos"], off["qvel"]
        slot[st.R_XPOS], slot[st.R_NXPOS] = off["site_xpos"], 3 * model.nsite
        slot[st.R_XMAT] = off["site_xmat"]
        slot[st.R_CTRL], slot[st.R_NU] = off["ctrl"], model.nu
        slot[st.R_SD], slot[st.R_NSD] = off["sensordata"], model.nsensordata
        slot[st.R_WARN], slot[st.R_NWARN] = off["warning"], off["n_warning"]
        self.slot = slot
        self.index = None
        self.data = data

    def __enter__(self):
        mujoco = self._mujoco
        with _reg_lock:
            if _installed["cb"] is None:
                _installed["cb"] = _make_callback()
            free = [s for s in range(st.N_SLOTS) if st.REGISTRY[s * st.SLOT + st.R_DATA] == 0]
            if not free:
                raise RuntimeError(f"more than {st.N_SLOTS} runs stepping at once in one process")
            s = free[0]
            st.REGISTRY[s * st.SLOT + 1 : (s + 1) * st.SLOT] = self.slot[1:]
            # the key last: the slot is whole when the callback can find it
            st.REGISTRY[s * st.SLOT + st.R_DATA] = self.slot[st.R_DATA]
            self.index = s
            if _installed["count"] == 0:
                _installed["previous"] = mujoco.get_mjcb_control()
                _installed["previous_time"] = mujoco.get_mjcb_time()
                control, clock = _installed["cb"]
                mujoco.set_mjcb_control(control)
                if _installed["previous_time"] is None:
                    mujoco.set_mjcb_time(clock)
            _installed["count"] += 1
        return self

    def __exit__(self, *exc):
        mujoco = self._mujoco
        with _reg_lock:
            s = self.index
            st.REGISTRY[s * st.SLOT : (s + 1) * st.SLOT] = 0
            self.index = None
            _installed["count"] -= 1
            if _installed["count"] == 0:
                mujoco.set_mjcb_control(_installed["previous"])
                mujoco.set_mjcb_time(_installed["previous_time"])
                _installed["previous"] = _installed["previous_time"] = None
        return False
