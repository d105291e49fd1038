"""The multi-rate co-simulation loop (replaces Simulink + ADAMS, paper Fig. 13).

One physics step of ``dt`` = 1 ms, stage by stage (:mod:`simpro_mj.sim.stages`)::

    step1             mj_step1: kinematics and sensors at the state of t_k
    sense             potentiometers, height encoder, IMU (own rates, ZOH)
    control           outer loop every ``period_ms``: task error -> integrated pose
                      -> IK -> q_d (feedforward mode: q_d = IK(y_d + c) every step,
                      the correction c integrated every ``period_ms``); the
                      set-point filter; joint loops q_r, q_meas -> valve voltages
    actuate           pneumatics: voltages, q, q_dot -> chamber pressures -> slide forces
    record            one log row every ``logging.decimation`` steps
    step2             mj_step2: integrate to t_{k+1} with those forces held

The plant is one object (:class:`~simpro_mj.plant.platform.Platform`,
dm_control's ``Physics``): ``step1``, ``front(k)`` (the state and the
sensors, compiled or Python, one contract), ``step2(forces)`` (raising
``PhysicsError`` from MuJoCo's warnings). The controllers are built here from
their public classes; the body of :meth:`CoSimulation.run` only calls stages.

In joint-only mode (the baseline) q_d(t) = IK(y_d(t)) of the nominal model,
computed for the whole run at once.

Set-points from outside (the live interface)
--------------------------------------------
A run normally computes its set-points from the scenario before it steps.
``CoSimulation(scenario, setpoints="external")`` instead starts every row
of the set-point buffer at the neutral pose (home; for a cueing scenario the
vehicle at rest) and lets a driver fill it while the loop runs, through two
things only (:mod:`simpro_mj.sim.live` is that driver):

* :meth:`CoSimulation.write_setpoints` ``(k, poses, f, w)`` writes rows
  ``k, k + 1, ...`` of the set-point buffer (and of the vehicle input logged
  beside it), in place;
* ``run(pace=...)``: ``pace(k, log) -> next_k`` is called before step ``k``
  is taken, first at ``k = 0`` and then at each step it returns, with the
  rows logged so far (``log``, a view of the :data:`COLUMNS` rows: read it only).
  Between two calls the loop steps without looking outside; the caller
  writes the rows its next chunk reads, waits for the wall clock, sends the
  pose. It ends the run early by raising ``KeyboardInterrupt`` (as a signal
  does).
"""

from __future__ import annotations

import sys
import time

import mujoco
import numpy as np

from controllers.design import Plant, paper_coefficients
from controllers.frames import GRAVITY
from controllers.geometry import nominal_geometry
from controllers.joint import JointControllers
from controllers.kinematics import inverse_kinematics
from controllers.setpoint_filter import SetpointFilter
from controllers.task_space import TaskSpaceController, outer_law
from controllers.velocity_feedforward import leg_velocity_feedforward
from simpro_mj.config.scenario import reference
from simpro_mj.core.errors import PhysicsError, UserInputError
from simpro_mj.core.rates import steps_per_period
from simpro_mj.identification.auto import with_identified
from simpro_mj.plant.faults import NEVER, FaultSchedule
from simpro_mj.plant.model import PlantIndex, load_model
from simpro_mj.plant.platform import Platform
from simpro_mj.plant.pneumatics.factory import make_actuators
from simpro_mj.plant.sensors import SensorConfig, Sensors
from simpro_mj.sim.result import COLUMNS, SimResult, qpos_names
from simpro_mj.sim.stages import FaultStages, Profile, Recorder, control_stage

__all__ = ["LOOP_OPEN_BOUND", "CoSimulation", "simulate"]

