"""Where the shipped data lives: the model, the scenarios, their telemetry and the presets.

The repository keeps them at its top level, as the design card lays it out::

    models/simpro_platform.xml      the MJCF (models/README.md: its assumptions)
    scenarios/*.yaml                the shipped scenarios, found by name
    scenarios/telemetry/*.csv       the vehicle drives the cueing scenarios replay
    scenarios/presets/*.yaml        the named plants a scenario's plant.preset picks

The build maps them into the package (``setup.py``: ``models/`` is
``simpro_mj/models``, ``scenarios/`` is ``simpro_mj/scenarios``), so an
installed wheel carries them and ``simpro-sim run step_pitch.yaml`` works from
any folder. :func:`shipped_dir` is the one place that knows both places: a
checkout (an editable install) reads the top-level folders, an installed wheel
its package's copy.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.safe_files import open_regular, read_bytes

_PACKAGE = Path(__file__).resolve().parents[1]  # simpro_mj/
_CHECKOUT = _PACKAGE.parent


def shipped_dir(name: str) -> Path:
    """The folder of shipped data ``name`` (``"models"`` or ``"scenarios"``).

    In a checkout (``pyproject.toml`` beside the package, as an editable
    install leaves it) the repository's top-level folder; otherwise the copy
    the build put inside the package.
    """
    top = _CHECKOUT / name
    if (_CHECKOUT / "pyproject.toml").is_file() and top.is_dir():
        return top
    return _PACKAGE / name


#: The MJCF's folder.
MODEL_DIR = shipped_dir("models")
#: The shipped scenarios (``$SIMPRO_SCENARIOS`` points elsewhere, see ``config.scenario``).
SCENARIOS_DIR = shipped_dir("scenarios")
#: The shipped vehicle telemetry (CSV).
TELEMETRY_DIR = SCENARIOS_DIR / "telemetry"
#: The shipped plant presets.
PRESETS_DIR = SCENARIOS_DIR / "presets"
#: Largest MJCF read (bytes): the shipped one is about 20 kB.
MAX_MODEL_BYTES = 5_000_000


def user_path(text, where: str) -> Path:
    """``text`` as a path with ``~`` and ``~USER`` expanded; an unknown user is a
    user's mistake at ``where`` (one line), not an internal error."""
    try:
        return Path(text).expanduser()
    except RuntimeError:  # pathlib: "Could not determine home directory."
        user = str(text)[1:].split("/", 1)[0]
        raise UserInputError(
            f"unknown user at {where}: {str(text)[:200]!r}: no user {user[:50]!r} on this "
            "machine; allowed: a path, ~/... or ~USER/... of an existing user"
        ) from None


def model_path() -> Path:
    """The MJCF a run compiles: ``$SIMPRO_MODEL`` when set, else the shipped one.

    Raises
    ------
    UserInputError
        ``$SIMPRO_MODEL`` is not a readable regular file of at most
        :data:`MAX_MODEL_BYTES` (missing, a folder, a FIFO, ``/dev/zero``: checked
        without blocking) or names an unknown ``~USER``.
    """
    given = os.environ.get("SIMPRO_MODEL")
    if not given:
        return MODEL_DIR / "simpro_platform.xml"
    path = user_path(given, "SIMPRO_MODEL")
    try:
        with open_regular(path, MAX_MODEL_BYTES, "MJCF", binary=True):
            pass
    except UserInputError as exc:
        raise UserInputError(
            f"invalid value at SIMPRO_MODEL: {exc}; unset it for the shipped model"
        ) from None
    return path


def model_digest() -> str:
    """SHA-256 of the MJCF's bytes (:func:`model_path`): part of every key of a result
    or cache computed from the model."""
    path = model_path()
    st = path.stat()
    key = (str(path), st.st_mtime_ns, st.st_size)
    if key not in _DIGESTS:  # read once per file version: a batch hashes every variant
        _DIGESTS[key] = hashlib.sha256(read_bytes(path, MAX_MODEL_BYTES, "MJCF")).hexdigest()
    return _DIGESTS[key]


_DIGESTS: dict[tuple, str] = {}
