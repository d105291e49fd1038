"""The one error formatter of the typed scenario: pydantic's error as one line.

:func:`user_error` maps pydantic's first error onto the one-line contract of
``docs/robustness.md``: ``<what> at <dotted.path>: <value>; allowed: <what is
allowed>``, the range, unit and meaning read from the field that refused the
value (:mod:`simpro_mj.config.rules`: :func:`~simpro_mj.config.rules.param`),
the choices of a ``Literal`` or a tagged union listed, the closest key or
choice suggested. The walk over the models that finds that field
(:func:`locate`) and the text of a range (:func:`range_text`) serve
``simpro-sim show`` too (:func:`simpro_mj.config.scenario.parameters`).
"""

from __future__ import annotations

import math
import types
from collections.abc import Iterable, Mapping
from typing import Annotated, Any, Literal, TypeVar, Union, get_args, get_origin

import annotated_types as at
from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from simpro_mj.config.rules import ONE_FOR_ALL
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import Block, Problem, apply_overrides, closest, key_text, value_text

# ------------------------------------------------------------------ walking the models


def strip(tp: Any) -> tuple[Any, list]:
    """An annotation without its ``Annotated`` and ``| None`` layers, and their metadata."""
    meta: list = []
    while True:
        if get_origin(tp) is Annotated:
            tp, *more = get_args(tp)
            meta += more
        elif get_origin(tp) in (Union, types.UnionType):
            args = [a for a in get_args(tp) if a is not type(None)]
            if len(args) != 1:
                return tp, meta
            tp = args[0]
        else:
            return tp, meta


def is_model(tp: Any) -> bool:
    """A pydantic model or pydantic dataclass (a type with pydantic's fields)."""
    return isinstance(tp, type) and hasattr(tp, "__pydantic_fields__")


#: The keys that tag an entry of a discriminated union.
TAGS = ("type", "distribution")


def tag_of(model: type[BaseModel]) -> str | None:
    """The key that tags ``model`` in its union (``type``), or None."""
    return next((t for t in TAGS if t in model.__pydantic_fields__), None)


def tagged_members(tp: Any) -> dict[str, type]:
    """The models of a tagged union by their tag ({} for anything else)."""
    tp, _ = strip(tp)
    out = {}
    if get_origin(tp) in (Union, types.UnionType):
        for member in get_args(tp):
            member, _ = strip(member)
            if is_model(member) and tag_of(member):
                (tag,) = get_args(member.__pydantic_fields__[tag_of(member)].annotation)
                out[tag] = member
    return out


def locate(model: type, loc: tuple) -> tuple[Any, FieldInfo | None, list, set]:
    """What lies at ``loc`` below ``model``: its annotation, the last field crossed, the
    metadata (constraints) there and the positions in ``loc`` that are a union's tags
    (no key of the file); ``(None, None, [], tags)`` for a key no model has."""
    tp: Any = model
    field: FieldInfo | None = None
    meta: list = []
    tags: set = set()
    for i, part in enumerate(loc):
        tp, _ = strip(tp)
        origin = get_origin(tp)
        if isinstance(part, int) and origin is list:
            tp, meta = strip(get_args(tp)[0])
            continue
        if isinstance(part, str) and origin is dict:  # a mapping's key: its value's type
            tp, meta = strip(get_args(tp)[1])
            continue
        members = tagged_members(tp)
        if part in members:
            tp, meta = members[part], []
            tags.add(i)
            continue
        if not is_model(tp) or part not in tp.__pydantic_fields__:
            return None, None, [], tags
        field = tp.__pydantic_fields__[part]
        tp, meta = field.annotation, list(field.metadata)
    return tp, field, meta, tags


# ------------------------------------------------------------------ what is allowed


def unit_of(field: FieldInfo | None) -> str:
    extra = field.json_schema_extra if field is not None else None
    return str(extra.get("unit", "")) if isinstance(extra, dict) else ""


def _num(x: Any) -> str:
    return str(x) if isinstance(x, int) else f"{x:g}"


def _constraints(meta: list) -> Iterable:
    """The constraints in ``meta`` (a FieldInfo in ``Annotated`` holds its own)."""
    for m in meta:
        yield from getattr(m, "metadata", None) or [m]


def range_text(meta: list, unit: str = "") -> str:
    """``0..5000 kg``, ``> 0 s``, ``> -1 and < 1`` from the constraints in ``meta``."""
    lo: tuple[str, Any] | None = None
    hi: tuple[str, Any] | None = None
    for c in _constraints(meta):
        if isinstance(c, at.Ge):
            lo = (">=", c.ge)
        elif isinstance(c, at.Gt):
            lo = (">", c.gt)
        elif isinstance(c, at.Le):
            hi = ("<=", c.le)
        elif isinstance(c, at.Lt):
            hi = ("<", c.lt)
    if lo is None and hi is None:
        return ""
    if lo and hi and lo[0] == ">=" and hi[0] == "<=":
        text = f"{_num(lo[1])}..{_num(hi[1])}"
    else:
        text = " and ".join(f"{part[0]} {_num(part[1])}" for part in (lo, hi) if part)
    return f"{text} {unit}".strip()


