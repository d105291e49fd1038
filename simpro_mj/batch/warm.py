"""What a batch's pool workers load once, before their first variant.

Its import is the work: :func:`simpro_mj.sim.executors.pool_context` has the
workers' forkserver import it (``PRELOAD`` of :mod:`simpro_mj.batch.worker`), and
every worker is forked from that server with these modules loaded, instead of
importing them itself (about a second of CPU per worker, more than a new cabin's
identification under ``identify: reduced``):

* the modules a variant imports on use: the run, its loop, the identification of
  a new plant (the experiment on the reduced chain and its fit);
* the compiled step from numba's cache (:func:`simpro_mj.sim.compiling.prepare_step`,
  which waits for another process's compile rather than compiling it twice): code
  loaded into memory, no MuJoCo callback set (each run sets its own).

Nothing here starts a thread or builds a MuJoCo model. A failure is left to the
variant that meets it: a worker imports what it lacks itself.
"""

from __future__ import annotations

import contextlib

with contextlib.suppress(Exception):
    import simpro_mj.identification.auto
    import simpro_mj.identification.reduced_experiment
    import simpro_mj.identification.sensitivity_fit
    import simpro_mj.job.run
    import simpro_mj.sim.loop  # noqa: F401
    from simpro_mj.sim.compiling import prepare_step

    prepare_step()
