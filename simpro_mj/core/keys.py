"""Nested parameter trees, their typed blocks and ``--set KEY=VALUE`` overrides.

A parameter tree is a plain nested ``dict`` whose leaves are numbers, strings,
booleans or lists. Units live in the key names at this edge (``pitch_deg``,
``heave_mm``, ``mass_kg``); code converts to SI right after reading.
"""

from __future__ import annotations

import copy
import difflib
import math
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Annotated, Any

import yaml
from pydantic import AllowInfNan, BaseModel, BeforeValidator, ConfigDict, Field, Strict

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.safe_yaml import YAMLLimitError, load, read_file

# YAML 1.1 reads 5e-3 (no dot) as a string; a numeric field takes it
_EXP_RE = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")
_PLAIN_KEY = re.compile(r"^[A-Za-z0-9_.\-]+$")
#: Longest key or value echoed whole in a message (characters); longer ones are cut.
ECHO_CHARS = 60


def short_text(text: str, limit: int = ECHO_CHARS) -> str:
    """``text``, or its start and end around ``...`` with its length when longer
    than ``limit``: a 100,000-character key or a 300-digit number stays readable."""
    if len(text) <= limit:
        return text
    keep = max(limit - 24, 8)
    return f"{text[: keep - keep // 3]}...{text[-(keep // 3) :]} ({len(text):,} chars)"


def value_text(value: Any) -> str:
    """``repr(value)`` cut by :func:`short_text` (for ``got ...`` in messages)."""
    return short_text(repr(value))


def key_text(key: Any) -> str:
    """A key as it appears in a dotted path: plain names as they are, anything
    else (spaces, newlines, non-strings) quoted, so a message stays one line;
    a long one cut (:func:`short_text`)."""
    text = key if isinstance(key, str) and _PLAIN_KEY.match(key) else repr(key)
    return short_text(text, 2 * ECHO_CHARS)


def closest(name: str, choices: Iterable[str]) -> str:
    """A ' (did you mean X?)' hint, or '' when nothing is close."""
    match = difflib.get_close_matches(name[:200], list(choices), n=1, cutoff=0.5)
    return f" (did you mean '{match[0]}'?)" if match else ""


def parse_set(expr: str) -> tuple[str, Any]:
    """Parse ``a.b.c=VALUE``; VALUE is read as YAML (numbers, lists, booleans).

    Raises
    ------
    UserInputError
        If the expression has no ``=`` or an empty key, or VALUE is not YAML.
    """
    if "=" not in expr:
        raise UserInputError(
            f"malformed --set at {value_text(expr)}: expected KEY=VALUE with a dotted KEY, e.g. "
            "controller.mode=task_space"
        )
    key, _, raw = expr.partition("=")
    bad = next((c for c in key if ord(c) < 32 or 127 <= ord(c) < 160), None)
    if bad is not None:  # a newline or an escape sequence: never part of a key
        raise UserInputError(
            f"malformed --set at {value_text(key)}: the key holds the control character "
            f"U+{ord(bad):04X}; allowed: a dotted path of printable characters like a.b.c"
        )
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise UserInputError(
            f"malformed --set at {value_text(expr)}: expected KEY=VALUE with KEY a dotted path "
            "like a.b.c"
        )
    try:
        value = load(raw) if raw.strip() else ""
    except YAMLLimitError as exc:
        raise UserInputError(
            f"invalid value at {key_text(key)}: {exc.problem}; allowed: {exc.allowed}"
        ) from exc
    except yaml.YAMLError as exc:
        raise UserInputError(
            f"malformed --set at {key_text(key)}: value {value_text(raw)} is not valid YAML"
        ) from exc
    return key, value


def set_path(tree: dict, path: str, value: Any) -> None:
    """Set a dotted path in a nested dict.

    The path must already exist (unknown keys are refused with the closest valid
    key) and the new value must have a compatible type.
    """
    parts = path.split(".")
    node: Any = tree
    for depth, part in enumerate(parts):
        here = ".".join(parts[: depth + 1])
        if not isinstance(node, dict):
            raise UserInputError(
                f"unknown key at {key_text(here)}: '{key_text(parts[depth - 1])}' has no sub-keys"
            )
        if part not in node:
            raise UserInputError(
                f"unknown key at {key_text(here)}: allowed keys are {sorted(node)}"
                f"{closest(part, node)}"
            )
        if depth == len(parts) - 1:
            _check_type(here, node[part], value)
            node[part] = value
            return
        node = node[part]


def _check_type(path: str, old: Any, new: Any) -> None:
    if old is None or new is None:
        return
    num = (int, float)
    if isinstance(old, bool) or isinstance(new, bool):
        ok, kind = isinstance(old, bool) == isinstance(new, bool), "true or false"
    elif isinstance(old, num):
        ok, kind = isinstance(new, num), "a number"
    elif isinstance(old, dict):
        ok, kind = isinstance(new, dict), "a mapping"
    elif isinstance(old, list):
        ok, kind = isinstance(new, list), "a list"
    else:
        ok, kind = isinstance(new, type(old)), f"a {type(old).__name__}"
    if not ok:
        raise UserInputError(
            f"wrong type at {key_text(path)}: got {type(new).__name__} {value_text(new)}; "
            f"allowed: {kind} like {value_text(old)}"
        )


def apply_overrides(tree: Mapping, sets: Iterable[str]) -> dict:
    """Return a deep copy of ``tree`` with every ``KEY=VALUE`` applied in order."""
    out = copy.deepcopy(dict(tree))
    for expr in sets or ():
        key, value = parse_set(expr)
        set_path(out, key, value)
    return out


