"""Every parameter of a scenario as rows: key, value, default, unit, allowed, meaning.

Read from the typed scenario's fields (:mod:`simpro_mj.config.models` and the
blocks it holds): the defaults, the units, the constraints and the one-line
descriptions declared with :func:`~simpro_mj.config.rules.param`. What
``simpro-sim show`` prints; nothing here is written twice.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, Literal, get_args, get_origin

from pydantic.fields import FieldInfo

from simpro_mj.config.messages import (
    is_model,
    item_meta,
    range_text,
    strip,
    tagged_members,
    unit_of,
)
from simpro_mj.config.models import Scenario, as_tree
from simpro_mj.config.rules import ONE_FOR_ALL, PHYSICS_DT_MS, Block, check_period

__all__ = ["Parameter", "parameters"]


@dataclass(frozen=True)
class Parameter:
    """One parameter of a scenario."""

    key: str  #: dotted path (``actuator.pneumatics.supply_pressure_bar_gauge``)
    value: Any  #: the run's value (the resolved scenario's)
    default: Any  #: the schema's default (before any preset or file)
    unit: str  #: edge unit ("" for a number without one, a choice or a flag)
    allowed: str  #: the allowed values or range
    meaning: str  #: one line

    def as_dict(self) -> dict:
        return asdict(self)


def _allowed(field: FieldInfo) -> str:
    tp, meta = strip(field.annotation)
    meta = [*field.metadata, *meta]
    if get_origin(tp) is Literal:
        return "one of " + ", ".join(map(str, get_args(tp)))
    if tp is bool:
        return "true or false"
    if tp is str:
        return "text"
    if any(getattr(m, "func", None) is check_period for m in meta):
        return f"a whole number of {PHYSICS_DT_MS:g} ms steps, <= 10000"
    rng = range_text(meta)
    extra = field.json_schema_extra
    if not rng and isinstance(extra, dict) and extra.get("range"):
        rng = str(extra["range"]).split(" (", 1)[0]  # the plant's range, its reason left out
    if get_origin(tp) is list:
        item = get_args(tp)[0]
        if tagged_members(item):
            return "list of: " + ", ".join(tagged_members(item))
        n = next((m.min_length for m in meta if hasattr(m, "min_length")), None)
        each = range_text(item_meta(tp))
        text = f"{n} numbers" if n else "numbers"
        if any(m is ONE_FOR_ALL for m in meta):
            text = f"one or {text}"
        return f"{text}, each {each}" if each else text
    if tp is int:
        return f"integer {rng}".strip()
    return rng or "number"


def _rows(model: type[Block], value: Mapping, default: Mapping, prefix: str) -> list[Parameter]:
    out = []
    for name, field in model.model_fields.items():
        if name not in value:  # a block the scenario does not have (setpoint.cueing)
            continue
        key = f"{prefix}{name}"
        tp, _ = strip(field.annotation)
        here, base = value.get(name), default.get(name)
        if is_model(tp) and issubclass(tp, Block) and isinstance(here, Mapping):
            out += _rows(tp, here, base if isinstance(base, Mapping) else {}, f"{key}.")
            continue
        out.append(
            Parameter(key, here, base, unit_of(field), _allowed(field), field.description or "")
        )
    return out


def parameters(resolved: Scenario | Mapping) -> list[Parameter]:
    """Every parameter of a resolved scenario (:func:`~simpro_mj.config.scenario.load_scenario`),
    in the order of the scenario's blocks."""
    return _rows(Scenario, as_tree(resolved), Scenario.defaults(), "")


def text(value: Any) -> str:
    """A value as one short line (YAML-like flow: null, true, [1.0, 2.0])."""
    return json.dumps(value, separators=(", ", ": ")) if not isinstance(value, str) else value
