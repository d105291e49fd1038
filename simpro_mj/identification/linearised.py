"""``controller.inner.identify: linearised``: the experiment's linear model in place of
the experiment.

Eq. (19)'s b, a1, a0 per leg are fitted, by the experiment's own fit, to the linear
model of the whole Fig. 12 set-up (:mod:`simpro_mj.identification.linear_experiment`:
the reduced chain, each leg's pneumatics, the other legs under the experiment's P
loops, the spool, the seals by their random-input describing function) instead of
to a MuJoCo record: no experiment and no cache entry (about the experiment's CPU).
On the ``paper`` preset it agrees with the experiment within 0.8 % on leg 1 and
1.9 % on legs 2 and 3 (docs/paper-notes.md, section 2).

A plant whose seals' dry friction dominates the experiment is refused in one line:
where the describing function's equivalent viscous friction of the excited leg
exceeds the seal's own viscous coefficient (the Coulomb force above the viscous
force at the leg's RMS speed), the real experiment is a stick-slip (the heavy
cabin's leg 1 is at rest 63 % of its record and slips in bursts: an RMS speed 3.7
times the describing function's), which no linear model of the experiment
represents; the identified design (``auto``) stays the procedure there.
"""

from __future__ import annotations

from simpro_mj.core.errors import UserInputError
from simpro_mj.identification.linear_experiment import LegResult, identify_linear

__all__ = ["linearise", "dominated_by_dry_friction"]


def dominated_by_dry_friction(leg: int, res: LegResult, friction) -> bool:
    """True when leg ``leg``'s seal's equivalent viscous friction in its own experiment
    exceeds the seal's viscous coefficient (module docstring)."""
    beta = friction[leg - 1][1][3]
    return bool(res.c_eq[leg - 1] > beta)


def linearise(tree: dict, model=None) -> dict:
    """Eq. (19)'s b, a1, a0 per actuator from the experiment's linear model (module
    docstring); ``{actuator: {b, a1, a0}}`` in SI (m/V), as the experiment's fit.

    ``tree`` is an identification tree (:func:`simpro_mj.identification.settings.default_tree`
    with the scenario's plant, :func:`simpro_mj.identification.auto.plant_tree`).

    Raises
    ------
    UserInputError
        A plant whose seals' dry friction dominates the experiment.
    """
    from simpro_mj.identification.linear_experiment import build

    em = build(tree, model)
    details: dict = {}
    got = identify_linear(tree, details=details, experiment=em)
    for i in (1, 2, 3):
        res = details[f"actuator{i}"]
        if dominated_by_dry_friction(i, res, em.friction):
            raise UserInputError(
                "invalid value at controller.inner.identify: linearised: the seals' dry "
                f"friction dominates actuator {i}'s experiment (equivalent viscous friction "
                f"{res.c_eq[i - 1]:.3g} N s/m against the seal's "
                f"{em.friction[i - 1][1][3]:.3g}: a stick-slip no linear model represents); "
                "allowed: auto (the identification experiment) or preset"
            )
    return {a: fit.model() for a, fit in got.items()}
