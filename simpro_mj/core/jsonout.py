"""The ``--json`` contract: one JSON object on stdout and nothing else there.

Its own module so that every command can print JSON without importing
:mod:`simpro_mj.commands.main` (which imports the commands: imports run one way).
"""

from __future__ import annotations

import json
import sys
from dataclasses import asdict, is_dataclass


def emit_json(obj) -> None:
    """Print one JSON object on stdout (numpy scalars and arrays as plain numbers, a
    dataclass record as its fields)."""
    json.dump(obj, sys.stdout, indent=2, sort_keys=False, default=_json_default)
    sys.stdout.write("\n")


def _json_default(o):
    if is_dataclass(o) and not isinstance(o, type):
        return asdict(o)
    if hasattr(o, "tolist"):  # a numpy scalar (its Python number) or array (lists)
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
