"""The scenario document, validated once at the edge.

- :mod:`.defaults`: every key with its default (``DEFAULT_SCENARIO``).
- :mod:`.presets`: named plants (``scenarios/presets/*.yaml``).
- :mod:`.scenario`: loading, ``--set``, the hash ``--resume`` compares.
- :mod:`.models`, :mod:`.plant_blocks`, :mod:`.pneumatics`, :mod:`.entries`,
  :mod:`.cue_models`, :mod:`.rules`: the typed scenario (pydantic v2): one model per
  block (``Scenario``), each field with its default, unit, range and meaning; the
  tagged set-point components and faults; the one error formatter
  (``<what> at <dotted.path>: <allowed>``).
- :mod:`.parameters`: every parameter as rows (``simpro-sim show``).
- :mod:`.reference`: the set-point poses of a scenario and their reachability.
- :mod:`.sweep`, :mod:`.variants`: a ``sweep:`` block's rules and its variants.
- :mod:`.telemetry`, :mod:`.manoeuvres`, :mod:`.cueing`: set-points from vehicle
  motion (CSV telemetry, CommonRoad manoeuvres, the washout).
"""
