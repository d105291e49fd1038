"""The multi-rate co-simulation loop (replaces Simulink + ADAMS, paper Fig. 13).

One physics step of ``dt`` = 1 ms::

    mj_step1          kinematics and sensors at the state of t_k
    sensors           potentiometers, height encoder, IMU (own rates, ZOH)
    outer loop        every ``period_ms``: task error -> integrated pose -> IK -> q_d
                      (feedforward mode: q_d = IK(y_d + c) every step, the
                      correction c integrated every ``period_ms``)
    joint loops       q_d, q_meas -> valve voltages (1 ms)
    pneumatics        voltages, q, q_dot -> chamber pressures -> slide forces
    mj_step2          integrate to t_{k+1} with those forces held

Splitting ``mj_step`` into ``mj_step1``/``mj_step2`` puts the sensors and
the controller at the same instant as the state they act on (no hidden
one-step delay), as a real-time controller sampling at t_k would.

In joint-only mode (the baseline) q_d(t) = IK(y_d(t)) of the nominal model,
computed for the whole run at once.
"""

from __future__ import annotations

import math
import struct
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from controllers.design import Plant, paper_coefficients
from controllers.geometry import nominal_geometry
from controllers.joint import JointControllers
from controllers.kinematics import inverse_kinematics
from controllers.setpoint_filter import SetpointFilter
from controllers.task_space import TaskSpaceController, outer_law
from simpro_mj.core.errors import PhysicsError, UserInputError
from simpro_mj.plant.faults import FAULT_COLUMNS, NEVER, FaultSchedule
from simpro_mj.plant.model import (
    PlantIndex,
    StateReader,
    assemble,
    check_physics,
    load_model,
    measured_pose,
)
from simpro_mj.plant.pneumatics.factory import make_actuators
from simpro_mj.plant.pneumatics.statics import holding_forces
from simpro_mj.plant.sensors import SensorConfig, Sensors

__all__ = ["COLUMNS", "SimResult", "CoSimulation", "simulate"]

#: Logged columns (SI, units in the names), in CSV order.
COLUMNS = (
    ["time_s"]
    + [f"{a}_ref_{u}" for a, u in (("roll", "rad"), ("pitch", "rad"), ("heave", "m"))]
    + ["roll_rad", "pitch_rad", "heave_m"]
    + ["roll_meas_rad", "pitch_meas_rad", "heave_meas_m"]
    + ["roll_cmd_rad", "pitch_cmd_rad", "heave_cmd_m"]
    + [f"q{i}_ref_m" for i in (1, 2, 3)]
    + [f"q{i}_m" for i in (1, 2, 3)]
    + [f"q{i}_meas_m" for i in (1, 2, 3)]
    + [f"u{i}_v" for i in (1, 2, 3)]
    + [f"f{i}_n" for i in (1, 2, 3)]
    + [f"p{i}{c}_pa" for i in (1, 2, 3) for c in ("a", "b")]
    + ["loop_closure_m"]
    + list(FAULT_COLUMNS)  # fault_flags (bit mask, faults.FLAG_BITS), supply_pa
)

#: Divergence bound on the loop-closure error (m): far above the 0.5 mm of
#: normal motion, well below anything physical.
LOOP_OPEN_BOUND = 5e-3


@dataclass
class SimResult:
    """What one run produced. ``columns`` holds copies, never MuJoCo views."""

    columns: dict
    status: str  # "ok" | "diverged" | "interrupted"
    reason: str | None
    sim: dict
    scenario: dict
    sensor_floor: dict = field(default_factory=dict)
    #: where :func:`simpro_mj.report.runner.execute` wrote the result folder (None: not written)
    folder: Path | None = None
    #: ``qpos`` at every logged row, (rows, nq), a copy: the whole closed chain, so
    #: ``simpro-sim render`` replays the run exactly without re-simulating it.
    qpos: np.ndarray | None = None
    #: the joint owning each ``qpos`` entry (all hinges and slides: one entry each)
    qpos_names: tuple = ()


def _ms_to_steps(ms: float, dt: float, path: str) -> int:
    n = ms * 1e-3 / dt
    k = int(round(n))
    if k < 1 or abs(n - k) > 1e-9 * max(1.0, n):
        raise UserInputError(
            f"invalid value at {path}: {ms} ms; allowed: a positive integer multiple of the "
            f"{dt * 1e3:g} ms physics timestep"
        )
    return k


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


