"""The identification experiment (Fig. 12) on the run's own 1 ms step.

:func:`step_experiment` steps a model with the law of
:mod:`controllers.experiment_law` in place of the joint controllers: the
stages of :mod:`simpro_mj.sim.step` (the sensors, that law, the actuators, the
log), compiled inside ``mj_step`` as MuJoCo's control callback when the run's
kernel is numba (``SIMPRO_KERNEL``, :func:`simpro_mj.plant.kernels.kernel_choice`),
else the same function interpreted between ``mj_step1`` and ``mj_step2``. The
experiment itself (the operating point, the holding voltages, the excitation,
the fit) is :mod:`simpro_mj.identification.identify`'s.
"""

from __future__ import annotations

import mujoco
import numpy as np

from simpro_mj.core.errors import PhysicsError
from simpro_mj.plant.kernels import kernel_choice
from simpro_mj.plant.model import check_physics
from simpro_mj.plant.sensors import DEFAULT_SENSORS, SensorConfig
from simpro_mj.sim import step
from simpro_mj.sim.stages import Log

#: Steps between two checks of the experiment's state (MuJoCo's, the loops' closure)
CHECK_EVERY = 250


def step_experiment(m, d, idx, act, xp, exc, loop_bound: float) -> dict:
    """Step the experiment, one step per row of ``exc`` but the last; its record.

    Parameters
    ----------
    m, d, idx : the model, its data at the operating point and its
        :class:`~simpro_mj.plant.model.PlantIndex`
    act : the actuators (reset at the operating point)
    xp : ndarray
        The law's constants (:data:`controllers.experiment_law.XC`).
    exc : ndarray (n + 1, 3)
        The dither and the excitation by step (the law's columns 0 and 1).
    loop_bound : float
        The loops' closure bound, m.

    Returns
    -------
    dict
        Per step (rows) and leg (columns): ``u`` the applied volts, ``q`` the
        slides (m) and ``qdot`` their speeds (m/s, the model's ``qdot``
        sensors), at the step's start.

    Raises
    ------
    PhysicsError
        On a MuJoCo warning, a non-finite force or state or an opened loop.
    """
    n = exc.shape[0] - 1
    dt = float(m.opt.timestep)
    act.set_timestep(dt)
    speeds, slides = idx.sensor["qdot1"].start, idx.sensor["pot1"].start
    if idx.sensor["qdot3"].start != speeds + 2 or idx.sensor["pot3"].start != slides + 2:
        raise ValueError("the model's qdot1-3 and pot1-3 sensors are not in order")
    C = step.CT.pack(
        dt=dt, nsteps=n, dec=1, outer=1, hold_sat=0.0, has_uff=1.0, head=1.0,
        loop_bound=loop_bound, fc=np.zeros(step.cs.FC.LEN), jc=np.zeros(step.cs.JC.LEN),
        tc=np.zeros(step.cs.TC.LEN), geom=np.zeros(step.cs.GEOM.LEN), iha=speeds, ihg=slides,
        sc=SensorConfig.from_tree(DEFAULT_SENSORS, dt).step_constants, xp=xp,
        ac=act.step_constants, **step.plant_reads(idx),
    )  # fmt: skip
    S = np.zeros(step.ST.LEN)
    S[step.ST.status] = step.IDLE
    S[step.ST.ast : step.ST.ast + step.ps.ACT.LEN] = act.step_state
    # the set-points and the joint-only input (unused by the law); the sensors read
    # without noise (the law acts on the true slides)
    ref, qj = np.zeros((n + 1, 3)), np.zeros((n + 1, 3))
    noise, walk = np.zeros((n + 1, 6)), np.zeros((n + 1, 2))
    log = Log(n + 1, m.nq, head=True)
    arrays = (ref, qj, exc, noise, walk, log.log, log.qlog, log.hlog)
    d.warning.number[:] = 0  # the assembly's: the step stops on any warning counted
    if kernel_choice() == "numba":
        from simpro_mj.sim.registration import Registration

        with Registration(d, S, C, *arrays):
            for k in range(0, n, CHECK_EVERY):
                S[step.ST.k], S[step.ST.status] = k, step.RUNNING
                mujoco.mj_step(m, d, min(CHECK_EVERY, n - k))
                _check(m, d, idx, S, loop_bound)
                S[step.ST.status] = step.IDLE
    else:
        qpos, qvel, sd, ctrl = d.qpos, d.qvel, d.sensordata, d.ctrl
        xpos, xmat = d.site_xpos.reshape(-1), d.site_xmat.reshape(-1)
        no_warn = np.zeros(0, dtype=np.int32)  # the warnings: checked here
        for k in range(n):
            mujoco.mj_step1(m, d)
            S[step.ST.k], S[step.ST.status] = k, step.RUNNING
            step.callback_step(S, C, qpos, qvel, xpos, xmat, sd, ctrl, no_warn, *arrays)
            mujoco.mj_step2(m, d)
            if (k + 1) % CHECK_EVERY == 0 or k == n - 1 or d.warning.number.any():
                _check(m, d, idx, S, loop_bound)
    if int(S[step.ST.rows]) != n:
        raise RuntimeError(f"the experiment's step ran {int(S[step.ST.rows])} of {n} steps")
    row = step.ROW
    return {
        "u": log.log[:n, row.u : row.u + 3],
        "q": log.log[:n, row.q : row.q + 3],
        "qdot": log.hlog[:n, :3],
    }


def _check(m, d, idx, S, loop_bound: float) -> None:
    """The step's own stop (an error code) and MuJoCo's state, as a PhysicsError."""
    check_physics(m, d, np.zeros_like(d.warning.number), loop_bound=loop_bound, index=idx)
    if S[step.ST.status] == step.STOPPED:
        err, t = int(S[step.ST.err]), S[step.ST.err_k] * float(m.opt.timestep)
        what = {step.ERR_FORCE: "a non-finite actuator force", step.ERR_LOOP: "a loop opened"}
        raise PhysicsError(f"the experiment stopped on {what.get(err, err)} at t = {t:.3f} s")
