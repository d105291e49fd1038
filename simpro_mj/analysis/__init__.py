"""What is computed from the plant and from runs.

- :mod:`.metrics`: step and tracking figures of a run.
- :mod:`.stability`: the task-space loop around the joint loops, analysed (one
  function for the preflight and the batch).
- :mod:`.preflight`: checks before a run (stability limit, payload).
- :mod:`.analyze`, :mod:`.response`, :mod:`.response_summary`, :mod:`.chain_response`:
  the loops' analysis and the closed-loop frequency responses (pose; vehicle to head).
- :mod:`.calibrate`: fit the plant to the paper's identified models.
- :mod:`.validate_ik`: Fig. 11's IK validation.
"""
