"""The plant's own linearisation in place of the identification experiment.

At the operating point of the Fig. 12 experiment (every leg at
``identify.position_mm``, the actuators at the pneumatic equilibrium holding the
static forces, :mod:`simpro_mj.identification.identify`), each leg i is linearised
from the model itself instead of being excited and fitted:

* the actuators' own 1 ms step function (the run's arithmetic, interpreted) with the
  slides held: a valve voltage step of ``DU_V``
  gives the force rate per volt :math:`B_i` (the slope of a least-squares line
  over the first ``WINDOW_S``);
* the same step with slide i moving at ``DV_M_S``: the force's immediate change is
  the viscous friction :math:`c_i` (intercept), its rate the chamber air's stiffness
  :math:`k_{p,i}` (slope);
* the closed chain reduced to the slides at that configuration
  (:mod:`simpro_mj.plant.pneumatics.statics`): the effective mass :math:`m_i` of slide
  i with the other two held, the mechanism's joint damping :math:`d_i`, and the
  gravity stiffness :math:`k_{g,i} = -∂F_{h,i}/∂q_i` (central difference of the
  holding forces, ``DQ_M``).

Linearised about rest, :math:`m_i \\dot v = F - (c_i + d_i) v - k_{g,i} q` and
:math:`\\dot F = B_i u - k_{p,i} v`, hence eq. (19):
:math:`V/U = b/(s^2 + a_1 s + a_0)` with :math:`b = B_i/m_i`,
:math:`a_1 = (c_i + d_i)/m_i`, :math:`a_0 = (k_{p,i} + k_{g,i})/m_i`.

What it leaves out, by construction: the seals' dry friction (a stick-slip seal
has no linearisation; on such a plant the experiment's fit is poor too), the valve
spool's lag (a pole far above the loop's), the chamber leakage's pressure feedback
beyond the window, and the coupling of the legs through the mechanism (the other
slides held, as the experiment's position loops hold them).
"""

from __future__ import annotations

import mujoco
import numpy as np

from controllers.design import paper_coefficients
from simpro_mj.core.errors import UserInputError
from simpro_mj.identification.settings import check_tree
from simpro_mj.plant.model import PlantIndex, assemble, load_model
from simpro_mj.plant.pneumatics.factory import make_actuators
from simpro_mj.plant.pneumatics.statics import (
    holding_forces,
    slide_damping_matrix,
    slide_mass_matrix,
)

__all__ = ["linearise", "DU_V", "DV_M_S", "WINDOW_S", "DQ_M"]

#: Valve voltage step (V): small against the ±0.3 V of the experiment's excitation.
DU_V = 0.01
#: Slide speed (m/s) of the stiffness probe: 1 mm/s.
DV_M_S = 1e-3
#: Window of the force's line fit (s): short against the chambers' time constants.
WINDOW_S = 0.005
#: Slide displacement (m) of the gravity stiffness's central difference.
DQ_M = 1e-4


def _force_line(act, step, f_hold, u, q0, qd, n, dt) -> tuple[np.ndarray, np.ndarray]:
    """Reset at the equilibrium holding ``f_hold``, step ``n`` times at valve voltages
    ``u`` and slide speeds ``qd``; (intercept, slope) per leg of the force's line."""
    act.reset(q0, np.zeros(3), force=f_hold)
    f = np.zeros((n, 3))
    force = np.zeros(3)
    q = q0.copy()
    for k in range(n):
        force[:] = 0.0
        step(u, q, qd, force)
        f[k] = force
        q = q + qd * dt
    t = np.arange(n) * dt
    slope, intercept = np.polyfit(t, f, 1)
    return intercept, slope


def linearise(tree: dict, model=None) -> dict:
    """Eq. (19)'s b, a1, a0 per actuator from the model's linearisation (module docstring).

    ``tree`` is an identification tree (:func:`simpro_mj.identification.settings.default_tree`
    with the scenario's plant, :func:`simpro_mj.identification.auto.plant_tree`).
    Returns ``{actuator: {b, a1, a0}}`` in SI (m/V), as the experiment's fit.
    """
    check_tree(tree)
    ip = tree["identify"]
    m = model if model is not None else load_model(tree["model"])
    d = mujoco.MjData(m)
    idx = PlantIndex.of(m)
    dt = float(m.opt.timestep)
    q0 = np.full(3, float(ip["position_mm"]) * 1e-3)
    assemble(m, d, q0, index=idx)
    f_hold = holding_forces(m, d, idx)
    mass = slide_mass_matrix(m, d, idx)
    damp = slide_damping_matrix(m, d, idx)
    k_grav = np.empty(3)
    for i in range(3):
        fs = []
        for sign in (1.0, -1.0):
            q = q0.copy()
            q[i] += sign * DQ_M
            assemble(m, d, q, index=idx)
            fs.append(holding_forces(m, d, idx)[i])
        k_grav[i] = -(fs[0] - fs[1]) / (2 * DQ_M)
    assemble(m, d, q0, index=idx)

    act = make_actuators(
        ip["actuator_kind"],
        tree["pneumatics"],
        model=m,
        linear_plants=paper_coefficients(tree["paper_units"]),
    )
    act.reset(q0, np.zeros(3), force=f_hold)
    u_hold = act.u_hold.copy()
    # the actuators' own step function, interpreted: a few dozen steps need no compile
    act.set_timestep(dt)
    fn, state, constants = act.step_function, act.step_state, act.step_constants

    def step(u, q, qd, f):
        fn(u, q, qd, state, constants, f)

    n = max(2, int(round(WINDOW_S / dt)))
    _, base_slope = _force_line(act, step, f_hold, u_hold.copy(), q0, np.zeros(3), n, dt)
    out = {}
    for i in range(3):
        u = u_hold.copy()
        u[i] += DU_V
        _, slope_u = _force_line(act, step, f_hold, u, q0, np.zeros(3), n, dt)
        qd = np.zeros(3)
        qd[i] = DV_M_S
        icpt_v, slope_v = _force_line(act, step, f_hold, u_hold.copy(), q0, qd, n, dt)
        icpt_0 = f_hold[i]
        gain = (slope_u[i] - base_slope[i]) / DU_V  # N/s per V
        c = -(icpt_v[i] - icpt_0) / DV_M_S  # N s/m
        k_air = -(slope_v[i] - base_slope[i]) / DV_M_S  # N/m
        mi = float(mass[i, i])
        out[f"actuator{i + 1}"] = {
            "b": gain / mi,
            "a1": (c + float(damp[i, i])) / mi,
            "a0": (k_air + k_grav[i]) / mi,
        }
        bad = [k for k, v in out[f"actuator{i + 1}"].items() if not v > 0.0]
        if bad:
            raise UserInputError(
                f"invalid value at controller.inner.identify: linearised: the plant's "
                f"linearisation gives {bad[0]} = {out[f'actuator{i + 1}'][bad[0]]:.3g} <= 0 "
                f"on actuator {i + 1} (seals that stick have no linearisation); allowed: "
                "auto (the identification experiment) or preset"
            )
    return out
