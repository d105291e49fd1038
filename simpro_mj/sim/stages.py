"""The stages of one 1 ms step, as functions the loop's body calls in turn.

:meth:`CoSimulation.run <simpro_mj.sim.loop.CoSimulation.run>` is a short
body over six stage functions::

    step1()                                              physics (mj_step1)
    q, q_dot, pose, q_meas, pose_meas, loop = sense(k)   sensors
    q_r, u, pose_cmd = control(k, pose_meas, q_meas)     controllers
    f = actuate(u, q, q_dot, dt).tolist()                pneumatics
    record(k, ...)                                       logging (every decimation)
    step2(f)                                             physics (mj_step2)

The stages are chosen before the run, not tested in the body: the
controller mode picks one :func:`control_stage`; a fault swaps the sensing
and control stages at its events (:class:`FaultStages`); profiling wraps
every stage in a clock (:class:`Profile`). Each is a closure over local
names (the body runs 10^4 - 10^6 times: a closure's cell read costs less
than an attribute look-up) doing the same IEEE operations, in the same order,
as the loop it replaced, so results stay bit-identical
(``tests/test_reference_metrics.py``).
"""

from __future__ import annotations

import struct
import time

import numpy as np

from simpro_mj.plant.faults import FaultSchedule

__all__ = ["control_stage", "Recorder", "FaultStages", "Profile"]


def control_stage(mode, *, task, joint, setpoint_filter, ref, outer_every, q_joint=None,
                  u_ff=None, hold_on_saturation=False):  # fmt: skip
    """The controllers of one step: ``control(k, pose_meas, q_meas) -> (q_r, u, pose_cmd)``.

    Parameters
    ----------
    mode : {"task_space", "feedforward", "joint_only"}
        ``task_space``: the outer loop every ``outer_every`` steps (eqs. 21-27),
        its IK held in between. ``feedforward``: ``IK(y_d + c)`` every step,
        the correction ``c`` integrated at the outer steps; a valve at its
        rail during the last outer period holds it (``hold_on_saturation``).
        ``joint_only`` (the baseline): ``q_joint[k] = IK(y_d(t_k))`` of the
        nominal model, precomputed.
    task : TaskSpaceController
    joint : JointControllers
        Its float path ``update_floats(q_r, q_meas[, u_ff])``.
    setpoint_filter : SetpointFilter
        Fig. 13's filter between q_d and the joint loops.
    ref : ndarray (n + 1, 3)
        The set-points y_d(t_k).
    outer_every : int
        The outer period in physics steps.
    q_joint : ndarray (n + 1, 3), optional
        ``joint_only``: the joint set-points.
    u_ff : list of (3,) lists, optional
        ``feedforward``: the leg velocity feed-forward voltage of each step.
    """
    filt, update = setpoint_filter.update, joint.update_floats
    if mode == "joint_only":

        def control(k, pose_meas, q_meas):
            q_r = filt(q_joint[k].tolist())
            return q_r, update(q_r, q_meas), ref[k].tolist()

        return control

    if mode == "task_space":
        q_d = task.q_desired.tolist()
        pose_cmd = ref[0].tolist()

        def control(k, pose_meas, q_meas):
            nonlocal q_d, pose_cmd
            if k % outer_every == 0:
                q_d = task.update_floats(ref[k].tolist(), pose_meas)
                pose_cmd = task.pose_command.tolist()
            q_r = filt(q_d)
            return q_r, update(q_r, q_meas), pose_cmd

        return control

    u_lo, u_hi = joint.u_min, joint.u_max
    sat_seen = False  # a valve at its rail since the last outer step

    def control(k, pose_meas, q_meas):
        nonlocal sat_seen
        if k % outer_every == 0:
            q_d = task.update_floats(ref[k].tolist(), pose_meas, sat_seen, q_meas)
            sat_seen = False
        else:
            q_d = task.feedforward_floats(ref[k].tolist(), pose_meas, q_meas)
        q_r = filt(q_d)
        u = update(q_r, q_meas) if u_ff is None else update(q_r, q_meas, u_ff[k])
        if hold_on_saturation and not sat_seen:
            u0, u1, u2 = u
            sat_seen = not (u_lo < u0 < u_hi and u_lo < u1 < u_hi and u_lo < u2 < u_hi)
        return q_r, u, task.pose_command.tolist()

    return control


