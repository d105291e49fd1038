"""Many runs: a sweep file's variants planned, run and tabulated; the speed bench.

- :mod:`.batch`: plan, worker, stability of a variant, tables (``simpro-sim batch``).
- :mod:`.plots`: the sweep figures.
- :mod:`.bench`: ``simpro-sim bench``.
"""
