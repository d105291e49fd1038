"""numba's on-disk cache of the compiled step: a folder that works, files that load.

numba loads a cached function with ``pickle``: a truncated ``.nbi`` (index) or
``.nbc`` (object code) raises inside the first call of the step, an internal
error on every run until the file is deleted. And a ``NUMBA_CACHE_DIR`` that
is not a writable folder made numba fall back, silently, to compiling every
run (23.8 s instead of 1.4 s) and to writing into the package's folders. So:

* :func:`cache_base` picks the folder: ``NUMBA_CACHE_DIR`` if it is (or can be
  made) a writable folder, else, said in one line, the user's cache folder;
* :func:`jit` and :func:`cfunc` compile a function with its cache in a folder
  passed to them, not in ``numba.config.CACHE_DIR`` (which every function of
  the process would share);
* :func:`first_compile` lets one process compile a folder that is not yet
  complete while the others wait for it and then load the cache (two first
  runs at once, a batch's worker processes, the test suite's workers), instead
  of each compiling the same half minute on cores they share;
* a function's cache that does not load is healed where numba loads it
  (:func:`heal` on that function's files only: a run loads the two C
  callbacks' entries, not the hundred files of every function in the
  folder): a file that does not read to its end is deleted with a one-line
  notice and the function compiled again. An object file is parsed, not
  loaded: loading it rebuilds the function's environment, which imports the
  module that defined it; what numba's own load raised is raised again when
  no file is damaged.
"""

from __future__ import annotations

import contextlib
import functools
import os
import pickle
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no lock, each process compiles its own
    fcntl = None  # type: ignore[assignment]

from simpro_mj.core.cache import notice

#: The file that marks a cache folder complete: every function of the step was
#: compiled (or loaded) into it by a process that then finished its import.
COMPLETE = "complete"

#: What a process is told while another one compiles the step into the same folder.
WAIT_NOTE = "waiting for another process compiling the 1 ms step into the same cache"


