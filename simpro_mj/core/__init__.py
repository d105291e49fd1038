"""The base every room stands on (imports nothing of the project).

- :mod:`.errors`: ``UserInputError`` (a ``ValueError``), ``PhysicsError`` and the others.
- :mod:`.messages`: an exception as one line (the CLI's errors, a task's reason).
- :mod:`.keys`: dotted keys (``--set KEY=VALUE``), key checks and their one-line
  messages (``closest`` valid key, allowed values).
- :mod:`.safe_yaml`: YAML without aliases bombs or non-finite surprises.
- :mod:`.jsonout`: the ``--json`` contract (one JSON object on stdout).
- :mod:`.rates`: the physics timestep; a period as a whole number of steps.
- :mod:`.interrupts`: Ctrl-C and SIGTERM as ``KeyboardInterrupt``, held while an
  import or a result folder's write runs.
"""
