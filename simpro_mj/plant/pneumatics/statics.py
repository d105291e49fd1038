"""The closed chain seen from the three slides: statics and reduced matrices (MuJoCo).

With N (nv, 3) the joint velocities produced by unit slide velocities while
the loops stay closed (``J_c N = 0``, ``S N = I``), the multibody reduces to
the slides as :math:`M_q = N^T M N` (mass), :math:`D_q = N^T D N` (joint
damping), :math:`F_h = N^T τ_{bias}` (the forces that hold it at rest) and
:math:`K_q = ∂F_h/∂q` (its gravity stiffness).
The linear actuators of eq. (19) need all three; the co-simulation,
identification and the payload statics start from :func:`holding_forces`.
"""

from __future__ import annotations

import mujoco
import numpy as np

from simpro_mj.plant.model import PlantIndex, assemble, loop_closure_jacobian

__all__ = ["slide_mass_matrix", "slide_damping_matrix", "holding_forces", "holding_stiffness"]


def slide_mass_matrix(model, data, index=None) -> np.ndarray:
    """Mass matrix of the closed chain in the slide coordinates (3, 3), kg.

    :math:`M_q = N^T M N` with N (nv, 3) the joint velocities produced by unit
    slide velocities while the loops stay closed (``J_c N = 0``, ``S N = I``).
    Its diagonal is the effective mass of a slide with the other two held;
    :math:`1/(M_q^{-1})_{ii}` with the other two free. Uses the current
    configuration (call after :func:`simpro_mj.plant.model.assemble`).
    """
    idx = index or PlantIndex.of(model)
    mujoco.mj_forward(model, data)
    n = _slide_velocity_map(model, data, idx)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, M, data.qM) if hasattr(data, "qM") else mujoco.mj_fullM(model, data, M)
    return n.T @ M @ n


def slide_damping_matrix(model, data, index=None) -> np.ndarray:
    """Joint damping of the mechanism reduced to the slides, :math:`N^T D N` (N s/m)."""
    idx = index or PlantIndex.of(model)
    n = _slide_velocity_map(model, data, idx)
    return n.T @ np.diag(model.dof_damping) @ n


def _slide_velocity_map(model, data, idx):
    _, jc = loop_closure_jacobian(model, data, idx)
    sel = np.zeros((3, model.nv))
    sel[np.arange(3), idx.slide_dof] = 1.0
    a = np.vstack([jc, sel])
    rhs = np.vstack([np.zeros((jc.shape[0], 3)), np.eye(3)])
    return np.linalg.lstsq(a, rhs, rcond=None)[0]


def holding_forces(model, data, index=None) -> np.ndarray:
    """Static slide forces (N) that hold the closed chain at rest where it is.

    :math:`F = N^T τ_{bias}` (gravity; ``qvel`` = 0): the constraint forces
    do no work along N, so this is the inverse-dynamics static solve.
    """
    idx = index or PlantIndex.of(model)
    saved = data.qvel.copy()
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    n = _slide_velocity_map(model, data, idx)
    out = n.T @ data.qfrc_bias
    data.qvel[:] = saved
    mujoco.mj_forward(model, data)
    return out


def holding_stiffness(model, data, q0, h: float, index=None) -> np.ndarray:
    """The gravity stiffness :math:`K_q = ∂F_h/∂q` (3, 3), N/m, about slides ``q0``.

    Central differences of :func:`holding_forces` with slide j at ``q0[j] ± h``
    (the chain assembled at each, :func:`simpro_mj.plant.model.assemble`, from
    where ``data`` stands); ``data`` is left at the last probe.
    """
    idx = index or PlantIndex.of(model)
    k = np.empty((3, 3))
    for j in range(3):
        f = []
        for sign in (1.0, -1.0):
            q = np.array(q0, dtype=float)
            q[j] += sign * h
            assemble(model, data, q, index=idx)
            f.append(holding_forces(model, data, idx))
        k[:, j] = (f[0] - f[1]) / (2 * h)
    return k
