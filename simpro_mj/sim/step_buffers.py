"""The flat arrays of one run's step (:mod:`simpro_mj.sim.step`), filled from its objects.

The controllers, the sensors' configuration and the actuators are built and
validated as objects (:class:`~controllers.joint.JointControllers`,
:class:`~controllers.task_space.TaskSpaceController`,
:class:`~controllers.setpoint_filter.SetpointFilter`,
:class:`~simpro_mj.plant.sensors.SensorConfig`, the actuators of
:func:`~simpro_mj.plant.pneumatics.factory.make_actuators`); here their
numbers go into the constants ``C`` and their initial state into ``S``.
"""

from __future__ import annotations

import numpy as np

from controllers import step_functions as cs
from simpro_mj.plant import step_functions as ps
from simpro_mj.sim import step as st

__all__ = ["build", "initial_state"]


def build(sim, loop_bound: float) -> tuple[np.ndarray, np.ndarray]:
    """``(S, C)`` of a :class:`~simpro_mj.sim.loop.CoSimulation`, state not yet initialised."""
    filt, joint, task, idx, act = sim.setpoint_filter, sim.joint, sim.task, sim.idx, sim.actuators
    act.set_timestep(sim.dt)
    ac = act.step_constants
    C = np.zeros(st.AC + ac.size)
    C[st.DT : st.OUTER + 1] = sim.dt, sim.n_steps, sim.decimation, sim.outer_every
    C[st.HOLD_SAT] = 1.0 if sim.mode == "feedforward" and sim.hold_on_saturation else 0.0
    C[st.HAS_UFF] = 1.0 if sim.u_ff is not None else 0.0
    C[st.LOOP_BOUND] = loop_bound
    C[st.FC : st.FC + cs.FC_LEN] = filt.step_constants
    C[st.JC : st.JC + cs.J_LEN] = joint.step_constants
    C[st.IQ : st.IQ + 3] = idx.slide_qpos
    C[st.IV : st.IV + 3] = idx.slide_dof
    C[st.IMAT], C[st.IH] = 9 * int(idx.site_p), 3 * int(idx.site_p) + 2
    pairs = [(3 * int(a), 3 * int(b)) for a, b in idx.connect_sites]
    if len(pairs) > st.MAX_PAIRS:
        raise ValueError(f"the model has {len(pairs)} closed loops; the step reads {st.MAX_PAIRS}")
    C[st.NPAIR] = len(pairs)
    C[st.PAIRS : st.PAIRS + 2 * len(pairs)] = [i for p in pairs for i in p]
    if sim.cueing:
        C[st.HEAD] = 1.0
        C[st.IHA] = _sensor_start(sim.idx.sensor["head_accel"])
        C[st.IHG] = _sensor_start(sim.idx.sensor["head_gyro"])
    C[st.ICTRL : st.ICTRL + 3] = idx.actuators
    C[st.SC : st.SC + ps.SC_LEN] = sim.sensor_cfg.step_constants
    C[st.TC : st.TC + cs.TC_LEN] = task.step_constants
    C[st.GEOM : st.GEOM + cs.GEOM_LEN] = task.step_geometry
    return np.zeros(st.RING + 3 * max(filt.n)), C


def _sensor_start(sl) -> int:
    """First ``sensordata`` index of a sensor (a slice or an index array)."""
    if isinstance(sl, slice):
        return int(sl.start)
    return int(np.asarray(sl).ravel()[0])


def initial_state(S, C, sim, noise_row, walk_row) -> None:
    """``S`` from the objects after their ``reset``; the sensors take a first reading.

    The controllers' (outer loop, set-point filter, joint loops) and the
    actuators' states are copied from the objects, which ran the same
    per-step functions on them.
    """
    S[st.SUPPLY_LOG] = sim.actuators.params.p_supply
    S[st.AST : st.AST + ps.A_LEN] = sim.actuators.step_state
    C[st.AC :] = sim.actuators.step_constants  # the linear model's rest values
    # the sensors initialised at the true state, and a first reading
    d = sim.data
    q, pose, qm, pm = (S[i : i + 3] for i in (st.Q, st.POSE, st.QM, st.PM))
    iq, iv = C[st.IQ : st.IQ + 3], C[st.IV : st.IV + 3]
    ps.slide_states(d.qpos, d.qvel, iq, iv, q, S[st.QD : st.QD + 3])
    ps.platform_pose(d.site_xmat.reshape(-1), d.site_xpos.reshape(-1), C[st.IMAT], C[st.IH], pose)
    ss, sc = S[st.SS : st.SS + ps.SS_LEN], C[st.SC : st.SC + ps.SC_LEN]
    ss[ps.SS_IMU : ps.SS_IMU + 2] = pose[:2]
    # no acceleration at the first reading (no IMU site positions)
    S[st.WALK_M] += ps.sample_sensors(0, True, q, pose, None, noise_row, walk_row, sc, ss, qm, pm)
    ts = S[st.TS : st.TS + cs.T_LEN]
    ts[:] = sim.task.step_state
    S[st.PCMD : st.PCMD + 3] = ts[cs.T_XC : cs.T_XC + 3]
    S[st.JX : st.JX + 9] = sim.joint._x
    S[st.FS : st.FS + cs.FS_LEN] = sim.setpoint_filter.step_state
    S[st.RING :].reshape(3, -1)[:] = sim.setpoint_filter.ring
    S[st.STATUS] = st.IDLE
