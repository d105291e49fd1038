"""Seal friction of a pneumatic cylinder: breakaway, Stribeck, Coulomb, viscous.

The static Stribeck curve of the cylinder-friction models in common use
(Armstrong-Hélouvry 1991; MathWorks Simscape's *Cylinder Friction* block,
whose breakaway force is the sum of its Coulomb and Stribeck parts):

.. math::
    F_f(v) = \\left[F_C + (F_S - F_C)\\, e^{-(v/v_S)^2}\\right] \\mathrm{sgn}(v) + β v

with :math:`F_S` the static (breakaway) force, :math:`F_C` the Coulomb
(running) force, :math:`v_S` the Stribeck velocity and :math:`β` the viscous
coefficient. At rest the seal holds any net force up to :math:`F_S`.

Two ways to put it into the step (``pneumatics.cylinder.friction_model``):

``stick`` (default)
    MuJoCo's joint dry friction (``frictionloss`` = :math:`F_S` on each slide,
    :func:`dry_friction_forces`) is a constraint the solver meets together
    with the loop closures and the other forces of the step: a slide whose
    net load is below :math:`F_S` stays put, one above it slides against
    :math:`F_S`. The rest of the curve is an explicit force of the step,
    :func:`seal_friction` with ``v_reg = 0``:

    .. math::
        F_e(v) = β v - (F_S - F_C)\\left(1 - e^{-(v/v_S)^2}\\right)\\mathrm{sgn}(v),

    zero at rest and continuous (it grows as :math:`v^2` from 0), so the sum
    is the curve above without a smoothing parameter. The constraint's own
    softness (``solreffriction`` 2 ms, ``solimpfriction`` 0.9999: MuJoCo's
    stiffest) lets a slide held at 80 % of :math:`F_S` creep by about
    0.3 µm/s; MuJoCo's default (20 ms, 0.9) would creep 3 mm/s
    (``docs/paper-notes.md``, seal friction).
``regularised``
    The whole curve in the pneumatic force with :math:`\\mathrm{sgn}(v)` as
    :math:`\\tanh(v / v_r)`: a smooth map of the present speed, so a leg
    loaded below :math:`F_S` creeps at about
    :math:`v_r\\,\\mathrm{artanh}(F/F_S)`, and the explicit 1 ms coupling stays
    stable only while :math:`h (F_S/v_r + β)` is below twice the slide's
    effective mass. Kept to compare with.
"""

from __future__ import annotations

import math

__all__ = ["seal_friction", "dry_friction_forces"]


def seal_friction(v, f_breakaway, f_coulomb, v_stribeck, viscous, v_reg):
    """The seal friction the step applies explicitly (N) at slide velocity ``v`` (m/s).

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
        ``0``: the ``stick`` model, MuJoCo's dry friction carries F_S and this
        is the rest of the curve, :math:`F_e(v)`; ``> 0``: the ``regularised``
        model's whole curve with ``tanh(v / v_reg)`` (module docstring).

    Returns
    -------
    float
        The force with the sign of the friction on the slide's motion
        (subtract it from the driving force); 0 at rest.
    """
    x = v / v_stribeck
    if v_reg > 0.0:
        peak = f_coulomb + (f_breakaway - f_coulomb) * math.exp(-(x * x))
        return peak * math.tanh(v / v_reg) + viscous * v
    drop = (f_breakaway - f_coulomb) * -math.expm1(-(x * x))
    if v < 0.0:
        drop = -drop
    return viscous * v - drop


def dry_friction_forces(params):
    """Each slide's MuJoCo ``frictionloss`` (N) for the ``pneumatics`` parameters ``params``.

    The breakaway force under the ``stick`` model, 0 under ``regularised``
    (its friction is all in the pneumatic force).
    """
    if params.friction_model == "stick":
        return [float(f) for f in params.breakaway]
    return [0.0, 0.0, 0.0]
