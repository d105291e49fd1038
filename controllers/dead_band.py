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

from typing import Literal

#: How a band shapes the error an integrator takes: :func:`dead_band` (``subtract``)
#: or :func:`gap`.
BandKind = Literal["subtract", "gap"]


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


def gap(e: float, width: float) -> float:
    """``e`` outside ``[-width, width]``, 0 inside: a gap in what an integrator takes.

    Discontinuous, so only for an integrator's input, whose output stays
    continuous: the task-space I law then integrates the whole error until the
    pose is within the band, where :func:`dead_band` slows to ``e - width`` on the
    last stretch (a 2 deg roll step held by the seals 0.09 deg short of its
    set-point creeps in at 0.04 deg of error under a 0.05 deg band). A leg's
    proportional action needs the continuous :func:`dead_band` instead.
    """
    if width > 0.0 and -width <= e <= width:
        return 0.0
    return e


def held(e: float, width: float, release: float, flags, k: int) -> bool:
    """Whether a band with a release holds ``e``; ``flags[k]`` is the hold's state.

    With ``release`` r > 1 the band holds from the step the error enters
    ``[-width, width]`` until it leaves ``[-r width, r width]`` (a hysteresis):
    a seal's slip that lands within ``r width`` does not restart the integrator
    whose push would cause the next slip, landing anywhere within the band again
    (Armstrong-Hélouvry, Dupont & Canudas de Wit 1994, section 6). ``r`` 1: never
    held here (the caller's band alone). ``flags[k]`` is set while held, cleared on
    release.
    """
    if release <= 1.0:
        return False
    if flags[k] != 0.0:
        if -release * width <= e <= release * width:
            return True
        flags[k] = 0.0
    elif -width <= e <= width:
        flags[k] = 1.0
        return True
    return False
