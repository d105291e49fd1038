"""The co-simulation: one 1 ms step, many steps, many runs.

- :mod:`.loop`: ``CoSimulation`` (plant, sensors, controllers; the multi-rate loop).
- :mod:`.stages`: the stage functions the loop's body calls (controllers per
  mode, the log row, faults as stage swaps, profiling as wrappers).
- :mod:`.result`: ``SimResult`` and the logged columns.
- :mod:`.readiness`: the readiness file a waiting test or tool watches.
- :mod:`.workers`, :mod:`.executors`: many tasks on a spawn pool or on Dask.
"""
