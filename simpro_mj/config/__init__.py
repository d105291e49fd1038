"""The scenario document, validated once at the edge.

- :mod:`.defaults`: every key with its default (``DEFAULT_SCENARIO``).
- :mod:`.presets`: named plants (``simpro_mj/presets/*.yaml``).
- :mod:`.scenario`: loading, ``--set``, checks with one-line errors, the hash.
- :mod:`.sweep`, :mod:`.variants`: a ``sweep:`` block's rules and its variants.
- :mod:`.telemetry`, :mod:`.manoeuvres`, :mod:`.cueing`: set-points from vehicle
  motion (CSV telemetry, CommonRoad manoeuvres, the washout).
"""
