"""``make_actuators``: the actuators of one kind, the interface the co-simulation uses.

Two models share one interface::

    act = make_actuators("nonlinear", pneumatics)    # or "linear"
    act.reset(q, qdot, force=holding_force)          # static equilibrium
    for each 1 ms step:
        force = act.step(u_volts, q, qdot, dt)       # (3,) N
        data.ctrl[idx.actuators] = force
        mujoco.mj_step(model, data)

The linear model without ``linear.effective_mass_kg`` takes its matrices
from the MuJoCo model at the home pose (:mod:`.statics`), hence MuJoCo here.
"""

from __future__ import annotations

import mujoco
import numpy as np

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import closest
from simpro_mj.plant.model import assemble, load_model
from simpro_mj.plant.pneumatics.linear import LinearActuators
from simpro_mj.plant.pneumatics.nonlinear import NonlinearActuators
from simpro_mj.plant.pneumatics.params import ACTUATOR_KINDS, PneumaticParams, fill_linear, typed
from simpro_mj.plant.pneumatics.statics import (
    holding_stiffness,
    slide_damping_matrix,
    slide_mass_matrix,
)

__all__ = ["make_actuators"]


def make_actuators(kind: str, params_tree=None, *, model=None, linear_plants=None):
    """Build the actuators of one kind.

    Parameters
    ----------
    kind : {"nonlinear", "linear"}
    params_tree : dict, Pneumatics or PneumaticParams, optional
        The ``pneumatics`` tree or block (:class:`~.params.Pneumatics`; None: defaults).
    model : mujoco.MjModel, optional
        For ``"linear"`` without ``linear.effective_mass_kg``: the effective
        slide masses are taken from this model at the home pose (mid-stroke).
    linear_plants : (b, a1, a0), optional
        For ``"linear"``: per-leg eq. (19) coefficients in SI for the
        ``linear`` keys left null (:func:`fill_linear`).

    Raises
    ------
    UserInputError
        Unknown ``kind`` (the message lists the allowed values).
    """
    if kind not in ACTUATOR_KINDS:
        raise UserInputError(
            f"unknown actuator kind '{kind}': allowed values are {list(ACTUATOR_KINDS)}"
            f"{closest(str(kind), ACTUATOR_KINDS)}"
        )
    P = params_tree if isinstance(params_tree, PneumaticParams) else typed(params_tree).params()
    if kind == "nonlinear":
        return NonlinearActuators(P)
    P = fill_linear(P, linear_plants)
    if P.lin_mass is not None:
        return LinearActuators(P, mass_matrix=P.lin_mass)
    m = model if model is not None else load_model()
    d = mujoco.MjData(m)
    q0 = np.full(3, 0.5 * P.stroke)
    assemble(m, d, q0)
    mq, dq = slide_mass_matrix(m, d), slide_damping_matrix(m, d)
    kq = holding_stiffness(m, d, q0, 1e-3)
    return LinearActuators(P, mass_matrix=mq, damping_matrix=dq, stiffness_matrix=kq)
