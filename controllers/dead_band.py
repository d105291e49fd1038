"""Dead band around the set-point: what a loop with an integrator needs against dry friction.

A leg with Coulomb (and breakaway) seal friction ``F_c`` cannot be moved by a
force below ``F_c``. An integrator in the loop (eq. 28's ``1/s`` in the joint
loops, eq. 22's I law in the task-space loop) keeps integrating the small error
that friction holds until the valve force breaks the leg free; the leg then
slips past the set-point and the integrator winds the other way: a stick-slip
limit cycle ("hunting"). On the heavy cabin with 150 N Coulomb per leg it is
1.0 Hz, pitch +-0.25 deg (docs/paper-notes.md, dead bands).

A dead band of width ``w`` gives zero error inside ``[-w, w]`` (the
integrator holds, the remaining controller states relax) and ``e -+ w``
outside: once the response is within the band the loop stops pushing against
friction. It bounds the steady-state error by ``w``, so it is chosen below the
accuracy the loop must give (the verdict's floors 0.02 deg and 0.2 mm in the
task space) and above what friction holds (``F_c / (k_p`` times the force per
volt) in the joints).

Plain scalar functions on floats (``math`` only): the same source runs in the
compiled step.
"""

from __future__ import annotations

__all__ = ["dead_band"]


def dead_band(e: float, width: float) -> float:
    """``e - width`` above ``width``, ``e + width`` below ``-width``, else 0.

    Continuous (``width >= 0``; 0 passes every error unchanged): a band that
    passed ``e`` itself would step the output by ``k_p width`` where the error
    leaves it (5.9 V for leg 1's 5.9 kV/m and 1 mm), a relay that chatters.
    """
    if width <= 0.0:
        return e
    if e > width:
        return e - width
    if e < -width:
        return e + width
    if e == e:  # inside the band (a NaN passes, as the loop would see it)
        return 0.0
    return e
