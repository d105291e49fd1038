"""Every key of a scenario with its default, as plain data.

The typed scenario holds every key, its default and what it means as its
fields (:class:`simpro_mj.config.models.Scenario` and its blocks; the plant's
and the sensors' numbers come from :mod:`simpro_mj.plant`, which owns them).
:data:`DEFAULT_SCENARIO` is that tree as a plain dict: what a scenario file is
merged over (:func:`simpro_mj.config.scenario.load_scenario`) and what a
sweep's paths are checked against (:mod:`simpro_mj.config.sweep`).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping

from simpro_mj.config.models import Scenario

__all__ = ["DEFAULT_SCENARIO", "merge"]


def merge(base: Mapping, over: Mapping) -> dict:
    """Deep merge: a copy of ``base`` with ``over`` applied (mappings merge, others replace)."""
    out = copy.deepcopy(dict(base))
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


#: Every key of a scenario with its default (the typed scenario's). A file is merged
#: over this tree.
DEFAULT_SCENARIO: dict = copy.deepcopy(dict(Scenario.defaults()))
