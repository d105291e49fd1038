"""The rig as one object: MuJoCo's multibody with its three actuators.

The co-simulation (:mod:`simpro_mj.sim.loop`) holds the plant through this
object, as a dm_control task holds its ``Physics``: :meth:`Platform.reset`
puts the closed chain at rest with the actuators holding it. The 1 ms step itself
(:mod:`simpro_mj.sim.step`) reads MuJoCo's state, runs the sensors,
controllers and actuators, and writes the slide forces into ``ctrl`` at the
point of ``mj_step`` after the position and velocity stages, so the sensors
and the controllers act at the same instant as the state they read (no
hidden one-step delay), as a real-time controller sampling at t_k would.
"""

from __future__ import annotations

import mujoco
import numpy as np

from simpro_mj.plant.friction import dry_friction_forces
from simpro_mj.plant.model import PlantIndex, assemble
from simpro_mj.plant.pneumatics.statics import holding_forces

__all__ = ["Platform", "set_seal_friction"]


def set_seal_friction(model: mujoco.MjModel, index: PlantIndex, actuators) -> None:
    """Each slide's MuJoCo dry friction for ``actuators``' seals: their breakaway
    force under the ``stick`` model, 0 otherwise (:mod:`simpro_mj.plant.friction`).

    Whatever steps the model with these actuators sets it first: the step's own
    friction is then only the rest of the seal's curve.
    """
    dry, noslip = [0.0] * 3, 0
    if actuators.kind == "nonlinear":
        dry = dry_friction_forces(actuators.params)
        p = actuators.params
        model.dof_solref[index.slide_dof, 0] = p.stick_solref
        model.dof_solimp[index.slide_dof, :2] = p.stick_solimp
        noslip = p.stick_noslip if p.friction_model == "stick" else 0
    # the friction rows solved hard after the soft solve: a stuck seal does not creep
    # (the model has no contacts, so the pass touches the seals' rows only)
    model.opt.noslip_iterations = noslip
    model.dof_frictionloss[index.slide_dof] = dry


class Platform:
    """MuJoCo's model and data with the actuators that act on them.

    Parameters
    ----------
    model : mujoco.MjModel
        The compiled closed chain (:func:`simpro_mj.plant.model.load_model`).
    actuators : NonlinearActuators or LinearActuators
        From :func:`simpro_mj.plant.pneumatics.factory.make_actuators`.

    Attributes
    ----------
    data : mujoco.MjData
        The state (its arrays are views: copy what you keep).
    """

    def __init__(self, model: mujoco.MjModel, actuators, index: PlantIndex | None = None):
        self.model = model
        self.data = mujoco.MjData(model)
        self.index = index or PlantIndex.of(model)
        self.actuators = actuators
        set_seal_friction(model, self.index, actuators)

    def reset(self, q0) -> None:
        """At rest with the slides at ``q0`` (m): the closed chain assembled and
        the actuators at the static pressures that hold it."""
        m, d, idx = self.model, self.data, self.index
        mujoco.mj_resetData(m, d)
        assemble(m, d, q0, index=idx)
        self.actuators.reset(q0, np.zeros(3), force=holding_forces(m, d, idx))
        mujoco.mj_forward(m, d)
