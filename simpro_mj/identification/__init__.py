"""Fig. 12's experiment: identify each leg's plant (eqs. 34-35).

- :mod:`.identify`: a PRBS on the valves, the legs' velocity recorded, second-order
  models fitted (``simpro-sim identify``).
- :mod:`.auto`: ``design_plant: identified`` identifies the scenario's own plant
  before it runs, with a cache.

It sits below ``sim``: the co-simulation designs its joint loops from these models.
"""
