"""The multi-rate co-simulation loop (replaces Simulink + ADAMS, paper Fig. 13).

One physics step of ``dt`` = 1 ms::

    mj_step1          kinematics and sensors at the state of t_k
    sensors           potentiometers, height encoder, IMU (own rates, ZOH)
    outer loop        every ``period_ms``: task error -> integrated pose -> IK -> q_d
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
import time
from dataclasses import dataclass, field

import mujoco
import numpy as np

from controllers.design import Plant
from controllers.geometry import nominal_geometry
from controllers.joint import JointControllers
from controllers.kinematics import inverse_kinematics
from controllers.task_space import TaskSpaceController

from .errors import PhysicsError, UserInputError
from .model import (
    PlantIndex,
    assemble,
    check_physics,
    load_model,
    loop_closure_error,
    measured_pose,
)
from .pneumatics import holding_forces, make_actuators
from .sensors import SensorConfig, Sensors

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
)
_C = {name: k for k, name in enumerate(COLUMNS)}

#: Divergence bound on the loop-closure error (m): far above the 0.5 mm of
#: normal motion, well below anything physical.
LOOP_OPEN_BOUND = 5e-3


@dataclass
class SimResult:
    """What one run produced. ``columns`` holds copies, never MuJoCo views."""

    columns: dict
    status: str  # "ok" | "diverged"
    reason: str | None
    sim: dict
    scenario: dict
    sensor_floor: dict = field(default_factory=dict)


def _ms_to_steps(ms: float, dt: float, path: str) -> int:
    n = ms * 1e-3 / dt
    k = int(round(n))
    if k < 1 or abs(n - k) > 1e-9 * max(1.0, n):
        raise UserInputError(
            f"invalid value at {path}: {ms} ms; allowed: a positive integer multiple of the "
            f"{dt * 1e3:g} ms physics timestep"
        )
    return k


class CoSimulation:
    """A scenario's plant, sensors and controllers, ready to run.

    Parameters
    ----------
    scenario : dict
        A resolved scenario (:func:`simpro_mj.scenario.load_scenario`).
    model : mujoco.MjModel, optional
        A compiled plant; built from ``scenario["plant"]`` when omitted.
    """

    def __init__(self, scenario: dict, model: mujoco.MjModel | None = None):
        from .scenario import reference

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
        self.task = TaskSpaceController(
            mode=outer["type"] if self.mode == "task_space" else "joint_only",
            gains=outer["gains"],
            period=self.outer_every * dt,
            geometry=self.geometry,
            clamp=bool(ctl.get("clamp_setpoints", False)),
            inner_dt=dt,
            pi_zero=float(outer.get("pi_zero", 0.2)),
        )
        inner = ctl["inner"]
        if inner["design_plant"] == "identified":
            acts = ("actuator1", "actuator2", "actuator3")
            plants = [Plant(**inner["identified"][a]) for a in acts]
        else:
            plants = None  # eqs. (34)-(35)
        spec = None
        if inner["variant"] == "redesigned":
            spec = {"zeta": inner["zeta"], "wn": inner["wn_rad_s"]}
        self.joint = JointControllers(
            variant=inner["variant"],
            dt=dt,
            method=inner["discretisation"],
            plants=plants,
            spec=spec,
        )
        act = scenario["actuator"]
        self.actuators = make_actuators(act["model"], act.get("pneumatics") or {}, model=m)
        self.rng = np.random.default_rng(int(scenario["seed"]))
        self.sensor_cfg = SensorConfig.from_tree(scenario["sensors"], dt)
        self.sensors = Sensors(self.sensor_cfg, self.rng)

        self.t = np.arange(self.n_steps + 1) * dt
        self.ref = np.ascontiguousarray(reference(scenario, self.t))
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
        mujoco.mj_forward(m, d)
        self.sensors.reset(d.qpos[idx.slide_qpos], measured_pose(d, idx.site_p))

    # ------------------------------------------------------------------ run
    def run(self, progress=None) -> SimResult:
        """Run the scenario; on divergence stop and return what was computed.

        Parameters
        ----------
        progress : callable(int), optional
            Called with the number of steps done, every 1000 steps.
        """
        self._initial_state()
        m, d, idx = self.model, self.data, self.idx
        dt, n, dec = self.dt, self.n_steps, self.decimation
        n_log = n // dec + 1
        log = np.full((n_log, len(COLUMNS)), np.nan)
        s_qpos, s_dof, act_ids = idx.slide_qpos, idx.slide_dof, idx.actuators
        site_p = idx.site_p
        no_warnings = np.zeros_like(d.warning.number)
        task_mode = self.mode == "task_space"
        outer_every = self.outer_every
        ref, t_grid = self.ref, self.t
        q_d = self.task.q_desired if task_mode else self.q_joint_only[0]
        pose_cmd = ref[0]
        act, joint, task, sensors = self.actuators, self.joint, self.task, self.sensors
        status, reason = "ok", None
        worst_loop = 0.0
        row = 0
        wall0 = time.perf_counter()
        k = 0
        try:
            for k in range(n + 1):
                mujoco.mj_step1(m, d)
                q_true = d.qpos[s_qpos]
                qdot = d.qvel[s_dof]
                pose = measured_pose(d, site_p)
                q_meas, pose_meas = sensors.sample(k, q_true, pose)
                if task_mode:
                    if k % outer_every == 0:
                        q_d = task.update(ref[k], pose_meas)
                        pose_cmd = task.pose_command
                else:
                    q_d = self.q_joint_only[k]
                    pose_cmd = ref[k]
                u = joint.update(q_d, q_meas)
                f = act.step(u, q_true, qdot, dt)
                if k % dec == 0:
                    loop = float(loop_closure_error(m, d, idx).max())
                    worst_loop = max(worst_loop, loop)
                    r = log[row]
                    r[0] = t_grid[k]
                    r[1:4] = ref[k]
                    r[4:7] = pose
                    r[7:10] = pose_meas
                    r[10:13] = pose_cmd
                    r[13:16] = q_d
                    r[16:19] = q_true
                    r[19:22] = q_meas
                    r[22:25] = u
                    r[25:28] = f
                    r[28:34:2] = act.p1
                    r[29:34:2] = act.p2
                    r[34] = loop
                    row += 1
                    if loop > LOOP_OPEN_BOUND:
                        check_physics(m, d, loop_bound=LOOP_OPEN_BOUND, index=idx)  # raises
                if k == n:
                    break
                if not math.isfinite(f[0] + f[1] + f[2]):
                    raise PhysicsError(
                        f"non-finite actuator force {f} at t = {t_grid[k]:.3f} s "
                        f"(pressures {act.p1}, {act.p2})"
                    )
                d.ctrl[act_ids] = f
                mujoco.mj_step2(m, d)
                if d.warning.number.any():
                    check_physics(m, d, no_warnings, index=idx)  # raises, naming the warning
                if progress is not None and k % 1000 == 0:
                    progress(k)
        except PhysicsError as exc:
            status, reason = "diverged", str(exc)
        wall = time.perf_counter() - wall0
        log = log[:row]
        columns = {name: log[:, j].copy() for j, name in enumerate(COLUMNS)}
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
        )


def simulate(scenario: dict, progress=None) -> SimResult:
    """Build and run a scenario (convenience)."""
    return CoSimulation(scenario).run(progress)
