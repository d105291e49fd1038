"""The identification experiment's law (Fig. 12) as a stage of the 1 ms step.

The paper identifies each actuator with the others held: every leg runs a
proportional position loop around its holding voltage, and the leg under
test gets an excitation on top (:mod:`simpro_mj.identification.identify`).
Here that law is a plain function the step (:mod:`simpro_mj.sim.step`) runs,
interpreted or compiled, in place of the joint controllers when its
constants say so (``XC.on``)::

    u_i = clip(u_hold,i + K_p,i (q_ref - q_i) + w[k] + [i = leg] x[k], lo, hi)

with ``w[k]`` the valves' dither and ``x[k]`` the excitation, read by step
index from the step's feed-forward input (columns 0 and 1). With ``leg`` 3 every
leg is excited at once, each by its own column (``w[k] + x_i[k]`` in column i).
The law acts on the slides' true positions (the experiment's own loop, not the rig's
potentiometers), summed in this order so that a record is the same number
for number whichever way the step runs.
"""

from __future__ import annotations

from .layout import layout

#: The experiment's constants: on (1) or not (0: the joint controllers act), the leg
#: under test (0-2; 3: all three at once), q_ref (m), per leg K_p (V/m) and the holding
#: voltage (V), the valves' range (V)
XC = layout("ExperimentConstants", on=1, leg=1, qref=1, kp=3, hold=3, lo=1, hi=1)


def experiment_volts(k, q, xc, exc, u):
    """The experiment's volts at step ``k`` into ``u`` (3,) (module docstring).

    ``q`` (3,): the slides (m); ``xc``: the constants (:data:`XC`); ``exc``:
    rows by step, the dither (column 0, every valve) and the excitation
    (column 1, the leg under test); with every leg under test, column i leg i's.
    """
    leg, qref, lo, hi = int(xc[XC.leg]), xc[XC.qref], xc[XC.lo], xc[XC.hi]
    for i in range(3):
        if leg > 2:
            v = (qref - q[i]) * xc[XC.kp + i] + xc[XC.hold + i] + exc[k, i]
        else:
            v = (qref - q[i]) * xc[XC.kp + i] + xc[XC.hold + i] + exc[k, 0]
        if i == leg:
            v = v + exc[k, 1]
        if v < lo:  # comparisons: a NaN passes through
            v = lo
        if v > hi:
            v = hi
        u[i] = v
