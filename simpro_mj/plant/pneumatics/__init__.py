"""Electro-pneumatic actuators of the SIMPRO platform: valve + cylinder, per leg.

Each leg has a FESTO MPYE-5-3/8 proportional 5/3 valve (0-10 V, 5 V closed
centre) feeding a FESTO DNC-125-500 double-acting cylinder. The actuators
turn valve voltages into the net force on each MuJoCo slide joint; the
multibody supplies mass, gravity and load (they are not duplicated here).

One module per concept, imported by its own path (this file imports none of
them, so that reading the parameters never loads MuJoCo):

- :mod:`.params`: :data:`~.params.DEFAULT_PNEUMATIC_PARAMS`, the SI record
  :class:`~.params.PneumaticParams` and its checks (no MuJoCo: the scenario
  validates ``actuator.pneumatics`` with it);
- :mod:`.flow`: the orifice flow law of ISO 6358 with a laminar end;
- :mod:`.nonlinear`: :class:`~.nonlinear.NonlinearActuators` (spool lag,
  metering edges, polytropic chambers, friction), with the optional compiled
  step in :mod:`.kernel` (numba, the same bits);
- :mod:`.linear`: :class:`~.linear.LinearActuators`, the paper's eq. (19);
- :mod:`.statics` (MuJoCo): the closed chain reduced to the slides, the
  holding forces;
- :mod:`.factory` (MuJoCo): :func:`~.factory.make_actuators`, the interface
  the co-simulation uses (``reset``, ``step(u, q, q_dot, dt) -> forces``).
"""
