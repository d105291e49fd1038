"""What is written: result folders, figures, videos.

- :mod:`.results`: the result folder (atomic, marked, never over a user's file).
- :mod:`.runner`: one scenario run into a folder (preflight, run, metrics, plots).
- :mod:`.plots`, :mod:`.cue_plots`: figures (Agg).
- :mod:`.render`: MP4 replays (MuJoCo offscreen).
- :mod:`.machine`: the machine fingerprint recorded with every result.
"""