def _writable(folder: str) -> bool:
    """Whether ``folder`` is, or can be made, a folder this process can write in."""
    try:
        os.makedirs(folder, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def cache_base(package_dir: str, say: Callable[[str], None] = notice) -> str:
    """The folder under which the step's cache lives.

    ``NUMBA_CACHE_DIR`` when set and writable (else said, and not used), then
    ``package_dir`` (``__pycache__`` beside the step, an editable install), then
    ``$XDG_CACHE_HOME`` or ``~/.cache``, then the temporary folder.
    """
    given = os.environ.get("NUMBA_CACHE_DIR")
    user = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    fallbacks = [package_dir, os.path.join(user, "simpro-sim"), tempfile.gettempdir()]
    if given:
        if _writable(given):
            return given
        fallback = next((f for f in fallbacks[1:] if _writable(f)), None)
        say(
            f"notice: NUMBA_CACHE_DIR={given[:200]} is not a writable folder; the compiled "
            + (f"step is cached in {fallback}" if fallback else "step is compiled on every run")
        )
        return fallback or given
    return next((f for f in fallbacks if _writable(f)), fallbacks[-1])


@contextlib.contextmanager
def first_compile(folder: str, say: Callable[[str], None] | None = None) -> Iterator[None]:
    """Hold ``folder`` for a compile into it, unless it is complete (:data:`COMPLETE`).

    An exclusive ``flock`` on a file in the folder: the first process compiles
    inside the ``with``, a second one waits (said once, :data:`WAIT_NOTE`) and
    then finds the functions in numba's cache. The kernel releases the lock of a
    process that dies, so a crash leaves nothing to clean. The folder is marked
    complete when the body ends without an exception; after that no lock is taken,
    and concurrent loads of the cache do not wait for each other.
    """
    done = os.path.join(folder, COMPLETE)
    if fcntl is None or os.path.exists(done):
        yield
        return
    try:
        os.makedirs(folder, exist_ok=True)
        fh = open(os.path.join(folder, ".compile-lock"), "a")  # noqa: SIM115 - held below
    except OSError:  # a folder we cannot write: numba compiles without its cache anyway
        yield
        return
    with fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if say is not None:
                say(WAIT_NOTE)
            fcntl.flock(fh, fcntl.LOCK_EX)
        yield  # closing the file releases the lock
        with contextlib.suppress(OSError):
            Path(done).touch()


def _loads(path: Path) -> None:
    """Read a numba cache file as numba does (``caching.IndexDataCacheFile``); raises
    if it is damaged.

    An index (``.nbi``: the version, then the stamp and the table of overloads, numba's
    own types) is loaded. An object file (``.nbc``) is parsed opcode by opcode to its
    ``STOP`` (:func:`pickletools.genops`; ``pickle.loads`` also stops there): a
    truncated or garbled file raises, and no module is imported, no object built.
    """
    import pickletools  # its opcode tables: only for a load that failed (14 ms)

    with open(path, "rb") as fh:
        if path.suffix == ".nbi":
            pickle.load(fh)  # the version
            stamp, overloads = pickle.loads(fh.read())
            if not isinstance(overloads, dict):
                raise ValueError("an index without its table")
            return
        data = fh.read()
    if not any(op.name == "STOP" for op, _arg, _pos in pickletools.genops(data)):
        raise ValueError("a pickle without its end")


def heal(files: Iterable[Path], say: Callable[[str], None] = notice) -> list[Path]:
    """Delete those of ``files`` that do not load (said, one line each); returns
    them. Only ``*.nbi`` and ``*.nbc`` files, numba's."""
    removed = []
    for path in sorted(Path(f) for f in files if Path(f).suffix in (".nbi", ".nbc")):
        try:
            _loads(path)
        except Exception as exc:  # noqa: BLE001 - whatever unpickling a damaged file raises
            try:
                path.unlink()
            except OSError:
                continue
            removed.append(path)
            why = type(exc).__name__
            say(f"notice: numba cache file {path} is damaged ({why}); the step is compiled again")
    return removed


@functools.cache
def _cache_class(folder: str):
    """numba's function cache with its files under ``folder`` (one class per folder:
    numba asks a locator *class* for the place)."""
    from numba.core import caching

    class Locator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
        # numba's UserProvidedCacheLocator with the folder given, not config.CACHE_DIR:
        # the same sub-path per source folder, so the files are where numba puts them
        def __init__(self, py_func, py_file):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = os.path.join(folder, self.get_suitable_cache_subpath(py_file))

        def get_cache_path(self):
            return self._cache_path

    class Impl(caching.CompileResultCacheImpl):
        _locator_classes = [Locator]

    class FolderCache(caching.FunctionCache):
        _impl_class = Impl

        def load_overload(self, sig, target_context):
            # numba's own first refreshes the target context: it starts numba's runtime
            # (NRT, whose symbols the object code links to) and imports and installs
            # every registry of implementations (through numba's arraymath, scipy.linalg
            # too), about 0.4 s of CPU that only a compile needs; a compile refreshes
            # the context itself (numba's CompilerBase). A cached function is rebuilt
            # from its object code with the runtime alone.
            from numba.core.runtime import rtsys

            rtsys.initialize(target_context)
            try:
                with self._guard_against_spurious_io_errors():
                    return self._load_overload(sig, target_context)
            except Exception:  # noqa: BLE001 - whatever unpickling a damaged file raises
                # a file that does not read to its end is deleted (said) and the
                # function compiled again; any other failure is numba's to report
                if not heal(self._files()):
                    raise  # no file of the function is damaged: not ours to hide
            return None  # numba compiles the function and saves it again

        def _files(self) -> list[Path]:
            """This function's index and object files (``NAME.nbi``, ``NAME.N.nbc``)."""
            cache = self._cache_file
            index = Path(cache._index_path)
            stem = index.name[: -len(".nbi")] + "."
            try:
                objects = [p for p in index.parent.iterdir() if p.name.startswith(stem)]
            except OSError:
                objects = []
            return [index, *(p for p in objects if p.suffix == ".nbc")]

    return FolderCache


def jit(folder: str) -> Callable:
    """The decorator ``numba.njit(cache=True)`` with the cache under ``folder``."""
    import numba

    def wrap(func: Callable):
        dispatcher = numba.njit(func)
        # what numba's enable_caching() sets, with the folder: numba has no public way
        dispatcher._cache = _cache_class(folder)(func)  # type: ignore[attr-defined]
        return dispatcher

    return wrap


def cfunc(signature, folder: str) -> Callable:
    """The decorator ``numba.cfunc(signature, cache=True)`` with the cache under ``folder``."""
    from numba.core import sigutils
    from numba.core.ccallback import CFunc

    def wrap(func: Callable):
        compiled = CFunc(func, sigutils.normalize_signature(signature), locals={}, options={})
        compiled._cache = _cache_class(folder)(func)  # type: ignore[attr-defined]
        compiled.compile()
        return compiled

    return wrap
