"""What a batch's pool workers load once, before their first variant.

Its import is the work: :func:`simpro_mj.sim.executors.pool_context` has the
workers' forkserver import it (``PRELOAD`` of :mod:`simpro_mj.batch.worker`), and
every worker is forked from that server with these loaded, instead of loading them
itself in its first variant (about 0.8 s of CPU per worker besides the imports, more
than a new cabin's identification under ``identify: reduced``):

* the modules a variant imports on use: the run, its loop, the identification of
  a new plant (the experiment on the reduced chain and its fit), ``scipy.signal``
  (the experiment's maximum-length sequence, 0.6-1.2 s), ``scipy.optimize`` (the
  loop analysis's root finder, 0.5 s);
* what every result folder records and a process reads once: the packages' versions
  and the machine's fingerprint (:func:`simpro_mj.report.results.versions`);
* the compiled step from numba's cache (:func:`simpro_mj.sim.compiling.prepare_step`,
  which waits for another process's compile rather than compiling it twice): code
  loaded into memory, no MuJoCo callback set (each run sets its own);
* the identification's compiled functions (the reduced chain's stepper, the fit's
  filter and normal equations) as numba's cache holds them for this machine
  (:func:`load_cached`: nothing compiled here), with numba's array functions, whose
  import loads scipy's BLAS bindings (0.6 s).

Nothing here starts a thread or builds a MuJoCo model. A failure is left to the
variant that meets it: a worker loads what it lacks itself.
"""

from __future__ import annotations

import contextlib


def load_cached(dispatcher) -> int:
    """Load every overload numba's cache holds of ``dispatcher`` (a ``numba.njit``
    function with a cache) for this machine's code generator and this source;
    compile nothing. Returns how many were loaded."""
    cache, codegen = dispatcher._cache, dispatcher.targetctx.codegen()
    # keyed (signature, the code generator's magic tuple, the source's hashes): an
    # entry for another machine or other code is left alone
    index = cache._cache_file._load_index()
    signatures = [key[0] for key in index if key == cache._index_key(key[0], codegen)]
    for sig in signatures:
        dispatcher.compile(sig)  # in the cache: loaded, not compiled
    return len(signatures)


with contextlib.suppress(Exception):
    import scipy.optimize  # noqa: F401
    import scipy.signal  # noqa: F401

    import simpro_mj.identification.auto
    import simpro_mj.job.run
    import simpro_mj.sim.loop  # noqa: F401
    from simpro_mj.identification import reduced_experiment, sensitivity_fit
    from simpro_mj.plant.kernels import kernel_choice
    from simpro_mj.report.results import versions
    from simpro_mj.sim.compiling import prepare_step

    versions()
    prepare_step()
    if kernel_choice() == "numba":
        import numba.np.arraymath  # noqa: F401

        for compiled in (reduced_experiment._stepper(), *sensitivity_fit._functions()):
            load_cached(compiled)
