"""What is written and shown: result folders, figures, tables, videos.

- :mod:`.folders`: result folders on disk (whose, the lock, the atomic install, complete).
- :mod:`.results`: what a run writes (``timeseries.csv``, ``metrics.json``) and its summary.
- :mod:`.runner`: one scenario run into a folder (preflight, run, metrics, plots).
- :mod:`.compare`: joint-only vs task-space on the same plant (Fig. 15).
- :mod:`.plots`: a run's figures, a cueing run's too (Agg); :mod:`.identify`,
  :mod:`.analyze`, :mod:`.response`: the figures and tables of those commands.
- :mod:`.recording`, :mod:`.scene`, :mod:`.render`, :mod:`.video_options`,
  :mod:`.viewer`: MP4 replays (MuJoCo offscreen) and the interactive viewer's playback.
- :mod:`.machine`: the machine fingerprint recorded with every result.
"""
