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

__all__ = ["sensor_constants", "build", "initial_state"]


def sensor_constants(cfg) -> np.ndarray:
    """``sc`` of :func:`simpro_mj.plant.step_functions.sample_sensors` from a SensorConfig."""
    sc = np.zeros(ps.SC_LEN)
    sc[ps.SC_GAIN : ps.SC_GAIN + 3] = cfg.pot_gain
    sc[ps.SC_OFF : ps.SC_OFF + 3] = cfg.pot_offset_m
    sc[ps.SC_SIGMA], sc[ps.SC_LSB] = cfg.pot_noise_m, cfg.pot_lsb_m
    sc[ps.SC_LO], sc[ps.SC_HI] = cfg.pot_range_m
    sc[ps.SC_POT_EVERY] = cfg.pot_every
    sc[ps.SC_ENC_NOISE], sc[ps.SC_RES], sc[ps.SC_ENC_EVERY] = (
        cfg.enc_noise_m,
        cfg.enc_res_m,
        cfg.enc_every,
    )
    sc[ps.SC_ALPHA], sc[ps.SC_SIGMA_IMU] = cfg.imu_alpha, cfg.imu_noise_rad
    sc[ps.SC_BIAS : ps.SC_BIAS + 2] = cfg.imu_bias_rad
    sc[ps.SC_IMU_EVERY] = cfg.imu_every
    sc[ps.SC_FS], sc[ps.SC_NL] = cfg.pot_full_scale_m, cfg.pot_nonlinearity
    sc[ps.SC_WALK], sc[ps.SC_ACCW] = cfg.imu_walk_rad, cfg.imu_accel_weight
    sc[ps.SC_IDT2] = 1.0 / (cfg.dt * cfg.dt)
    return sc


def build(sim, loop_bound: float) -> tuple[np.ndarray, np.ndarray]:
    """``(S, C)`` of a :class:`~simpro_mj.sim.loop.CoSimulation`, state not yet initialised."""
    filt, joint, task, idx, act = sim.setpoint_filter, sim.joint, sim.task, sim.idx, sim.actuators
    act.set_timestep(sim.dt)
    ac = act.step_constants
    lay = st.Layout(max(filt.n), ac.size)
    C = np.zeros(lay.c_len)
    C[st.DT], C[st.NSTEPS], C[st.DEC], C[st.OUTER] = (
        sim.dt,
        sim.n_steps,
        sim.decimation,
        sim.outer_every,
    )
    C[st.HOLD_SAT] = 1.0 if sim.mode == "feedforward" and sim.hold_on_saturation else 0.0
    C[st.HAS_UFF] = 1.0 if sim.u_ff is not None else 0.0
    C[st.LOOP_BOUND] = loop_bound
    C[st.FKIND] = filt.step_kind
    C[st.FN : st.FN + 3] = filt.step_n
    C[st.FA : st.FA + 3] = filt.step_a
    C[st.FB : st.FB + 3] = filt.step_b
    C[st.LIM : st.LIM + 5] = joint.step_limits
    C[st.IGAIN : st.IGAIN + 3] = joint._int_gain
    C[st.JDB : st.JDB + 3] = joint.step_band
    C[st.JM : st.JM + 48] = joint.step_matrices.reshape(48)
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
    C[st.SC : st.SC + ps.SC_LEN] = sensor_constants(sim.sensor_cfg)
    C[st.TC : st.TC + cs.TC_LEN] = task.step_constants
    C[st.GEOM : st.GEOM + cs.GEOM_LEN] = task.step_geometry
    C[st.AC :] = ac
    return np.zeros(lay.s_len), C


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
    S[:] = 0.0
    S[st.SUPPLY_LOG] = sim.actuators.params.p_supply
    S[st.AST : st.AST + ps.A_LEN] = sim.actuators.step_state
    C[st.AC :] = sim.actuators.step_constants  # the linear model's rest values
    # the sensors initialised at the true state, and a first reading
    d = sim.data
    q, pose = S[st.Q : st.Q + 3], S[st.POSE : st.POSE + 3]
    ps.slide_states(
        d.qpos, d.qvel, C[st.IQ : st.IQ + 3], C[st.IV : st.IV + 3], q, S[st.QD : st.QD + 3]
    )
    ps.platform_pose(d.site_xmat.reshape(-1), d.site_xpos.reshape(-1), C[st.IMAT], C[st.IH], pose)
    ss = S[st.SS : st.SS + ps.SS_LEN]
    ss[ps.SS_IMU : ps.SS_IMU + 2] = pose[:2]
    S[st.WALK_M] += ps.sample_sensors(
        0,
        True,
        S[st.Q : st.Q + 3],
        S[st.POSE : st.POSE + 3],
        None,  # no acceleration at the first reading
        noise_row,
        walk_row,
        C[st.SC : st.SC + ps.SC_LEN],
        ss,
        S[st.QM : st.QM + 3],
        S[st.PM : st.PM + 3],
    )
    ts = S[st.TS : st.TS + cs.T_LEN]
    ts[:] = sim.task.step_state
    S[st.PCMD : st.PCMD + 3] = ts[cs.T_XC : cs.T_XC + 3]
    S[st.JX : st.JX + 9] = sim.joint._x
    y, total, head, ring = sim.setpoint_filter.state()
    S[st.FY : st.FY + 3], S[st.FSUM : st.FSUM + 3], S[st.FHEAD : st.FHEAD + 3] = y, total, head
    S[st.RING :].reshape(3, -1)[:] = ring
    S[st.STATUS] = st.IDLE
