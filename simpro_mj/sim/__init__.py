"""The co-simulation: one 1 ms step, many steps, many runs.

- :mod:`.loop`: ``CoSimulation`` (plant, sensors, controllers; the multi-rate loop).
- :mod:`.readiness`: the readiness file a waiting test or tool watches.
- :mod:`.workers`, :mod:`.executors`: many tasks on a spawn pool or on Dask.
"""
