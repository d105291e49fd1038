"""The scenario document, validated once at the edge.

- :mod:`.defaults`: every key with its default (``DEFAULT_SCENARIO``).
- :mod:`.presets`: named plants (``scenarios/presets/*.yaml``).
- :mod:`.scenario`: loading, ``--set``, the hash ``--resume`` compares.
- :mod:`.models`, :mod:`.entries`, :mod:`.rules`: the typed scenario (pydantic v2):
  one model per block (``Scenario``), the tagged set-point components and faults,
  the limits and the one-line messages (``<what> at <dotted.path>: <allowed>``).
- :mod:`.reference`: the set-point poses of a scenario and their reachability.
- :mod:`.sweep`, :mod:`.variants`: a ``sweep:`` block's rules and its variants.
- :mod:`.telemetry`, :mod:`.manoeuvres`, :mod:`.cueing`: set-points from vehicle
  motion (CSV telemetry, CommonRoad manoeuvres, the washout).
"""
