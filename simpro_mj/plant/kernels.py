"""How the 1 ms step runs: the ``SIMPRO_KERNEL`` switch.

``SIMPRO_KERNEL`` = ``auto`` (default: numba if it is importable), ``python``
or ``numba`` (an error if numba is missing), read when a run starts
(:meth:`simpro_mj.sim.loop.CoSimulation.run`): ``numba`` compiles the step
(:mod:`simpro_mj.sim.step`) into MuJoCo's control callback, ``python`` runs
the same functions interpreted (the readable reference, for debugging; several
times slower). numba is a dependency of the package; ``auto`` still runs the
step interpreted where it cannot be installed. This module only asks whether
it is installed, it never imports it (its import costs ~0.2 s).
"""

from __future__ import annotations

import importlib.util
import os
from importlib import metadata

from simpro_mj.core.errors import UserInputError

KERNEL_CHOICES = ("auto", "python", "numba")

_HAVE_NUMBA = importlib.util.find_spec("numba") is not None


def kernel_choice() -> str:
    """The kernel selected by ``SIMPRO_KERNEL``: ``"python"`` or ``"numba"``.

    Raises
    ------
    UserInputError
        An unknown value, or ``numba`` requested but not installed.
    """
    raw = os.environ.get("SIMPRO_KERNEL", "auto")
    value = raw.strip().lower()
    if value not in KERNEL_CHOICES:
        raise UserInputError(
            f"invalid value at SIMPRO_KERNEL: {raw!r}; allowed: one of {list(KERNEL_CHOICES)}"
        )
    if value == "auto":
        return "numba" if _HAVE_NUMBA else "python"
    if value == "numba" and not _HAVE_NUMBA:
        raise UserInputError("SIMPRO_KERNEL=numba but numba is not installed: pip install numba")
    return value


def kernel_label() -> str:
    """``"numba 0.68.1"`` or ``"python"``: how the next run's step will run."""
    try:
        return "python" if kernel_choice() == "python" else f"numba {metadata.version('numba')}"
    except UserInputError:
        return "invalid"
    except metadata.PackageNotFoundError:  # pragma: no cover - a bare source tree
        return "numba unknown"
