"""Linearised actuators of the paper's eq. (19), on every slide of the closed chain
(:class:`LinearActuators`; its docstring states the model)."""

from __future__ import annotations

import numpy as np

from simpro_mj.core.errors import UserInputError
from simpro_mj.plant import step_functions as sf
from simpro_mj.plant.pneumatics.nonlinear import ArrayStep, NonlinearActuators
from simpro_mj.plant.pneumatics.params import U_CENTRE, PneumaticParams, fill_linear

__all__ = ["LinearActuators"]


class LinearActuators(ArrayStep):
    r"""Linearised actuators reproducing eq. (19) on every slide of the closed chain.

    Per leg an acceleration-like state :math:`φ` (a pressure difference per
    unit effective mass) obeys
    :math:`\dot φ = b (u - u_h) - a_0 \dot q - a_1 φ` (integrated exactly over
    the held step), and the slide forces are

    .. math::
        F = F_h + M_q φ + D_q \dot q + K_q (q - q_0),

    with :math:`M_q` the mass matrix of the closed chain reduced to the slides,
    :math:`D_q` the joint damping of the mechanism reduced the same way and
    :math:`K_q = ∂F_h/∂q` the change of the gravity holding forces with the
    configuration (all at home, :func:`~.statics.slide_mass_matrix`; leg 1 sees a
    negative gravity stiffness of about -4.4 kN/m). Linearised about rest the
    multibody obeys :math:`M_q \ddot q + D_q \dot q = F - F_h - K_q (q - q_0)`, hence
    :math:`\ddot q = φ` and every leg follows
    :math:`Q/U = b/(s(s^2 + a_1 s + a_0))` exactly, decoupled from the other
    legs (the reflected masses of legs 2 and 3 are coupled by about 40 %:
    a diagonal-mass design would not reproduce eq. 35 in the closed chain).

    Parameters
    ----------
    params : dict or PneumaticParams, optional
        The ``pneumatics`` tree; ``linear`` holds b, a1, a0 per leg.
    mass_matrix : array (3, 3) or (3,), optional
        :math:`M_q` in kg (a vector: a diagonal). Default
        ``linear.effective_mass_kg`` (diagonal; required then).
    damping_matrix : array (3, 3), optional
        :math:`D_q` in N s/m (default 0).
    stiffness_matrix : array (3, 3), optional
        :math:`K_q` in N/m (default 0); q_0 is the ``q`` given to :meth:`reset`.

    Attributes
    ----------
    p1, p2 : ndarray (3,)
        Nominal chamber pressures consistent with the force (display only: the
        nonlinear static equilibrium plus the force deviation shared equally).
    spool : ndarray (3,)
        Normalised valve command (no spool dynamics in this model).
    """

    kind = "linear"
    step_function = staticmethod(sf.linear_step)

    def __init__(self, params=None, mass_matrix=None, damping_matrix=None, stiffness_matrix=None):
        P = params if isinstance(params, PneumaticParams) else PneumaticParams.from_tree(params)
        P = fill_linear(P)  # raises if eq. (19)'s coefficients are left null
        self.params = P
        m = mass_matrix if mass_matrix is not None else P.lin_mass
        if m is None:
            raise UserInputError(
                "linear actuators need the effective slide masses: give a MuJoCo model to "
                "make_actuators(..., model=) or set pneumatics.linear.effective_mass_kg"
            )
        m = np.asarray(m, float)
        self.mass_matrix = np.diag(np.broadcast_to(m, (3,))) if m.ndim <= 1 else m.copy()
        if self.mass_matrix.shape != (3, 3):
            raise ValueError("mass_matrix must be (3, 3) or (3,)")
        self.damping_matrix = (
            np.zeros((3, 3)) if damping_matrix is None else np.asarray(damping_matrix, float)
        )
        self.stiffness_matrix = (
            np.zeros((3, 3)) if stiffness_matrix is None else np.asarray(stiffness_matrix, float)
        )
        self._a1 = np.asarray(P.lin_a1, float)
        self._nl = NonlinearActuators(P)  # static pressures for display
        # the per-step function's arrays (simpro_mj.plant.step_functions.linear_step): the
        # state (phi, spool and the display pressures are views of it) and the constants
        ast = self.step_state = np.zeros(sf.ACT.LEN)
        self.phi = ast[sf.ACT.phi : sf.ACT.phi + 3]
        self.spool = ast[sf.ACT.spool : sf.ACT.spool + 3]
        self.p1, self.p2 = ast[sf.ACT.p : sf.ACT.p + 3], ast[sf.ACT.p + 3 : sf.ACT.p + 6]
        ast[sf.ACT.ps] = P.p_supply  # the supply the log shows (a fault changes it)
        ast[sf.ACT.fmin], ast[sf.ACT.fmax] = P.force_range
        # exp(-a1 dt) and its integral: set_timestep's; u_hold, F_hold, q_0 and the
        # display pressures: reset's
        z = np.zeros(3)
        self.step_constants = sf.ACL.pack(
            kind=1.0, pa=P.p_atm, a1=P.area_cap, a2=P.area_rod_side, ar=P.area_rod, b=P.lin_b,
            a0=P.lin_a0, ea=z, ia=z, uhold=z, fhold=z, q0=z, mq=self.mass_matrix,
            dq=self.damping_matrix, kq=self.stiffness_matrix, sat=1.0 if P.lin_saturate else 0.0,
            p10=z, p20=z,
        )  # fmt: skip
        ac = self.step_constants
        self.u_hold = ac[sf.ACL.uhold : sf.ACL.uhold + 3]  # views of the constants
        self.force_hold = ac[sf.ACL.fhold : sf.ACL.fhold + 3]
        self.q_ref = ac[sf.ACL.q0 : sf.ACL.q0 + 3]

    def reset(self, q, qdot, force=None) -> None:
        """At rest holding ``force`` (N) with the valve at the nonlinear model's
        holding voltage (5 V and the centred-valve force when ``force`` is None)."""
        self._nl.reset(q, qdot, force)
        if force is None:
            self.force_hold[:] = self._nl.force_now(np.zeros(3))
        else:
            self.force_hold[:] = np.broadcast_to(np.asarray(force, float), (3,))
        self.u_hold[:] = self._nl.u_hold
        self.q_ref[:] = q
        ac = self.step_constants
        ac[sf.ACL.p10 : sf.ACL.p10 + 3], ac[sf.ACL.p20 : sf.ACL.p20 + 3] = self._nl.p1, self._nl.p2
        self.phi[:] = 0.0
        self.spool[:] = (self.u_hold - U_CENTRE) / 5.0
        self.p1[:], self.p2[:] = self._nl.p1, self._nl.p2

    def set_timestep(self, dt: float) -> None:
        """The step's constants that depend on ``dt`` (s): ``e^(-a1 dt)`` and its integral."""
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        self._dt = dt
        a1, ac = self._a1, self.step_constants
        ac[sf.ACL.ea : sf.ACL.ea + 3] = np.exp(-a1 * dt)
        safe = np.where(a1 > 0, a1, 1.0)
        ac[sf.ACL.ia : sf.ACL.ia + 3] = np.where(a1 > 0, -np.expm1(-a1 * dt) / safe, dt)
