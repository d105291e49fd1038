"""The scenario document, validated once at the edge.

- :mod:`.presets`: named plants (``scenarios/presets/*.yaml``).
- :mod:`.scenario`: loading, ``--set``, the hash ``--resume`` compares, every parameter
  as rows (``simpro-sim show``), what ships (``simpro-sim list``).
- :mod:`.models`, :mod:`.plant_blocks`, :mod:`.pneumatics`, :mod:`.entries`,
  :mod:`.cue_models`, :mod:`.rules`: the typed scenario (pydantic v2): one model per
  block (``Scenario``; ``DEFAULT_SCENARIO`` its defaults as a plain tree), each field
  with its default, unit, range and meaning; the tagged set-point components and
  faults; the one error formatter (``<what> at <dotted.path>: <allowed>``).
- :mod:`.reference`: the set-point poses of a scenario and their reachability.
- :mod:`.sweep`, :mod:`.variants`: a ``sweep:`` block's rules and its variants.
- :mod:`.telemetry`, :mod:`.manoeuvres`, :mod:`.cueing`: set-points from vehicle
  motion (CSV telemetry, CommonRoad manoeuvres, the washout).
"""
