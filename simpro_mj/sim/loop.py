"""The multi-rate co-simulation loop (replaces Simulink + ADAMS, paper Fig. 13).

:class:`CoSimulation` builds a scenario's plant (one object,
:class:`~simpro_mj.plant.platform.Platform`, dm_control's ``Physics``), sensors
and controllers from their public classes, whose numbers and states the
step's arrays take (:func:`simpro_mj.sim.step.build`), and runs the 1 ms
step of :mod:`simpro_mj.sim.step` (its stages are listed there; the outer
loop every ``period_ms``). Compiled (numba, the default), the stages run
inside ``mj_step`` as MuJoCo's control callback and Python steps chunks of
:data:`~simpro_mj.sim.stages.CHUNK` steps, checking the run between them;
interpreted (``SIMPRO_KERNEL=python``), with faults or profiling, Python
calls ``mj_step1``, the stages and ``mj_step2`` every step.

In joint-only mode (the baseline) q_d(t) = IK(y_d(t)) of the nominal model,
computed for the whole run at once.

Set-points from outside (the live interface)
--------------------------------------------
A co-simulation with ``setpoints="external"`` (``Build(scenario,
setpoints="external").simulation()``, :mod:`simpro_mj.sim.build`) starts every row of the
set-point buffer at the neutral pose (home; for a cueing scenario the
vehicle at rest) and lets a driver (:mod:`simpro_mj.sim.live`) fill it while
the loop runs, through :meth:`CoSimulation.write_setpoints` and
``run(pace=...)`` only. Between two calls of ``pace`` the loop steps without
looking outside; the caller writes the rows its next chunk reads, waits for
the wall clock, sends the pose, and ends the run early by raising
``KeyboardInterrupt`` (as a signal does). :meth:`CoSimulation.snapshot` and
:meth:`CoSimulation.restore` stop and resume a run bit for bit.
"""

from __future__ import annotations

import copy
import functools
import threading
import time
from collections.abc import Mapping

import mujoco
import numpy as np

from controllers.design import paper_coefficients
from controllers.dither import dither_signal
from controllers.frames import GRAVITY
from controllers.joint import JointControllers
from controllers.kinematics import inverse_kinematics
from controllers.setpoint_filter import SetpointFilter
from controllers.task_space import TaskSpaceController, outer_law, raise_step_error
from controllers.velocity_feedforward import leg_velocity_feedforward
from simpro_mj.config.models import Scenario, as_scenario
from simpro_mj.core.errors import PhysicsError, UserInputError
from simpro_mj.core.rates import steps_per_period
from simpro_mj.plant.faults import NEVER, FaultSchedule
from simpro_mj.plant.kernels import kernel_choice
from simpro_mj.plant.model import PlantIndex, check_physics
from simpro_mj.plant.platform import Platform
from simpro_mj.plant.pneumatics.factory import make_actuators
from simpro_mj.plant.sensors import SensorConfig
from simpro_mj.sim import step
from simpro_mj.sim.compiling import prepare_step
from simpro_mj.sim.registration import Registration
from simpro_mj.sim.result import COLUMNS, SimResult, qpos_names
from simpro_mj.sim.snapshot import Snapshot, model_digest, put_back, take
from simpro_mj.sim.stages import CHUNK, FaultHooks, Log, NoiseBlock, Profile

#: Divergence bound on the loop-closure error (m): far above the 0.5 mm of
#: normal motion, well below anything physical.
LOOP_OPEN_BOUND = 5e-3