# ------------------------------------------------------------------ typed blocks
# The vocabulary of a typed parameter tree (the scenario's blocks, the plant's
# pneumatics): a block is a pydantic model refusing unknown keys, its fields
# declared with :func:`param`; a rule's refusal is a :class:`Problem`.


class Problem(ValueError):
    """A rule's refusal, relative to where the rule sits.

    The message is ``<head> at <path><suffix><rest>``, ``path`` the dotted
    location pydantic reports (:func:`~simpro_mj.config.messages.user_error` fills
    it in): ``suffix`` names a key below it (``.time_s``), ``rest`` says what is
    allowed.
    """

    def __init__(self, head: str, rest: str, suffix: str = "") -> None:
        super().__init__(f"{head} at <here>{suffix}{rest}")
        self.head, self.rest, self.suffix = head, rest, suffix

    @classmethod
    def wrong_type(cls, value: Any, allowed: str, suffix: str = "") -> Problem:
        kind = "null" if value is None else type(value).__name__
        return cls("wrong type", f": got {kind} {value_text(value)}; allowed: {allowed}", suffix)

    @classmethod
    def invalid(cls, value: Any, allowed: str, suffix: str = "") -> Problem:
        return cls("invalid value", f": {value_text(value)}; allowed: {allowed}", suffix)


def yaml_number(value: Any) -> Any:
    """``'5e-3'`` (a string to YAML 1.1) as the number it means; anything else as given."""
    if isinstance(value, str) and _EXP_RE.match(value.strip()):
        return float(value)
    return value


def integral(value: Any) -> Any:
    """An integral float as its int (``60.0`` -> 60); ``2.5`` refused; anything else as given."""
    value = yaml_number(value)
    if isinstance(value, float) and math.isfinite(value):
        if value != int(value):
            raise Problem.invalid(value, "an integer")
        return int(value)
    return value


#: A finite number (an int is taken and becomes a float; booleans, strings refused).
Real = Annotated[float, BeforeValidator(yaml_number), Strict(), AllowInfNan(False)]
#: An integer (an integral float is taken; booleans, strings refused).
Whole = Annotated[int, BeforeValidator(integral), Strict()]


def param(
    default: Any,
    unit: str = "",
    doc: str = "",
    *,
    note: str = "",
    why: str = "",
    **constraints: Any,
) -> Any:
    """A field of a block: its default, unit, one line of meaning and pydantic's constraints.

    ``unit`` and ``doc`` are what ``simpro-sim show`` prints and what a refusal's
    "allowed" says beside the range (``ge``, ``gt``, ``le``, ``lt``); ``note``: the
    allowed range in words where a rule of its own checks it; ``why``: why the range
    is plausible, said in a refusal in place of ``doc``.
    """
    pairs = (("unit", unit), ("range", note), ("why", why))
    extra: dict[str, Any] | None = {k: v for k, v in pairs if v}
    extra = extra or None
    if isinstance(default, list | dict):
        return Field(
            default_factory=lambda d=default: copy.deepcopy(d),
            description=doc or None,
            json_schema_extra=extra,
            **constraints,
        )
    return Field(default, description=doc or None, json_schema_extra=extra, **constraints)


def block(model: type, doc: str = "") -> Any:
    """A sub-block field: the model's defaults, ``doc`` (default: the model's first line)."""
    line = doc or (model.__doc__ or "").strip().split("\n\n")[0].replace("\n", " ")
    return Field(default_factory=model, description=line or None)


_DEFAULTS: dict[type, dict] = {}


class Block(BaseModel):
    """A block of the scenario: its fields are its keys, each with its default;
    a key it does not have is refused (``extra="forbid"``)."""

    model_config = ConfigDict(extra="forbid", protected_namespaces=(), validate_assignment=False)

    @classmethod
    def defaults(cls) -> Mapping:
        """The block's keys with their defaults, as a plain tree (computed once)."""
        tree = _DEFAULTS.get(cls)
        if tree is None:
            tree = _DEFAULTS[cls] = cls.model_construct().model_dump()
        return tree


# ------------------------------------------------------------------ YAML files


def read_yaml(path: Path, what: str = "file") -> Any:
    """Read a YAML file within the bounds of :mod:`simpro_mj.core.safe_yaml` (size,
    depth, alias expansion, number length; duplicate keys and empty files
    refused); one-line :class:`UserInputError` naming ``what`` and the file
    (line and column for a syntax error)."""
    try:
        return read_file(path, what)
    except (OSError, UnicodeDecodeError) as exc:
        raise UserInputError(
            f"unreadable {what} at {path}: {exc.__class__.__name__}: {short_text(str(exc))}; "
            "allowed: a UTF-8 YAML file"
        ) from exc
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{path} line {mark.line + 1}, column {mark.column + 1}" if mark else str(path)
        problem = short_text(" ".join(str(exc.problem or exc).split()), 200)
        if isinstance(exc, YAMLLimitError):
            allowed = exc.allowed
        else:
            allowed = "each key once" if "duplicate key" in problem else "a YAML mapping of keys"
        raise UserInputError(f"invalid YAML at {where}: {problem}; allowed: {allowed}") from exc
    except yaml.YAMLError as exc:
        raise UserInputError(
            f"invalid YAML at {path}: {short_text(str(exc), 200)}; allowed: a YAML mapping of keys"
        ) from exc