class CoSimulation:
    """A scenario's plant, sensors and controllers, ready to run.

    Parameters
    ----------
    scenario : dict
        A resolved scenario (:func:`simpro_mj.config.scenario.load_scenario`).
    model : mujoco.MjModel, optional
        A compiled plant; built from ``scenario["plant"]`` when omitted.
    """

    def __init__(self, scenario: dict, model: mujoco.MjModel | None = None):
        from simpro_mj.config.scenario import reference
        from simpro_mj.identification.auto import with_identified

        # design_plant identified: the scenario's own plant's models (cached)
        scenario, self.identified_source = with_identified(scenario, _say)
        self.scenario = scenario
        self.model = load_model(scenario["plant"]) if model is None else model
        m = self.model
        self.data = mujoco.MjData(m)
        self.idx = PlantIndex.of(m)
        self.dt = float(m.opt.timestep)
        dt = self.dt
        self.n_steps = int(round(scenario["duration_s"] / dt))
        self.decimation = int(scenario["logging"]["decimation"])
        if self.decimation < 1:
            raise UserInputError("invalid value at logging.decimation: allowed: integer >= 1")
        self.geometry = nominal_geometry()  # the controller's nominal model

        ctl = scenario["controller"]
        self.mode = ctl["mode"]
        outer = ctl["outer"]
        self.outer_every = _ms_to_steps(outer["period_ms"], dt, "controller.outer.period_ms")
        law, pi_zero = outer_law(outer["type"], outer["integrator"], outer["pi_zero"])
        self.task = TaskSpaceController(
            mode={"task_space": law, "feedforward": "feedforward"}.get(self.mode, "joint_only"),
            # feedforward: the correction's own K K_I (controller.feedforward.gains)
            gains=ctl["feedforward"]["gains"] if self.mode == "feedforward" else outer["gains"],
            period=self.outer_every * dt,
            geometry=self.geometry,
            clamp=bool(ctl.get("clamp_setpoints", False)),
            inner_dt=dt,
            pi_zero=pi_zero,
            outer_law=law,
            model_tau=ctl["feedforward"]["model_tau_ms"] * 1e-3,
            lag=ctl["feedforward"]["lag"],
            average=bool(ctl["feedforward"]["average"]),
        )
        self.hold_on_saturation = bool(ctl["feedforward"]["hold_on_saturation"])
        inner = ctl["inner"]
        if inner["design_plant"] == "identified":
            acts = ("actuator1", "actuator2", "actuator3")
            plants = [Plant(**inner["identified"][a]) for a in acts]
        else:
            plants = None  # eqs. (34)-(35) in SI under the paper_units reading
        spec = None
        if inner["variant"] == "redesigned":
            spec = {"zeta": inner["zeta"], "wn": inner["wn_rad_s"]}
        self.joint = JointControllers(
            variant=inner["variant"],
            dt=dt,
            method=inner["discretisation"],
            plants=plants,
            spec=spec,
            reading=scenario["paper_units"],
        )
        sf = ctl["setpoint_filter"]
        # Fig. 13's "Filter": q_d (outer loop every T, or the IK every 1 ms in
        # joint-only mode) -> joint references (controllers.setpoint_filter)
        self.setpoint_filter = SetpointFilter(
            sf["type"], dt=dt, time=(np.asarray(sf["time_ms"], float) * 1e-3).tolist()
        )
        act = scenario["actuator"]
        self.actuators = make_actuators(
            act["model"],
            act.get("pneumatics") or {},
            model=m,
            linear_plants=paper_coefficients(scenario["paper_units"]),
        )
        self.rng = np.random.default_rng(int(scenario["seed"]))
        self.sensor_cfg = SensorConfig.from_tree(scenario["sensors"], dt)
        self.sensors = Sensors(self.sensor_cfg, self.rng)

        self.t = np.arange(self.n_steps + 1) * dt
        self.ref = np.ascontiguousarray(reference(scenario, self.t))
        # motion cueing (issue 16): the vehicle side, and the head sensors to log
        self.cueing = bool(scenario["setpoint"].get("cueing"))
        if self.cueing:
            from simpro_mj.config.cueing import vehicle_input

            _, self.veh_f, self.veh_w, _, _ = vehicle_input(scenario)
            if "head_accel" not in self.idx.sensor or "head_gyro" not in self.idx.sensor:
                raise UserInputError(
                    "invalid value at setpoint.cueing: the model has no head_accel/head_gyro "
                    "sensors (simpro_mj/models/simpro_platform.xml)"
                )
        # leg velocity feed-forward (feedforward mode): (a0/b) J dy_d/dt per leg
        self.u_ff = None
        if self.mode == "feedforward" and ctl["feedforward"]["leg_velocity"]:
            from controllers.velocity_feedforward import leg_velocity_feedforward

            ident = ctl["inner"]["identified"]
            legs = [Plant(**ident[a]) for a in ("actuator1", "actuator2", "actuator3")]
            j = self.joint  # clipped to the valve's span around its centre (5 V)
            span = min(j.u_offset - j.u_min, j.u_max - j.u_offset)
            # through a filter like Fig. 13's, as the reference the joint loops follow
            vfilt = SetpointFilter(
                sf["type"], dt=dt, time=(np.asarray(sf["time_ms"], float) * 1e-3).tolist()
            )
            self.u_ff = leg_velocity_feedforward(
                self.ref, dt, legs, self.geometry, span, setpoint_filter=vfilt
            )
        if self.mode == "joint_only":
            # the baseline: q_d = IK(y_d) of the nominal model, every 1 ms
            # (reference() has already clamped the set-points if the scenario asks)
            self.q_joint_only = inverse_kinematics(self.ref, self.geometry, check=False)

    # ------------------------------------------------------------------ setup
    def _initial_state(self) -> None:
        """Start at rest at the first set-point, as the controller believes it.

        The slides are placed where the potentiometers read IK(y_d(0)) (sensor
        offset and gain inverted), the closed chain is assembled, the
        pneumatics start at the static pressures that hold it.
        """
        m, d, idx = self.model, self.data, self.idx
        q_d0 = inverse_kinematics(self.ref[0], self.geometry)
        c = self.sensor_cfg
        q0 = (q_d0 - c.pot_offset_m) / c.pot_gain
        mujoco.mj_resetData(m, d)
        assemble(m, d, q0, index=idx)
        f0 = holding_forces(m, d, idx)
        self.actuators.reset(q0, np.zeros(3), force=f0)
        self.joint.reset()
        self.task.reset(self.ref[0])
        self.setpoint_filter.reset(q_d0.tolist())
        mujoco.mj_forward(m, d)
        self.sensors.reset(d.qpos[idx.slide_qpos], measured_pose(d, idx.site_p))

    # ------------------------------------------------------------------ run
    def run(self, progress=None, *, profile: dict | None = None) -> SimResult:
        """Run the scenario; on divergence or interruption stop and return what was computed.

        Parameters
        ----------
        progress : callable(int), optional
            Called with the number of steps done, every 1000 steps.
        profile : dict, optional
            If given, the loop is instrumented (``time.perf_counter_ns`` around
            each stage, which slows it down) and the wall time per stage is
            written into it, ns summed over the run: ``physics`` (``mj_step1``,
            ``mj_step2``, the warning check), ``sensors`` (reading the MuJoCo
            state and the sensor models), ``controllers`` (task and joint
            loops), ``pneumatics``, ``logging`` (loop-closure error and the log
            row); plus ``steps``. ``simpro-sim bench`` reports it.

        Notes
        -----
        The loop is the hot path of every run (issue 7, ``docs/performance.md``).
        What it moves between the stages are short lists of Python floats:
        for three legs numpy's per-call overhead (0.2-0.7 us) exceeds the
        arithmetic, so the components expose float fast paths
        (``Sensors.sample_floats``, ``JointControllers.update_floats``,
        ``TaskSpaceController.update_floats`` with its single-pose IK
        :class:`~controllers.kinematics.PoseKinematics`,
        :class:`~simpro_mj.plant.model.StateReader`) that do the same IEEE operations
        as their array versions. The MuJoCo views are bound once and read once
        per step (``StateReader.read``; the loop-closure check reuses that
        ``site_xpos`` read); the log is preallocated and each row is packed
        straight into its buffer. With the compiled kernels
        (``SIMPRO_KERNEL``, :mod:`simpro_mj.plant.sensors_kernel`) the read, the
        sensors and the loop-closure maximum are one call,
        :meth:`Sensors.front <simpro_mj.plant.sensors.Sensors.front>`, with the
        same bits.
        """
        self._initial_state()
        m, d, idx = self.model, self.data, self.idx
        dt, n, dec = self.dt, self.n_steps, self.decimation
        n_log = n // dec + 1
        n_col = len(COLUMNS)
        log = np.full((n_log, n_col), np.nan)
        qlog = np.empty((n_log, m.nq))  # copies of qpos at the logged rows
        # cueing runs (issue 16): head specific force and angular velocity (ISO axes).
        # The accelerometer's value after mj_step1 is the one mj_step2 computed for
        # the previous step (1 ms old); the gyro's is current.
        head_on = self.cueing
        if head_on:
            hlog = np.full((n_log, 6), np.nan)
            sd = d.sensordata
            ha, hg = self.idx.sensor["head_accel"], self.idx.sensor["head_gyro"]
        qpos = d.qpos
        # one row = n_col native doubles packed into the (C-contiguous) log buffer
        put_row, row_bytes = struct.Struct(f"{n_col}d").pack_into, 8 * n_col
        reader = StateReader(m, d, idx)
        read, loop_closure = reader.read, reader.loop_closure_max
        # compiled kernel (SIMPRO_KERNEL): read, sensors and loop closure in one call
        front = self.sensors.front(reader)
        fused = front is not None
        xpos, loop = None, 0.0
        ctrl = d.ctrl
        c0, c1, c2 = idx.actuators.tolist()
        warnings = d.warning.number  # live view of the warning counters
        no_warnings = np.zeros_like(warnings)
        step1, step2 = mujoco.mj_step1, mujoco.mj_step2
        task_mode = self.mode == "task_space"
        ff_mode = self.mode == "feedforward"
        u_ff = None if self.u_ff is None else self.u_ff.tolist()
        # feedforward: a valve at its rail during the last outer period holds the correction
        ff_hold, sat_seen = ff_mode and self.hold_on_saturation, False
        u_lo, u_hi = self.joint.u_min, self.joint.u_max
        outer_every = self.outer_every
        ref = self.ref
        q_joint = None if task_mode or ff_mode else self.q_joint_only
        q_d = (self.task.q_desired if q_joint is None else q_joint[0]).tolist()
        pose_cmd = ref[0].tolist()
        act, task = self.actuators, self.task
        act_p1, act_p2 = act.p1, act.p2  # views of the chamber pressures, updated in place
        sample, control, act_step = self.sensors.sample_floats, self.joint.update_floats, act.step
        filt = self.setpoint_filter.update
        # faults (issue 8): event driven, so a run without faults pays one int compare
        sched = (
            FaultSchedule.from_scenario(self.scenario, dt) if self.scenario.get("faults") else None
        )
        next_ev = sched.next_event if sched is not None else NEVER
        valve_on = sensor_on = False
        flags, supply_pa = 0, float(act.params.p_supply)
        timed = profile is not None
        clock = time.perf_counter_ns
        t_phys = t_sens = t_ctl = t_pn = t_log = 0
        ta = tb = 0
        status, reason = "ok", None
        worst_loop = 0.0
        row = 0
        wall0 = time.perf_counter()
        k = 0
        try:
            for k in range(n + 1):
                if timed:
                    ta = clock()
                step1(m, d)
                if timed:
                    tb = clock()
                    t_phys += tb - ta
                if fused:
                    q_true, qdot, pose, q_meas, pose_meas, loop = front(k)
                else:
                    q_true, qdot, pose, xpos = read()
                    q_meas, pose_meas = sample(k, q_true, pose)
                if k == next_ev:  # a fault starts or ends at this step
                    ch = sched.at_event(k)
                    if ch.supply_pa is not None:
                        act.set_supply_pressure(ch.supply_pa)
                        supply_pa = ch.supply_pa
                    valve_on, sensor_on = sched.valve_active, sched.sensor_active
                    flags, next_ev = sched.flags, sched.next_event
                if sensor_on:  # what the controllers see; the sensors' state is untouched
                    q_meas, pose_meas = sched.apply_sensors(k, q_meas, pose_meas)
                if timed:
                    ta = clock()
                    t_sens += ta - tb
                if task_mode:
                    if k % outer_every == 0:
                        q_d = task.update_floats(ref[k].tolist(), pose_meas)
                        pose_cmd = task.pose_command.tolist()
                elif ff_mode:  # IK(y_d + c) every step, c integrated at the outer steps
                    if k % outer_every == 0:
                        q_d = task.update_floats(ref[k].tolist(), pose_meas, sat_seen, q_meas)
                        sat_seen = False
                    else:
                        q_d = task.feedforward_floats(ref[k].tolist(), pose_meas, q_meas)
                    pose_cmd = task.pose_command.tolist()
                else:
                    q_d = q_joint[k].tolist()
                    pose_cmd = ref[k].tolist()
                q_r = filt(q_d)
                u = control(q_r, q_meas) if u_ff is None else control(q_r, q_meas, u_ff[k])
                if ff_hold and not sat_seen:
                    u0, u1, u2 = u
                    sat_seen = not (u_lo < u0 < u_hi and u_lo < u1 < u_hi and u_lo < u2 < u_hi)
                if valve_on:  # the controller keeps its own command in its state
                    u = sched.apply_valves(u)
                if timed:
                    tb = clock()
                    t_ctl += tb - ta
                f = act_step(u, q_true, qdot, dt)
                f0, f1, f2 = f.tolist()
                if timed:
                    ta = clock()
                    t_pn += ta - tb
                if k % dec == 0:
                    if not fused:
                        loop = loop_closure(xpos)
                    if loop > worst_loop:  # max(worst_loop, loop) without the call
                        worst_loop = loop
                    p1, p2 = act_p1.tolist(), act_p2.tolist()
                    put_row(
                        log, row * row_bytes,
                        k * dt, *ref[k].tolist(), *pose, *pose_meas, *pose_cmd, *q_r,
                        *q_true, *q_meas, *u, f0, f1, f2,
                        p1[0], p2[0], p1[1], p2[1], p1[2], p2[2], loop, flags, supply_pa,
                    )  # fmt: skip
                    qlog[row] = qpos
                    if head_on:
                        hlog[row, :3] = sd[ha]
                        hlog[row, 3:] = sd[hg]
                    row += 1
                    if loop > LOOP_OPEN_BOUND:
                        check_physics(m, d, loop_bound=LOOP_OPEN_BOUND, index=idx)  # raises
                if timed:
                    tb = clock()
                    t_log += tb - ta
                if k == n:
                    break
                if not math.isfinite(f0 + f1 + f2):
                    raise PhysicsError(
                        f"non-finite actuator force {f} at t = {k * dt:.3f} s "
                        f"(pressures {act.p1}, {act.p2})"
                    )
                ctrl[c0], ctrl[c1], ctrl[c2] = f0, f1, f2
                step2(m, d)
                if any(warnings.tolist()):
                    check_physics(m, d, no_warnings, index=idx)  # raises, naming the warning
                if timed:
                    t_phys += clock() - tb
                if progress is not None and k % 1000 == 0:
                    progress(k)
        except PhysicsError as exc:
            status, reason = "diverged", str(exc)
        except KeyboardInterrupt:
            # SIGINT, or SIGTERM turned into KeyboardInterrupt by the CLI: keep
            # what was computed so the caller can still write it
            status = "interrupted"
            reason = f"interrupted by signal (SIGINT/SIGTERM) at t = {k * dt:.3f} s"
        wall = time.perf_counter() - wall0
        if timed:
            profile.update(
                physics=t_phys, sensors=t_sens, controllers=t_ctl, pneumatics=t_pn,
                logging=t_log, steps=k + 1,
            )  # fmt: skip
        log = log[:row]
        columns = {name: log[:, j].copy() for j, name in enumerate(COLUMNS)}
        if self.cueing:
            from simpro_mj.config.cueing import CUE_COLUMNS

            rows = np.arange(row) * dec
            if row > 1:  # at t = 0 the accelerometer holds mj_forward's value with no
                hlog[0] = hlog[1]  # pneumatic force yet: the first row repeats the second
            veh = np.hstack([self.veh_f[rows], self.veh_w[rows], hlog[:row]])
            for j, name in enumerate(CUE_COLUMNS):
                columns[name] = veh[:, j].copy()
        steps = k
        return SimResult(
            columns=columns,
            status=status,
            reason=reason,
            sim={
                "steps": int(steps),
                "timestep_s": dt,
                "simulated_s": float(steps * dt),
                "max_loop_closure_error_m": float(worst_loop),
                "wall_s": wall,
                "realtime_factor": float(steps * dt / wall) if wall > 0 else None,
            },
            scenario=self.scenario,
            sensor_floor=self.sensors.resolution_floor(),
            qpos=qlog[:row].copy(),
            qpos_names=qpos_names(m),
        )


def qpos_names(model: mujoco.MjModel) -> tuple:
    """Name of the joint of each ``qpos`` entry (the model has only 1-DOF joints)."""
    names = []
    for j in range(model.njnt):
        width = {0: 7, 1: 4}.get(int(model.jnt_type[j]), 1)  # free, ball, slide/hinge
        name = model.joint(j).name
        names += [name] if width == 1 else [f"{name}[{i}]" for i in range(width)]
    return tuple(names)


def simulate(scenario: dict, progress=None) -> SimResult:
    """Build and run a scenario (convenience)."""
    return CoSimulation(scenario).run(progress)
