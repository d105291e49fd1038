"""One run of a scenario as one object: built once, checked, stepped, measured.

:class:`~simpro_mj.job.run.Run` is dm_control's ``Environment`` around the
``Physics`` (:class:`~simpro_mj.plant.platform.Platform`) and the ``Task``
(the controllers :class:`~simpro_mj.sim.loop.CoSimulation` builds): it
resolves the design plants, compiles the model and evaluates the set-points
once, runs the preflight on those same objects, steps, measures, and returns
a typed :class:`~simpro_mj.job.run.RunOutcome`. It writes nothing;
:mod:`simpro_mj.report` writes what it is given.
"""
