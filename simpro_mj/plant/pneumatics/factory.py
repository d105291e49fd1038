"""``make_actuators``: the actuators of one kind, the interface the co-simulation uses.

Two models share one interface::

    act = make_actuators("nonlinear", params_tree)   # or "linear"
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
from simpro_mj.plant.pneumatics.params import ACTUATOR_KINDS, PneumaticParams, fill_linear
from simpro_mj.plant.pneumatics.statics import (
    holding_stiffness,
    slide_damping_matrix,
    slide_mass_matrix,
)

__all__ = ["make_actuators"]


def _pneu_tree(params_tree):
    if params_tree is None:
        return None
    if isinstance(params_tree, PneumaticParams):
        return params_tree
    if "pneumatics" in params_tree:
        return params_tree["pneumatics"]
    return params_tree


def make_actuators(kind: str, params_tree=None, *, model=None, linear_plants=None):
    """Build the actuators of one kind.

    Parameters
    ----------
    kind : {"nonlinear", "linear"}
    params_tree : dict, optional
        The ``pneumatics`` tree, or a whole scenario tree with a ``pneumatics`` key.
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
    tree = _pneu_tree(params_tree)
    if kind == "nonlinear":
        return NonlinearActuators(tree)
    P = tree if isinstance(tree, PneumaticParams) else PneumaticParams.from_tree(tree)
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