#: Divergence bound on the loop-closure error (m): far above the 0.5 mm of
#: normal motion, well below anything physical.
LOOP_OPEN_BOUND = 5e-3


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
    setpoints : {"scenario", "external"}
        ``scenario``: the set-points (and a cueing scenario's vehicle input)
        computed from the scenario for the whole run. ``external``: every row
        starts at the neutral pose and the vehicle at rest, to be written
        while the run goes (:meth:`write_setpoints`, ``run(pace=...)``).
    poses : ndarray, (n + 1, 3), optional
        With ``setpoints="scenario"``: the set-point poses on this run's 1 ms
        grid (:func:`reference`), when the caller has them; evaluated here when
        omitted.
    identified_source : str, optional
        Given when ``scenario`` already carries its design plants
        (:func:`~simpro_mj.identification.auto.with_identified` ran, as
        :class:`simpro_mj.job.run.Run` does); resolved here when omitted.
    """

    def __init__(self, scenario: dict, model: mujoco.MjModel | None = None, *,
                 setpoints: str = "scenario", poses: np.ndarray | None = None,
                 identified_source: str | None = None):  # fmt: skip
        if setpoints not in ("scenario", "external"):
            raise ValueError(f"setpoints={setpoints!r}; allowed: 'scenario' or 'external'")
        external = setpoints == "external"
        if identified_source is None:
            # design_plant identified: the scenario's own plant's models (cached)
            scenario, identified_source = with_identified(scenario, _say)
        self.identified_source = identified_source
        self.scenario = scenario
        m = load_model(scenario["plant"]) if model is None else model
        self.model, self.idx = m, PlantIndex.of(m)
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
        self.outer_every = steps_per_period(outer["period_ms"], dt, "controller.outer.period_ms")
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
        # the plant as the loop sees it (dm_control's Physics): step1 / front / step2
        self.platform = Platform(m, self.actuators, self.sensors, self.idx)
        self.data = self.platform.data

        self.t = np.arange(self.n_steps + 1) * dt
        if external:  # the neutral pose until write_setpoints says otherwise
            self.ref = np.tile(np.asarray(self.geometry.home, float), (self.n_steps + 1, 1))
        else:
            if poses is None:
                poses = reference(scenario, self.t)
            self.ref = np.ascontiguousarray(poses)
        # motion cueing: the vehicle side, and the head sensors to log
        self.cueing = bool(scenario["setpoint"].get("cueing"))
        if self.cueing and external:  # the vehicle at rest: f = (0, 0, g), w = 0
            self.veh_f = np.zeros((self.n_steps + 1, 3))
            self.veh_f[:, 2] = GRAVITY
            self.veh_w = np.zeros((self.n_steps + 1, 3))
        elif self.cueing:
            # on use: config.cueing loads scipy's filter design (seconds under load),
            # which no other run needs
            from simpro_mj.config.cueing import vehicle_input

            _, self.veh_f, self.veh_w, _, _ = vehicle_input(scenario)
            if "head_accel" not in self.idx.sensor or "head_gyro" not in self.idx.sensor:
                raise UserInputError(
                    "invalid value at setpoint.cueing: the model has no head_accel/head_gyro "
                    "sensors (models/simpro_platform.xml)"
                )
        # leg velocity feed-forward (feedforward mode): (a0/b) J dy_d/dt per leg
        self.u_ff = None  # (n + 1, 3) volts
        if self.mode == "feedforward" and ctl["feedforward"]["leg_velocity"]:
            if external:  # it differentiates the whole set-point in advance
                raise UserInputError(
                    "invalid value at controller.feedforward.leg_velocity: true needs the "
                    "set-points in advance; allowed: false with set-points from outside (live)"
                )
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
        self.q_joint_only = None
        if self.mode == "joint_only":
            # the baseline: q_d = IK(y_d) of the nominal model, every 1 ms
            # (reference() has already clamped the set-points if the scenario asks)
            self.q_joint_only = inverse_kinematics(self.ref, self.geometry, check=False)

    # ------------------------------------------------------------------ live
    def write_setpoints(self, k: int, poses, f=None, w=None) -> None:
        """Write rows ``k, k + 1, ...`` of the set-point buffer, in place.

        Parameters
        ----------
        k : int
            The first step written; rows past the run's last step are dropped.
        poses : array_like, (m, 3) or (3,)
            Set-point poses (roll rad, pitch rad, heave m absolute), base frame.
            In joint-only mode their IK is written too.
        f, w : array_like, (m, 3) or (3,), optional
            A cueing run's vehicle input at those rows (V frame, SI): only
            logged (the ``veh_*`` columns), the set-points already follow from it.
        """
        poses = np.atleast_2d(np.asarray(poses, float))
        rows = slice(k, min(k + poses.shape[0], self.n_steps + 1))
        m = rows.stop - rows.start
        if m <= 0:
            return
        self.ref[rows] = poses[:m]
        if self.q_joint_only is not None:
            self.q_joint_only[rows] = inverse_kinematics(poses[:m], self.geometry, check=False)
        if self.cueing:
            if f is not None:
                self.veh_f[rows] = np.atleast_2d(np.asarray(f, float))[:m]
            if w is not None:
                self.veh_w[rows] = np.atleast_2d(np.asarray(w, float))[:m]

    # ------------------------------------------------------------------ setup
    def _initial_state(self) -> None:
        """Start at rest at the first set-point, as the controller believes it.

        The slides are placed where the potentiometers read IK(y_d(0)) (sensor
        offset and gain inverted), the closed chain is assembled, the
        pneumatics start at the static pressures that hold it.
        """
        q_d0 = inverse_kinematics(self.ref[0], self.geometry)
        c = self.sensor_cfg
        self.platform.reset((q_d0 - c.pot_offset_m) / c.pot_gain)
        self.joint.reset()
        self.task.reset(self.ref[0])
        self.setpoint_filter.reset(q_d0.tolist())

    # ------------------------------------------------------------------ run
    def run(self, progress=None, *, profile: dict | None = None, pace=None) -> SimResult:
        """Run the scenario; on divergence or interruption stop and return what was computed.

        Parameters
        ----------
        progress : callable(int), optional
            Called with the number of steps done, every 1000 steps.
        profile : dict, optional
            If given, every stage is wrapped in ``time.perf_counter_ns``
            (:class:`~simpro_mj.sim.stages.Profile`, which slows it down) and
            the wall time per stage is written into it, ns summed over the
            run: ``physics`` (``mj_step1``, ``mj_step2``, the warning check),
            ``sensors`` (reading the MuJoCo state and the sensor models, the
            sensor faults), ``controllers`` (task and joint loops, stuck
            valves), ``pneumatics``, ``logging`` (the log row); plus
            ``steps``. ``simpro-sim bench`` reports it.
        pace : callable(int, ndarray) -> int, optional
            The live interface (module docstring): called before step ``k``,
            first at 0, then at each step it returns, with the rows logged so far.

        Notes
        -----
        The loop is the hot path of every run (``docs/performance.md``).
        What it moves between the stages are short lists of Python floats:
        for three legs numpy's per-call overhead (0.2-0.7 us) exceeds the
        arithmetic, so the components expose float fast paths
        (``Sensors.front``, ``JointControllers.update_floats``,
        ``TaskSpaceController.update_floats`` with its single-pose IK
        :class:`~controllers.kinematics.PoseKinematics`) that do the same
        IEEE operations as their array versions. The body below only calls
        the stages (:mod:`simpro_mj.sim.stages`): what differs between runs
        (controller mode, faults, profiling) is which stage functions it
        holds, not tests in the body.
        """
        self._initial_state()
        plat, dt, n, dec = self.platform, self.dt, self.n_steps, self.decimation
        rec = Recorder(n // dec + 1, len(COLUMNS), self.model.nq, self.cueing,
                       self.actuators.params.p_supply)  # fmt: skip
        head = None
        if self.cueing:
            head = self.idx.sensor["head_accel"], self.idx.sensor["head_gyro"]
        timer = Profile() if profile is not None else None
        wrap = timer.wrap if timer is not None else (lambda fn, stage: fn)
        sense, control = plat.front, self._control_stage()
        faults = None
        if self.scenario.get("faults"):  # event driven: without faults one int compare a step
            sched = FaultSchedule.from_scenario(self.scenario, dt)
            faults = FaultStages(sched, self.actuators, rec, sense, control, wrap)
        next_ev = faults.next_event if faults is not None else NEVER
        next_pace = 0 if pace is not None else NEVER
        step1, step2 = wrap(plat.step1, "physics"), wrap(plat.step2, "physics")
        sense, control = wrap(sense, "sensors"), wrap(control, "controllers")
        actuate = wrap(self.actuators.step, "pneumatics")
        record = wrap(rec.writer(self.ref, dt, plat, LOOP_OPEN_BOUND, head), "logging")
        status, reason = "ok", None
        wall0 = time.perf_counter()
        k = 0
        try:
            for k in range(n + 1):
                if k == next_ev:  # a fault starts or ends: it swaps the stages it acts on
                    sense, control, next_ev = faults.at(k)
                if k == next_pace:  # the live driver: set-points in, wall clock, pose out
                    next_pace = pace(k, rec.log[: rec.rows])
                step1()
                q, qd, pose, q_meas, pose_meas, loop = sense(k)
                q_r, u, pose_cmd = control(k, pose_meas, q_meas)
                f = actuate(u, q, qd, dt).tolist()
                if k % dec == 0:
                    record(k, pose, pose_meas, pose_cmd, q_r, q, q_meas, u, f, loop)
                if k == n:
                    break
                step2(f)
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
        if timer is not None:
            profile.update(timer.ns, steps=k + 1)
        return self._result(rec, k, status, reason, wall)

    def _control_stage(self):
        """The controllers' stage for this scenario's mode (:func:`~.stages.control_stage`)."""
        return control_stage(
            self.mode,
            task=self.task,
            joint=self.joint,
            setpoint_filter=self.setpoint_filter,
            ref=self.ref,
            outer_every=self.outer_every,
            q_joint=self.q_joint_only,
            u_ff=None if self.u_ff is None else self.u_ff.tolist(),
            hold_on_saturation=self.mode == "feedforward" and self.hold_on_saturation,
        )

    def _result(self, rec: Recorder, steps: int, status: str, reason, wall: float) -> SimResult:
        """The log as columns (copies), the cueing columns, the run's figures."""
        row, dt = rec.rows, self.dt
        log = rec.log[:row]
        columns = {name: log[:, j].copy() for j, name in enumerate(COLUMNS)}
        if self.cueing:
            from simpro_mj.config.cueing import CUE_COLUMNS  # on use, see __init__

            rows = np.arange(row) * self.decimation
            hlog = rec.hlog
            if row > 1:  # at t = 0 the accelerometer holds mj_forward's value with no
                hlog[0] = hlog[1]  # pneumatic force yet: the first row repeats the second
            veh = np.hstack([self.veh_f[rows], self.veh_w[rows], hlog[:row]])
            for j, name in enumerate(CUE_COLUMNS):
                columns[name] = veh[:, j].copy()
        return SimResult(
            columns=columns,
            status=status,
            reason=reason,
            sim={
                "steps": int(steps),
                "timestep_s": dt,
                "simulated_s": float(steps * dt),
                "max_loop_closure_error_m": float(rec.worst_loop),
                "wall_s": wall,
                "realtime_factor": float(steps * dt / wall) if wall > 0 else None,
            },
            scenario=self.scenario,
            sensor_floor=self.sensors.resolution_floor(),
            qpos=rec.qlog[:row].copy(),
            qpos_names=qpos_names(self.model),
        )


def simulate(scenario: dict, progress=None) -> SimResult:
    """Build and run a scenario (convenience)."""
    return CoSimulation(scenario).run(progress)
