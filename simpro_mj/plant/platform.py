"""The rig as one object: MuJoCo's multibody, its three actuators and its sensors.

The co-simulation loop (:mod:`simpro_mj.sim.loop`) sees the plant only
through this object, as a dm_control task sees its ``Physics``: the state
goes out through :attr:`Platform.front`, the actuator forces come in through
:attr:`Platform.step2`, and divergence comes back as
:class:`~simpro_mj.core.errors.PhysicsError` raised from MuJoCo's
``data.warning`` counters. One 1 ms step is MuJoCo's split step around the
actuation::

    step1()                                   # mj_step1: kinematics at t_k
    q, q_dot, pose, q_meas, pose_meas, loop = front(k)
    ...                                       # controllers: u(t_k)
    f = actuators.step(u, q, q_dot, dt)       # pneumatics: forces over [t_k, t_k+1)
    step2(f)                                  # mj_step2: integrate to t_k+1

Splitting ``mj_step`` puts the sensors and the controllers at the same
instant as the state they act on (no hidden one-step delay), as a real-time
controller sampling at t_k would.
"""

from __future__ import annotations

import math
from functools import partial

import mujoco
import numpy as np

from simpro_mj.core.errors import PhysicsError
from simpro_mj.plant.model import PlantIndex, StateReader, assemble, check_physics, measured_pose
from simpro_mj.plant.pneumatics.statics import holding_forces

__all__ = ["Platform"]


class Platform:
    """MuJoCo's model and data with the actuators and sensors that act on them.

    Parameters
    ----------
    model : mujoco.MjModel
        The compiled closed chain (:func:`simpro_mj.plant.model.load_model`).
    actuators : NonlinearActuators or LinearActuators
        From :func:`simpro_mj.plant.pneumatics.factory.make_actuators`.
    sensors : Sensors
        :class:`simpro_mj.plant.sensors.Sensors`.

    Attributes
    ----------
    data : mujoco.MjData
        The state (its arrays are views: copy what you keep).
    step1 : callable()
        ``mj_step1`` on this model and data.
    step2 : callable(forces)
        Apply the three slide forces (N) and integrate to the next step
        (``mj_step2``). Raises :class:`PhysicsError` on a non-finite force
        and when a MuJoCo warning counter is set after the step.
    front : callable(k)
        After :meth:`reset`: ``front(k) -> (q, q_dot, pose, q_meas,
        pose_meas, loop_max)``, the state and the sensors' reading at step
        ``k`` (:meth:`Sensors.front <simpro_mj.plant.sensors.Sensors.front>`:
        the compiled kernel or the Python path, the same bits).
    """

    def __init__(self, model: mujoco.MjModel, actuators, sensors, index: PlantIndex | None = None):
        self.model = model
        self.data = mujoco.MjData(model)
        self.index = index or PlantIndex.of(model)
        self.timestep = float(model.opt.timestep)
        self.actuators = actuators
        self.sensors = sensors
        self.reader = StateReader(model, self.data, self.index)
        self.step1 = partial(mujoco.mj_step1, model, self.data)
        self.step2 = self._bind_step2()
        self.front = None

    def _bind_step2(self):
        """:attr:`step2` as a closure over pre-bound views (it runs every 1 ms)."""
        m, d, idx, act = self.model, self.data, self.index, self.actuators
        ctrl = d.ctrl
        c0, c1, c2 = idx.actuators.tolist()
        warnings = d.warning.number  # live view of the warning counters
        none = np.zeros_like(warnings)
        mj_step2, isfinite = mujoco.mj_step2, math.isfinite

        def step2(forces) -> None:
            f0, f1, f2 = forces
            if not isfinite(f0 + f1 + f2):
                raise PhysicsError(
                    f"non-finite actuator force {np.asarray(forces)} at t = {d.time:.3f} s "
                    f"(pressures {act.p1}, {act.p2})"
                )
            ctrl[c0], ctrl[c1], ctrl[c2] = f0, f1, f2
            mj_step2(m, d)
            if any(warnings.tolist()):  # 0.11 us; check_physics names the warning
                check_physics(m, d, none, index=idx)

        return step2

    def reset(self, q0) -> None:
        """At rest with the slides at ``q0`` (m): the closed chain assembled,
        the actuators at the static pressures that hold it, the sensors
        initialised at that state; binds :attr:`front`."""
        m, d, idx = self.model, self.data, self.index
        mujoco.mj_resetData(m, d)
        assemble(m, d, q0, index=idx)
        self.actuators.reset(q0, np.zeros(3), force=holding_forces(m, d, idx))
        mujoco.mj_forward(m, d)
        self.sensors.reset(d.qpos[idx.slide_qpos], measured_pose(d, idx.site_p))
        self.front = self.sensors.front(self.reader)

    def check_loops(self, bound: float) -> None:
        """Raise :class:`PhysicsError` naming the kinematic loop open beyond ``bound`` (m)."""
        check_physics(self.model, self.data, loop_bound=bound, index=self.index)
