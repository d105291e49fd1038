"""Seal friction of a pneumatic cylinder: breakaway, Stribeck, Coulomb, viscous.

One scalar function, :func:`seal_friction`, on plain floats and :mod:`math`
only, so the same source runs interpreted and compiled (numba) in the 1 ms
step. The law is the static Stribeck curve of the cylinder-friction models in
common use (Armstrong-Hélouvry 1991; MathWorks Simscape's *Cylinder Friction*
block, whose breakaway force is the sum of its Coulomb and Stribeck parts):

.. math::
    F_f(v) = \\left[F_C + (F_S - F_C)\\, e^{-(v/v_S)^2}\\right]
             \\tanh(v / v_r) + β v

with :math:`F_S` the static (breakaway) force, :math:`F_C` the Coulomb
(running) force, :math:`v_S` the Stribeck velocity, :math:`β` the viscous
coefficient and :math:`v_r` a regularising velocity. The force opposes the
motion: the slide's net force is the pneumatic force minus :math:`F_f`.

Why a regularised static map and not a switching (Karnopp) or a bristle
(LuGre) model: the step applies the force for the next 1 ms from the present
velocity, with no access to the other forces on the slide that a stick
condition needs (gravity and the platform's coupling act inside MuJoCo), and
a bristle state with a stiffness of 10^5-10^6 N/m adds a state and a mode
faster than the 1 ms step resolves at the light loads of the ``paper`` preset.
The regularisation makes the law a smooth function of v, so the ODE stays
well-posed; its price is creep: a leg loaded by ``F < F_S`` slides at the
speed where :math:`F_f(v) = F`, about :math:`v_r\\,\\mathrm{artanh}(F/F_S)`
(0.55 v_r at half the breakaway force). Below ``v_r`` the law is a viscous
damper of slope :math:`F_S / v_r + β`; the explicit 1 ms coupling stays stable
while that slope times the step is below twice the slide's effective mass
(``docs/paper-notes.md``, seal friction, has the numbers of both presets).
"""

from __future__ import annotations

import math

__all__ = ["seal_friction"]


def seal_friction(v, f_breakaway, f_coulomb, v_stribeck, viscous, v_reg):
    """Friction force (N) of a cylinder's seals at slide velocity ``v`` (m/s).

    Parameters
    ----------
    v : float
        Slide velocity, m/s.
    f_breakaway : float
        Static (breakaway) force F_S, N; ``f_breakaway == f_coulomb`` gives
        no Stribeck peak.
    f_coulomb : float
        Coulomb (running) force F_C, N.
    v_stribeck : float
        Stribeck velocity v_S, m/s (> 0): where the peak has fallen to 1/e.
    viscous : float
        Viscous coefficient β, N s/m.
    v_reg : float
        Regularising velocity v_r, m/s (> 0).

    Returns
    -------
    float
        The friction force, with the sign of ``v`` (subtract it from the
        driving force); 0 at rest.
    """
    x = v / v_stribeck
    peak = f_coulomb + (f_breakaway - f_coulomb) * math.exp(-(x * x))
    return peak * math.tanh(v / v_reg) + viscous * v
