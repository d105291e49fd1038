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

import os
from pathlib import Path

__all__ = [
    "shipped_dir",
    "model_path",
    "MODEL_DIR",
    "SCENARIOS_DIR",
    "TELEMETRY_DIR",
    "PRESETS_DIR",
]

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


def model_path() -> Path:
    """The MJCF a run compiles: ``$SIMPRO_MODEL`` when set, else the shipped one."""
    return Path(os.environ.get("SIMPRO_MODEL") or MODEL_DIR / "simpro_platform.xml")