def item_meta(tp: Any) -> list:
    """The constraints of a list's items (``Each(3, ge=0)``)."""
    tp, _ = strip(tp)
    if get_origin(tp) is list:
        return strip(get_args(tp)[0])[1]
    return []


def allowed_text(
    field: FieldInfo | None, tp: Any = None, meta: list | None = None, bound: str = ""
) -> str:
    """What a field allows: its range and unit (``bound`` first, the one a value
    crossed), its meaning in brackets."""
    if tp is None and field is not None:
        tp = field.annotation
    if meta is None:
        meta = list(field.metadata) if field is not None else []
    rng = range_text(meta + strip(tp)[1] + item_meta(tp), unit_of(field))
    extra = field.json_schema_extra if field is not None else None
    if not rng and isinstance(extra, dict) and extra.get("range"):  # a range the plant states
        return f"{extra['range']}, {unit_of(field)}".rstrip(", ")
    if bound:
        unit = unit_of(field)
        first = f"{bound} {unit}".strip()
        rng = first if rng in ("", first) else f"{first}, within {rng}"
    doc = (field.description or "") if field is not None else ""
    if rng and isinstance(extra, dict) and extra.get("why"):  # why the range is plausible
        doc = str(extra["why"])
    if rng and doc:
        return f"{rng} ({doc})"
    return rng or doc or "see simpro-sim show"


def _choices(tp: Any) -> list:
    tp, _ = strip(tp)
    return list(get_args(tp)) if get_origin(tp) is Literal else []


def _kind_text(kind: str, tp: Any, field: FieldInfo | None) -> str:
    """What a value of the field's type is, for a "wrong type"."""
    base, _ = strip(tp)
    if base is list:
        return "a non-empty list of values, e.g. [1, 2, 4]"
    if base is dict or get_origin(base) is dict:
        return "a non-empty mapping"
    if get_origin(base) is list:
        default = field.get_default(call_default_factory=True) if field is not None else None
        n = len(default) if isinstance(default, list) else None
        item, _ = strip(get_args(base)[0])
        members = tagged_members(item)
        if members:
            noun = getattr(next(iter(members.values())), "noun", "entry")
            return f"a list of {noun}s, mappings with a type: one of {list(members)}"
        if n and item is float and _fixed_length(tp, field) == n:
            one = field is not None and any(m is ONE_FOR_ALL for m in field.metadata)
            return f"{'one number or ' if one else ''}a list of {n} numbers like {default}"
        return "a non-empty list of numbers"
    return {
        "float_type": "a number",
        "int_type": "an integer",
        "bool_type": "true or false",
        "string_type": "a string",
        "model_type": "a mapping",
        "dict_type": "a mapping",
        "model_attributes_type": f"a mapping with a {_tag_key(tp)}: one of "
        f"{list(tagged_members(tp))}",
    }.get(kind, "a value of the right type")


def _fixed_length(tp: Any, field: FieldInfo | None) -> int | None:
    """The length a list must have (its ``max_length``), None when it may vary."""
    meta = strip(tp)[1] + (list(field.metadata) if field is not None else [])
    return next((c.max_length for c in _constraints(meta) if isinstance(c, at.MaxLen)), None)


def _tag_key(tp: Any) -> str:
    members = list(tagged_members(tp).values())
    return (tag_of(members[0]) if members else None) or "type"


def _dotted(loc: tuple) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{key_text(part)}" if out else key_text(part)
    return out


#: pydantic's bound errors: the operator and its context key
_BOUNDS = {
    "greater_than": (">", "gt"),
    "greater_than_equal": (">=", "ge"),
    "less_than": ("<", "lt"),
    "less_than_equal": ("<=", "le"),
}
_RANGE_ERRORS = {
    "string_too_long",
    "greater_than",
    "greater_than_equal",
    "less_than",
    "less_than_equal",
    "finite_number",
    "string_pattern_mismatch",
}
_TYPE_ERRORS = {
    "float_type",
    "int_type",
    "bool_type",
    "string_type",
    "list_type",
    "too_short",
    "too_long",
    "model_type",
    "dict_type",
    "model_attributes_type",
}


_M = TypeVar("_M", bound=BaseModel)
_B = TypeVar("_B", bound=Block)


def validated(model: type[_M], value: Any, prefix: str = "", context: Any = None) -> _M:
    """``model.model_validate(value)``; its first error raised as :func:`user_error`'s line.

    ``prefix``: the dotted path of ``value`` when it is a block on its own
    (``setpoint.cueing``); ``context``: pydantic's validation context.
    """
    try:
        return model.model_validate(value, context=context)
    except ValidationError as exc:
        raise user_error(exc, model, prefix) from None


