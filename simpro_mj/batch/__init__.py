"""Many runs: a sweep file's variants planned, run and tabulated.

- :mod:`.plan`: the inputs expanded into rows (variants to run, invalid entries).
- :mod:`.worker`: one variant run headless into its result folder.
- :mod:`.runner`: the batch on an executor, stopped cleanly, resumed (``simpro-sim batch``).
- :mod:`.stability`: a variant's measured stability and its analysed limit.
- :mod:`.summary`, :mod:`.tables`: the rows, ``summary.csv``/``summary.json``; the
  stability-limit and Monte Carlo tables and the printed summary.
- :mod:`.plots`: the sweep figures.
"""