class CoSimulation:
    """A scenario's plant, sensors and controllers, ready to run.

    Parameters
    ----------
    scenario : Scenario or mapping
        A resolved scenario (:func:`simpro_mj.config.scenario.load_scenario`), typed
        or its dict (recorded with the result).
    model : mujoco.MjModel
        The compiled plant of the scenario's ``plant``.
    setpoints : {"scenario", "external"}
        ``scenario``: the set-points (and a cueing scenario's vehicle input)
        computed from the scenario for the whole run. ``external``: every row
        starts at the neutral pose and the vehicle at rest, to be written
        while the run goes (:meth:`write_setpoints`, ``run(pace=...)``).
    poses : ndarray, (n + 1, 3) or None
        With ``setpoints="scenario"``: the set-point poses on this run's 1 ms
        grid (:func:`~simpro_mj.config.reference.reference`).
    identified_source : str
        Where ``scenario``'s design plants came from.

    :class:`~simpro_mj.sim.build.Build` makes each of these once and is the
    one maker of a co-simulation.
    """

    def __init__(
        self,
        scenario: Scenario | Mapping,
        model: mujoco.MjModel,
        *,
        setpoints: str = "scenario",
        poses: np.ndarray | None = None,
        identified_source: str,
    ):
        self.external = external = setpoints == "external"
        self._resume: int | None = None
        self.identified_source = identified_source
        #: the typed scenario
        self.spec = sc = as_scenario(scenario)
        #: the resolved scenario as a dict: what the result records
        self.scenario = scenario if isinstance(scenario, dict) else sc.model_dump()
        m = model
        self.model, self.idx = m, PlantIndex.of(m)
        self.dt = dt = float(m.opt.timestep)
        self.n_steps = int(round(sc.duration_s / dt))
        self.decimation = sc.logging.decimation
        # the controller's nominal model: the rig's (plant.rig; the paper's when null),
        # without the plant's as-built errors
        self.geometry = sc.plant.geometry()

        ctl = sc.controller
        self.mode = ctl.mode
        outer, ff, inner = ctl.outer, ctl.feedforward, ctl.inner
        self.outer_every = steps_per_period(outer.period_ms, dt, "controller.outer.period_ms")
        law, pi_zero = outer_law(outer.type, outer.integrator, outer.pi_zero)
        db = outer.dead_band  # degrees and millimetres at the edge
        band = [np.radians(db.roll_deg), np.radians(db.pitch_deg), db.heave_mm * 1e-3]
        self.task = TaskSpaceController(
            mode={"task_space": law, "feedforward": "feedforward"}.get(self.mode, "joint_only"),
            # feedforward: the correction's own K K_I (controller.feedforward.gains)
            gains=ff.gains if self.mode == "feedforward" else outer.gains,
            period=self.outer_every * dt,
            geometry=self.geometry,
            clamp=ctl.clamp_setpoints,
            inner_dt=dt,
            pi_zero=pi_zero,
            outer_law=law,
            model_tau=ff.model_tau_ms * 1e-3,
            lag=ff.lag,
            average=ff.average,
            dead_band=band,
            band_kind=outer.dead_band.kind,
            band_release=outer.dead_band.release,
            joint_lag=outer.joint_lag,
            joint_band=np.asarray(inner.dead_band_mm) * 1e-3,
        )
        self.hold_on_saturation = ff.hold_on_saturation
        identified = inner.identified.plants()
        # design_plant paper: eqs. (34)-(35) in SI under the paper_units reading
        plants = identified if inner.design_plant == "identified" else None
        spec = {"zeta": inner.zeta, "wn": inner.wn_rad_s} if inner.variant == "redesigned" else None
        self.joint = JointControllers(
            variant=inner.variant,
            dt=dt,
            method=inner.discretisation,
            plants=plants,
            spec=spec,
            reading=sc.paper_units,
            dead_band=[w * 1e-3 for w in inner.dead_band_mm],
            dead_band_release=inner.dead_band_release,
            anti_windup=inner.anti_windup,
            tracking_time=inner.tracking_time_ms * 1e-3,
        )
        sf = ctl.setpoint_filter
        # Fig. 13's "Filter": q_d (outer loop every T, or the IK every 1 ms in
        # joint-only mode) -> joint references (controllers.setpoint_filter)
        self.setpoint_filter = SetpointFilter(sf.type, dt=dt, time=[t * 1e-3 for t in sf.time_ms])
        self.actuators = make_actuators(
            sc.actuator.model,
            sc.actuator.pneumatics,  # the plant's typed block, validated once
            model=m,
            linear_plants=paper_coefficients(sc.paper_units),
        )
        self.rng = np.random.default_rng(sc.seed)
        self.sensor_cfg = SensorConfig.from_tree(sc.sensors.model_dump(), dt)
        # the IMU bias's random walk draws from a generator of its own
        self.walk_rng = self.rng.spawn(1)[0] if self.sensor_cfg.imu_walk_rad > 0 else None
        # the plant as the loop sees it (dm_control's Physics)
        self.platform = Platform(m, self.actuators, self.idx)
        self.data = self.platform.data

        self.t = np.arange(self.n_steps + 1) * dt
        if external:  # the neutral pose until write_setpoints says otherwise
            self.ref = np.tile(np.asarray(self.geometry.home, float), (self.n_steps + 1, 1))
        else:  # Build checked setpoints and made the poses
            self.ref = np.ascontiguousarray(poses)
        # motion cueing: the vehicle side, and the head sensors to log
        self.cueing = sc.setpoint.cueing is not None
        self.veh_f = self.veh_w = None
        if self.cueing and external:  # the vehicle at rest: f = (0, 0, g), w = 0
            self.veh_f = np.tile([0.0, 0.0, GRAVITY], (self.n_steps + 1, 1))
            self.veh_w = np.zeros_like(self.veh_f)
        elif self.cueing:
            # on use: config.cueing loads scipy's filter design (seconds under load),
            # which no other run needs
            from simpro_mj.config.cueing import vehicle_input

            _, self.veh_f, self.veh_w, _, _ = vehicle_input(self.spec)
            if "head_accel" not in self.idx.sensor or "head_gyro" not in self.idx.sensor:
                raise UserInputError(
                    "invalid value at setpoint.cueing: the model has no head_accel/head_gyro "
                    "sensors (models/simpro_platform.xml)"
                )
        # leg velocity feed-forward (feedforward mode): (a0/b) J dy_d/dt per leg
        self.u_ff = None  # (n + 1, 3) volts
        if self.mode == "feedforward" and ff.leg_velocity:
            if external:  # it differentiates the whole set-point in advance
                raise UserInputError(
                    "invalid value at controller.feedforward.leg_velocity: true needs the "
                    "set-points in advance; allowed: false with set-points from outside (live)"
                )
            j = self.joint  # clipped to the valve's span around its centre (5 V)
            span = min(j.u_offset - j.u_min, j.u_max - j.u_offset)
            # through a filter like Fig. 13's, as the reference the joint loops follow
            vfilt = copy.deepcopy(self.setpoint_filter)  # not yet started
            self.u_ff = leg_velocity_feedforward(
                self.ref, dt, identified, self.geometry, span, setpoint_filter=vfilt
            )
        if inner.dither_v > 0.0:  # added to the joint loops' output like the feed-forward
            wave = dither_signal(
                self.n_steps + 1, dt, inner.dither_v, inner.dither_period_ms * 1e-3
            )
            self.u_ff = wave if self.u_ff is None else self.u_ff + wave
        self.q_joint_only = None
        if self.mode == "joint_only":
            # the baseline: q_d = IK(y_d) of the nominal model, every 1 ms
            # (reference() has already clamped the set-points if the scenario asks)
            self.q_joint_only = inverse_kinematics(self.ref, self.geometry, check=False)

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
        for name, v in (("veh_f", f), ("veh_w", w)):
            if self.cueing and v is not None:
                getattr(self, name)[rows] = np.atleast_2d(np.asarray(v, float))[:m]

    def snapshot(self) -> Snapshot:
        """The run as it stands before step ``k``, to resume exactly (:meth:`restore`;
        :func:`simpro_mj.sim.snapshot.take`)."""
        return take(self)

    def restore(self, snap: Snapshot) -> None:
        """Put the run back where :meth:`snapshot` took it; the next :meth:`run` goes on
        from there (:func:`simpro_mj.sim.snapshot.put_back`)."""
        put_back(self, snap)

    @functools.cached_property
    def _model_digest(self) -> str:
        return model_digest(self.model)

    def _initial_state(self) -> None:
        """Start at rest at the first set-point, as the controller believes it.

        The slides are placed where the potentiometers read IK(y_d(0)) (sensor
        offset and gain inverted), the closed chain is assembled, the
        pneumatics start at the static pressures that hold it; the step's
        buffers (:mod:`simpro_mj.sim.step`) are filled and the sensors take a
        first reading.
        """
        q_d0 = inverse_kinematics(self.ref[0], self.geometry)
        c = self.sensor_cfg
        self.platform.reset((q_d0 - c.pot_offset_m) / c.pot_gain)
        self.joint.reset()
        self.task.reset(self.ref[0])
        self.setpoint_filter.reset(q_d0.tolist())
        self.noise = NoiseBlock(self.rng)
        self.walk = NoiseBlock(self.walk_rng, width=2)
        self.S, self.C = step.build(self, LOOP_OPEN_BOUND, self.noise.rows[0], self.walk.rows[0])
        self._log = Log(self.n_steps // self.decimation + 1, self.model.nq, self.cueing)

    def run(
        self,
        progress=None,
        *,
        profile: dict | None = None,
        pace=None,
        stop: threading.Event | None = None,
    ) -> SimResult:
        """Run the scenario; on divergence or interruption stop and return what was computed.

        Parameters
        ----------
        progress : callable(int), optional
            Called with the number of steps done, every 1000 steps.
        profile : dict, optional
            If given, the step runs stage by stage from Python with
            ``time.perf_counter_ns`` around each (:class:`~simpro_mj.sim.stages.Profile`,
            which slows it down) and the wall time per stage is written into
            it, ns summed over the run: ``physics`` (``mj_step1``,
            ``mj_step2``), ``sensors``, ``controllers`` (with the faults' hooks),
            ``pneumatics``, ``logging``; plus ``steps``.
        pace : callable(int, ndarray) -> int, optional
            The live interface (module docstring): ``pace(k, log)`` is called
            before step ``k``, first at 0, then at each step it returns; ``log``
            is a view of the rows logged so far (read it only). After
            :meth:`restore`, the run goes on from the snapshot's step.
        stop : threading.Event, optional
            This run's stop token: once set, the run ends between two chunks of
            steps as ``interrupted`` with what it logged, as a signal ends it (how
            runs on threads other than the main one, which alone receives
            signals, are stopped: :func:`simpro_mj.sim.executors.run_threads`).
            Other runs in the process hold their own.
        """
        k0, self._resume = self._resume, None
        if k0 is None:
            self._initial_state()
            k0 = 0
        log = self._log
        faults = None
        if self.spec.faults:
            faults = FaultSchedule(self.spec, self.dt)
        kernel = kernel_choice()
        timer = Profile() if profile is not None else None
        status, reason = "ok", None
        prepare_step()  # a compile (or the cache's load) is not the simulation's wall time
        wall0 = time.perf_counter()
        k = 0
        try:
            if kernel == "numba" and faults is None and profile is None:
                ref, qj, uff = self._inputs()
                with Registration(self.data, self.S, self.C, ref, qj, uff, self.noise.rows,
                                  self.walk.rows, log.log, log.qlog, log.hlog):  # fmt: skip
                    k = self._chunks(self._callback_steps(), log, pace, progress, k0, stop)
            else:
                stages = step.compiled() if kernel == "numba" else step
                advance = self._python_steps(stages, faults, timer)
                k = self._chunks(advance, log, pace, progress, k0, stop)
        except PhysicsError as exc:
            status, reason = "diverged", str(exc)
            k = self._k
        except KeyboardInterrupt as exc:
            # SIGINT, or SIGTERM/SIGHUP turned into KeyboardInterrupt by the CLI: keep
            # what was computed so the caller can still write it (a compiled chunk
            # may have run past the step Python last saw: S[ST.k] is the next step)
            k = max(self._k, int(self.S[step.ST.k]) - 1)
            status = "interrupted"
            which = str(exc).removeprefix("signal ") or "SIGINT"
            reason = f"interrupted by signal ({which}) at t = {k * self.dt:.3f} s"
        finally:
            if timer is not None and profile is not None:
                profile.update(timer.ns, steps=self._k + 1)
        wall = time.perf_counter() - wall0
        return self._result(log, k, status, reason, wall)

    def _inputs(self):
        """The set-point arrays the stages read: poses, joint-only q_d, feed-forward volts."""
        unused = np.zeros_like(self.ref)
        qj = self.q_joint_only if self.q_joint_only is not None else unused
        uff = self.u_ff if self.u_ff is not None else unused
        return self.ref, np.ascontiguousarray(qj), np.ascontiguousarray(uff)

    def _chunks(self, advance, log, pace, progress, k0: int, token=None) -> int:
        """Steps ``k0 .. n`` by ``advance(k, stop)`` in chunks of at most :data:`CHUNK`.

        A chunk ends at the next step ``pace`` asked for; between two chunks:
        ``pace``, progress, a stop request, MuJoCo's warnings.
        """
        S, n = self.S, self.n_steps
        next_pace = k0 if pace is not None else NEVER
        k = self._k = k0
        while True:
            if k == next_pace:
                next_pace = pace(k, log.log[: int(S[step.ST.rows])])
            stop = min(n, (k // CHUNK + 1) * CHUNK)
            if k < next_pace < stop:
                stop = next_pace
            self._draws(k, stop + 1)
            advance(k, stop)
            if k == n:
                return n
            if progress is not None and stop // 1000 > k // 1000:
                progress(stop // 1000 * 1000)
            k = self._k = stop
            if token is not None and token.is_set():
                raise KeyboardInterrupt("stop requested")
            if any(self.data.warning.number.tolist()):
                self._raise(step.ERR_WARNING, k - 1)

    def _python_steps(self, stages, faults, timer):
        """``advance(k, stop)`` from Python: steps ``k .. stop - 1``, or the last alone.

        Each step: ``mj_step1``, the stages (and the faults' hooks between
        them), ``mj_step2`` (not after the last step).
        """
        m, d, S, C, n = self.model, self.data, self.S, self.C, self.n_steps
        qpos, qvel, sd, ctrl = d.qpos, d.qvel, d.sensordata, d.ctrl
        xpos, xmat = d.site_xpos.reshape(-1), d.site_xmat.reshape(-1)
        ref, qj, uff = self._inputs()
        noise, walk, log = self.noise.rows, self.walk.rows, self._log
        wrap = timer.wrap if timer is not None else (lambda fn, stage: fn)
        step1 = wrap(mujoco.mj_step1, "physics")
        step2 = wrap(mujoco.mj_step2, "physics")
        sense, control = wrap(stages.sense, "sensors"), wrap(stages.control, "controllers")
        actuate, apply_forces = wrap(stages.actuate, "pneumatics"), stages.apply_forces
        record = wrap(stages.record, "logging")
        hooks = FaultHooks(faults, S, self.actuators) if faults is not None else None
        next_ev = faults.next_event if faults is not None else NEVER
        warnings = d.warning.number

        def advance(k0: int, stop: int) -> None:
            nonlocal next_ev
            for k in range(k0, max(stop, k0 + 1)):
                self._k = k
                if k == next_ev and hooks is not None:
                    next_ev = hooks.at(k)
                step1(m, d)
                sense(k, S, C, qpos, qvel, xpos, xmat, noise, walk)
                if hooks is not None and hooks.sensors:
                    hooks.apply_sensors(k)
                self._raise(control(k, S, C, ref, qj, uff), k)
                if hooks is not None and hooks.valves:
                    hooks.apply_valves()
                self._raise(actuate(S, C), k)
                apply_forces(S, C, ctrl)
                self._raise(record(k, S, C, ref, qpos, sd, log.log, log.qlog, log.hlog), k)
                if k == n:
                    return
                step2(m, d)
                if any(warnings.tolist()):
                    self._raise(step.ERR_WARNING, k)

        return advance

    def _callback_steps(self):
        """``advance(k, stop)`` compiled: ``mj_step`` of steps ``k .. stop - 1``, or the last."""
        m, d, S = self.model, self.data, self.S

        def advance(k: int, stop: int) -> None:
            S[step.ST.k], S[step.ST.status] = k, step.RUNNING
            if stop > k:
                mujoco.mj_step(m, d, stop - k)
            else:  # the last step: its stages without integrating (mj_step1's work)
                mujoco.mj_forward(m, d)
            if S[step.ST.status] == step.STOPPED:
                self._raise(int(S[step.ST.err]), int(S[step.ST.err_k]))
            S[step.ST.status] = step.IDLE
            if int(S[step.ST.k]) != max(stop, k + 1):
                raise RuntimeError(
                    f"the control callback ran {int(S[step.ST.k]) - k} of "
                    f"{max(stop - k, 1)} steps: another callback replaced it"
                )

        return advance

    def _draws(self, k0: int, k1: int) -> None:
        """The sensors' and the bias walk's draws for steps ``k0 .. k1 - 1`` in their blocks."""
        S = self.S
        S[step.ST.noise_k0] = self.noise.ensure(k0, k1)
        m = int(S[step.ST.walk_m])  # an IMU sample at most every step
        S[step.ST.walk_m0] = self.walk.ensure(m, m + (k1 - k0))

    def _raise(self, err: int, k: int):
        """The exception of a step's error code (:mod:`simpro_mj.sim.step`); none for 0."""
        if not err:
            return
        self._k = k
        S, t = self.S, k * self.dt
        if err == step.ERR_WARNING:
            check_physics(
                self.model, self.data, np.zeros_like(self.data.warning.number), index=self.idx
            )
            raise PhysicsError(f"MuJoCo warning at t = {t:.3f} s")
        if err == step.ERR_FORCE:
            f = S[step.ST.f : step.ST.f + 3]
            p = S[step.ST.ast + step.ps.ACT.p :][:6]
            raise PhysicsError(
                f"non-finite actuator force {f} at t = {t:.3f} s (pressures {p[:3]}, {p[3:]})"
            )
        if err == step.ERR_LOOP:
            row = int(S[step.ST.rows]) - 1
            scratch = mujoco.MjData(self.model)
            scratch.qpos[:] = self._log.qlog[row]
            scratch.time = t
            mujoco.mj_kinematics(self.model, scratch)
            check_physics(self.model, scratch, loop_bound=LOOP_OPEN_BOUND, index=self.idx)
            raise PhysicsError(f"kinematic loop opened at t = {t:.3f} s")
        # the controllers' codes, named as TaskSpaceController names them
        raise_step_error(
            err, self.ref[k], S[step.ST.yp : step.ST.yp + 3], self.geometry, self.task.margin
        )
        raise RuntimeError(f"step error {err} at t = {t:.3f} s")

    def _result(self, rec: Log, steps: int, status: str, reason, wall: float) -> SimResult:
        """The log as columns (copies), the cueing columns, the run's figures."""
        row, dt = int(self.S[step.ST.rows]), self.dt
        log = rec.log[:row]
        columns = {name: log[:, j].copy() for j, name in enumerate(COLUMNS)}
        if self.cueing:
            from simpro_mj.config.cueing import CUE_COLUMNS  # on use, see __init__

            rows = np.arange(row) * self.decimation
            hlog = rec.hlog
            # a cueing run logs the head and holds the vehicle's input
            assert hlog is not None and self.veh_f is not None and self.veh_w is not None
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
                "max_loop_closure_error_m": float(self.S[step.ST.worst]),
                "wall_s": wall,
                "realtime_factor": float(steps * dt / wall) if wall > 0 else None,
            },
            scenario=self.scenario,
            sensor_floor=self.sensor_cfg.resolution_floor(),
            noise_floor=self.sensor_cfg.resolution_floor(with_bias=False),
            qpos=rec.qlog[:row].copy(),
            qpos_names=qpos_names(self.model),
        )