def from_sets(model: type[_B], sets: Iterable[str] = ()) -> _B:
    """A model of a command's parameters: its defaults with the ``--set KEY=VALUE``
    overrides, validated (:func:`validated`).

    Raises
    ------
    UserInputError
        An unknown key, or a value of the wrong type or out of range (one line).
    """
    return validated(model, apply_overrides(model.defaults(), sets))


def user_error(exc: ValidationError, model: type, prefix: str = "") -> UserInputError:
    """The one-line :class:`UserInputError` for pydantic's first error (an unknown key first).

    Parameters
    ----------
    exc : ValidationError
        What ``model.model_validate`` raised.
    model : type
        The model validated (the scenario, or a block of it): where the field that
        refused the value is looked up for its range, unit, meaning and choices.
    prefix : str
        The dotted path of what was validated, when that is a block on its own
        rather than the whole scenario (``setpoint.cueing``).
    """
    errors = exc.errors(include_url=False)
    err = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
    kind, value = err["type"], err.get("input")
    loc = tuple(err["loc"])
    tp, field, meta, tags = locate(model, loc)
    # the tag pydantic adds inside a tagged union is no key of the file
    keys = tuple(p for i, p in enumerate(loc) if i not in tags)
    path = ".".join(p for p in (prefix, _dotted(keys)) if p) or "top level"

    def line(head: str, rest: str, at: str | None = None) -> UserInputError:
        return UserInputError(f"{head} at {at or path}{rest}")

    cause = (err.get("ctx") or {}).get("error")
    if isinstance(cause, UserInputError):  # an absolute message (names its own path)
        return UserInputError(str(cause))
    if isinstance(cause, Problem):
        where = f"{path}{cause.suffix}" if keys or prefix else cause.suffix.lstrip(".") or path
        return line(cause.head, cause.rest, where)
    if kind == "extra_forbidden":
        parent = locate(model, loc[:-1])[0]
        names = sorted(strip(parent)[0].__pydantic_fields__) if is_model(strip(parent)[0]) else []
        key = str(loc[-1])
        return line("unknown key", f": allowed keys are {names}{closest(key, names)}")
    if kind == "missing":
        parent = strip(locate(model, loc[:-1])[0])[0]
        fields = parent.__pydantic_fields__.items() if is_model(parent) else ()
        need = [k for k, f in fields if f.is_required() and k not in TAGS]
        tag = loc[-2] if len(loc) > 1 and isinstance(loc[-2], str) else "block"
        return line("missing key", f": a {tag} needs {need}")
    if kind in ("union_tag_not_found", "union_tag_invalid"):
        names, key = list(tagged_members(tp)), _tag_key(tp)
        if kind == "union_tag_not_found":
            return line("missing key", f": allowed: one of {names}", f"{path}.{key}")
        given = value.get(key) if isinstance(value, Mapping) else value
        rest = f": {value_text(given)}; allowed: one of {names}{closest(str(given), names)}"
        return line("invalid value", rest, f"{path}.{key}")
    if kind == "literal_error":
        choices = _choices(tp)
        head = "invalid value"
        if value is not None and choices and not isinstance(value, type(choices[0])):
            return line("wrong type", f": got {type(value).__name__} {value_text(value)}; "
                        f"allowed: one of {choices}")  # fmt: skip
        hint = closest(str(value), [str(c) for c in choices])
        return line(head, f": {value_text(value)}; allowed: one of {choices}{hint}")
    index = ""
    if keys and isinstance(keys[-1], int) and strip(tp)[0] in (float, int, str):
        # an item of a list of numbers: the list's field says what is allowed
        index = f" (item [{keys[-1]}])"
        path = path[: path.rindex("[")]
        tp, field, meta, _ = locate(model, loc[:-1])
        meta = item_meta(tp)
    if kind in _TYPE_ERRORS:
        got = "null" if value is None else f"{type(value).__name__} {value_text(value)}"
        allowed = _kind_text(kind, tp, field)
        return line("wrong type", f": got {got}{index}; allowed: {allowed}")
    if kind in _RANGE_ERRORS:
        ctx = err.get("ctx") or {}
        op = _BOUNDS.get(kind)
        bound = f"{op[0]} {_num(ctx[op[1]])}" if op and op[1] in ctx else ""
        allowed = allowed_text(field, tp, meta, bound)
        if kind == "finite_number" or (isinstance(value, float) and not math.isfinite(value)):
            allowed = f"a finite number, {allowed}"
        return line("invalid value", f": {value_text(value)}{index}; allowed: {allowed}")
    msg = " ".join(str(err["msg"]).split())  # not expected from these models: still one line
    return line("invalid value", f": {value_text(value)}{index}; allowed: {msg}")