class Recorder:
    """The run's log: one row of :data:`~simpro_mj.sim.result.COLUMNS` per logged step.

    Preallocated (``rows`` x columns); :meth:`writer` gives the ``record``
    stage, which packs each row straight into the buffer
    (``struct.pack_into``, no per-step objects), copies ``qpos`` and, for
    cueing runs, the head sensors.

    Attributes
    ----------
    rows : int
        Rows written.
    worst_loop : float
        Largest loop-closure error logged (m).
    flags, supply_pa : int, float
        The fault columns of the next rows (set by :class:`FaultStages`).
    """

    def __init__(self, n_rows: int, n_cols: int, nq: int, head: bool, supply_pa: float):
        self.log = np.full((n_rows, n_cols), np.nan)
        self.qlog = np.empty((n_rows, nq))  # copies of qpos at the logged rows
        self.hlog = np.full((n_rows, 6), np.nan) if head else None
        self.rows = 0
        self.worst_loop = 0.0
        self.flags = 0
        self.supply_pa = float(supply_pa)

    def writer(self, ref, dt: float, platform, loop_bound: float, head_sensors=None):
        """``record(k, pose, pose_meas, pose_cmd, q_r, q, q_meas, u, f, loop)``.

        ``head_sensors``: the ``sensordata`` slices of ``head_accel`` and
        ``head_gyro`` (cueing runs). The accelerometer's value after
        ``mj_step1`` is the one ``mj_step2`` computed for the previous step
        (1 ms old); the gyro's is current. A loop-closure error above
        ``loop_bound`` (m) stops the run (:meth:`Platform.check_loops`,
        raising :class:`PhysicsError`) after its row is written.
        """
        log, qlog, hlog, rec = self.log, self.qlog, self.hlog, self
        # one row = n_col native doubles packed into the (C-contiguous) log buffer
        put_row, row_bytes = struct.Struct(f"{log.shape[1]}d").pack_into, 8 * log.shape[1]
        d, act = platform.data, platform.actuators
        qpos, sd = d.qpos, d.sensordata
        act_p1, act_p2 = act.p1, act.p2  # views of the chamber pressures, updated in place
        ha, hg = head_sensors if head_sensors is not None else (None, None)
        check_loops = platform.check_loops

        def record(k, pose, pose_meas, pose_cmd, q_r, q, q_meas, u, f, loop):
            row = rec.rows
            if loop > rec.worst_loop:  # max() without the call
                rec.worst_loop = loop
            p1, p2 = act_p1.tolist(), act_p2.tolist()
            put_row(
                log, row * row_bytes,
                k * dt, *ref[k].tolist(), *pose, *pose_meas, *pose_cmd, *q_r,
                *q, *q_meas, *u, *f,
                p1[0], p2[0], p1[1], p2[1], p1[2], p2[2], loop, rec.flags, rec.supply_pa,
            )  # fmt: skip
            qlog[row] = qpos
            if ha is not None:
                hlog[row, :3] = sd[ha]
                hlog[row, 3:] = sd[hg]
            rec.rows = row + 1
            if loop > loop_bound:
                check_loops(loop_bound)  # raises, naming the loop

        return record


class FaultStages:
    """Scheduled faults as stage swaps at their event steps.

    Between events the loop runs the plain stages (a run without faults pays
    one int compare per step, ``k == next_event``); at an event :meth:`at`
    brings the schedule to step ``k``, applies a supply change to the
    actuators, sets the fault columns of the log and returns the stages for
    the new fault state: while a sensor fault acts, ``sense`` hands the
    controllers :meth:`FaultSchedule.apply_sensors` of the readings (the
    sensors' own state is untouched); while a valve is stuck, ``control``
    returns :meth:`FaultSchedule.apply_valves` of the joint loops' command
    (their own state keeps their own command). The log holds what the
    controllers saw and the voltages applied.
    """

    def __init__(self, schedule: FaultSchedule, actuators, recorder: Recorder, sense, control,
                 wrap=None):  # fmt: skip
        self.schedule, self.actuators, self.recorder = schedule, actuators, recorder
        self._wrap = wrap if wrap is not None else (lambda fn, stage: fn)
        self._sense, self._control = sense, control
        apply_sensors, apply_valves = schedule.apply_sensors, schedule.apply_valves

        def sense_faulty(k):
            q, qd, pose, q_meas, pose_meas, loop = sense(k)
            q_meas, pose_meas = apply_sensors(k, q_meas, pose_meas)
            return q, qd, pose, q_meas, pose_meas, loop

        def control_stuck(k, pose_meas, q_meas):
            q_r, u, pose_cmd = control(k, pose_meas, q_meas)
            return q_r, apply_valves(u), pose_cmd

        self._sense_faulty, self._control_stuck = sense_faulty, control_stuck

    @property
    def next_event(self) -> int:
        return self.schedule.next_event

    def at(self, k: int):
        """Event at step ``k``: ``(sense, control, next_event)`` from this step on."""
        s = self.schedule
        ch = s.at_event(k)
        if ch.supply_pa is not None:
            self.actuators.set_supply_pressure(ch.supply_pa)
            self.recorder.supply_pa = ch.supply_pa
        self.recorder.flags = s.flags
        sense = self._sense_faulty if s.sensor_active else self._sense
        control = self._control_stuck if s.valve_active else self._control
        wrap = self._wrap
        return wrap(sense, "sensors"), wrap(control, "controllers"), s.next_event


class Profile:
    """Wall time per stage, by wrapping the stage functions (``CoSimulation.run(profile=)``).

    :meth:`wrap` returns the stage with ``time.perf_counter_ns`` around it,
    adding to the stage's total; a plain run never sees the wrappers. The
    clock calls slow the step down (about 0.06 us each, two per stage).
    """

    STAGES = ("physics", "sensors", "controllers", "pneumatics", "logging")

    def __init__(self):
        self.ns = dict.fromkeys(self.STAGES, 0)

    def wrap(self, fn, stage: str):
        ns, clock = self.ns, time.perf_counter_ns

        def timed(*args):
            t0 = clock()
            out = fn(*args)
            ns[stage] += clock() - t0
            return out

        return timed
