"""Nested parameter trees and ``--set KEY=VALUE`` overrides.

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
from typing import Any

import yaml

from .errors import UserInputError

__all__ = [
    "parse_set",
    "apply_overrides",
    "set_path",
    "get_path",
    "closest",
    "check_keys",
    "check_number",
    "key_text",
    "check_tagged",
]


_PLAIN_KEY = re.compile(r"^[A-Za-z0-9_.\-]+$")


def key_text(key: Any) -> str:
    """A key as it appears in a dotted path: plain names as they are, anything
    else (spaces, newlines, non-strings) quoted, so a message stays one line."""
    return key if isinstance(key, str) and _PLAIN_KEY.match(key) else repr(key)


def closest(name: str, choices: Iterable[str]) -> str:
    """A ' (did you mean X?)' hint, or '' when nothing is close."""
    match = difflib.get_close_matches(name, list(choices), n=1, cutoff=0.5)
    return f" (did you mean '{match[0]}'?)" if match else ""


def check_tagged(
    entry: Mapping,
    path: str,
    tag: str,
    kinds: Mapping[str, tuple[tuple[str, ...], Mapping[str, Any]]],
    noun: str = "",
) -> tuple[str, tuple[str, ...], Mapping[str, Any]]:
    """Check a tagged entry such as ``{type: step, time_s: 1, value: 3}``.

    The tag (``entry[tag]``) picks the entry's kind in ``kinds``, which maps
    each kind to its required keys and its optional keys with defaults; the
    entry's other keys must be among them.

    Parameters
    ----------
    entry : mapping
        The entry as read from YAML.
    path : str
        Its dotted path, for messages (``setpoint.pitch_deg[0]``).
    tag : str
        The key naming the kind (``type``, ``distribution``).
    kinds : mapping
        ``kind -> (required keys, {optional key: default})``.
    noun : str, optional
        Appended to the kind in messages (``"distribution"``: "a normal
        distribution needs ...").

    Returns
    -------
    (kind, required, optional)

    Raises
    ------
    UserInputError
        Missing or unknown tag, unknown key (with the closest valid one),
        missing required key; one line, ``<what> at <path>: <allowed>``.
    """
    names = list(kinds)
    kind = entry.get(tag)
    if not isinstance(kind, str) or kind not in kinds:
        if tag not in entry:
            raise UserInputError(f"missing key at {path}.{tag}: allowed: one of {names}")
        raise UserInputError(
            f"invalid value at {path}.{tag}: {kind!r}; allowed: one of {names}"
            f"{closest(str(kind), names)}"
        )
    required, optional = kinds[kind]
    label = f"{kind} {noun}".strip()
    allowed = [tag, *required, *optional]
    for key in entry:
        if key not in allowed:
            raise UserInputError(
                f"unknown key at {path}.{key_text(key)}: allowed keys of a {label} are "
                f"{allowed}{closest(str(key), allowed)}"
            )
    for key in required:
        if key not in entry:
            raise UserInputError(f"missing key at {path}.{key}: a {label} needs {list(required)}")
    return kind, required, optional


def parse_set(expr: str) -> tuple[str, Any]:
    """Parse ``a.b.c=VALUE``; VALUE is read as YAML (numbers, lists, booleans).

    Raises
    ------
    UserInputError
        If the expression has no ``=`` or an empty key, or VALUE is not YAML.
    """
    if "=" not in expr:
        raise UserInputError(
            f"malformed --set at {expr!r}: expected KEY=VALUE with a dotted KEY, e.g. "
            "controller.mode=task_space"
        )
    key, _, raw = expr.partition("=")
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise UserInputError(
            f"malformed --set at {expr!r}: expected KEY=VALUE with KEY a dotted path like a.b.c"
        )
    try:
        value = yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError as exc:
        raise UserInputError(
            f"malformed --set at {key_text(key)}: value {raw!r} is not valid YAML"
        ) from exc
    return key, value


def get_path(tree: Mapping, path: str) -> Any:
    node: Any = tree
    for part in path.split("."):
        if not isinstance(node, Mapping) or part not in node:
            raise KeyError(path)
        node = node[part]
    return node


def set_path(tree: dict, path: str, value: Any, strict: bool = True) -> None:
    """Set a dotted path in a nested dict.

    With ``strict`` the path must already exist (unknown keys are refused with
    the closest valid key) and the new value must have a compatible type.
    """
    parts = path.split(".")
    node: Any = tree
    for depth, part in enumerate(parts):
        here = ".".join(parts[: depth + 1])
        last = depth == len(parts) - 1
        if not isinstance(node, dict):
            raise UserInputError(f"unknown key at {here}: '{parts[depth - 1]}' has no sub-keys")
        if part not in node:
            if strict:
                raise UserInputError(
                    f"unknown key at {here}: allowed keys are {sorted(node)}{closest(part, node)}"
                )
            if last:
                node[part] = value
                return
            node[part] = {}
        if last:
            if strict:
                _check_type(here, node[part], value)
            node[part] = value
            return
        node = node[part]


def _check_type(path: str, old: Any, new: Any) -> None:
    if old is None or new is None:
        return
    num = (int, float)
    if isinstance(old, bool) or isinstance(new, bool):
        ok = isinstance(old, bool) == isinstance(new, bool)
    elif isinstance(old, num):
        ok = isinstance(new, num)
    elif isinstance(old, dict):
        ok = isinstance(new, dict)
    elif isinstance(old, list):
        ok = isinstance(new, list)
    else:
        ok = isinstance(new, type(old))
    if not ok:
        raise UserInputError(
            f"wrong type at {path}: got {type(new).__name__} {new!r}, "
            f"expected {type(old).__name__} like {old!r}"
        )


def apply_overrides(tree: Mapping, sets: Iterable[str], strict: bool = True) -> dict:
    """Return a deep copy of ``tree`` with every ``KEY=VALUE`` applied in order."""
    out = copy.deepcopy(dict(tree))
    for expr in sets or ():
        key, value = parse_set(expr)
        set_path(out, key, value, strict=strict)
    return out


def check_keys(tree: Mapping, ref: Mapping, path: str) -> None:
    """Refuse keys of ``tree`` that ``ref`` does not have, recursively.

    Only key names and the mapping/leaf shape are checked (values are the
    owner's job). ``path`` is the dotted prefix used in the messages.

    Raises
    ------
    UserInputError
        ``unknown key at <path>: allowed keys are [...] (did you mean ...?)`` or
        ``wrong type at <path>: expected a mapping``.
    """
    for key, sub in tree.items():
        here = f"{path}.{key_text(key)}" if path else key_text(key)
        if key not in ref:
            raise UserInputError(
                f"unknown key at {here}: allowed keys are {sorted(ref)}{closest(str(key), ref)}"
            )
        if isinstance(ref[key], Mapping):
            if not isinstance(sub, Mapping):
                raise UserInputError(
                    f"wrong type at {here}: got {type(sub).__name__} {sub!r}; allowed: a mapping"
                )
            check_keys(sub, ref[key], here)


def check_number(
    tree: Mapping,
    path: str,
    lo: float = -math.inf,
    hi: float = math.inf,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    integer: bool = False,
    unit: str = "",
) -> float:
    """The number at dotted ``path`` of ``tree``, checked to be finite and in range.

    Raises
    ------
    UserInputError
        ``wrong type at <path>: ...`` for a non-number (booleans included) or
        ``invalid value at <path>: <value>; allowed: <range>`` for NaN, inf,
        a value out of range or (``integer``) a fractional one.
    """
    value = get_path(tree, path)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserInputError(
            f"wrong type at {path}: got {type(value).__name__} {value!r}; allowed: a number"
        )
    x = float(value)
    lo_ok = x > lo if lo_open else x >= lo
    hi_ok = x < hi if hi_open else x <= hi
    if not (math.isfinite(x) and lo_ok and hi_ok and (not integer or x == int(x))):
        parts = []
        if lo > -math.inf:
            parts.append(f"{'>' if lo_open else '>='} {lo:g}{unit}")
        if hi < math.inf:
            parts.append(f"{'<' if hi_open else '<='} {hi:g}{unit}")
        allowed = ("an integer " if integer else "a finite number ") + " and ".join(parts)
        raise UserInputError(f"invalid value at {path}: {value!r}; allowed: {allowed.strip()}")
    return int(x) if integer else x


# ------------------------------------------------------------------ YAML files


class _UniqueKeyLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses duplicate mapping keys (no other change)."""


def _construct_unique_mapping(loader, node, deep=False):
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        if isinstance(key, (str, int, float, bool)) or key is None:
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark
                )
            seen.add(key)
    return loader.construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor(
    yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_unique_mapping
)


def read_yaml(path: Path, what: str = "file") -> Any:
    """Read a YAML file (duplicate keys refused); one-line :class:`UserInputError`
    naming ``what`` and the file (line and column for a syntax error)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UserInputError(
            f"unreadable {what} at {path}: {exc.__class__.__name__}: {exc}; "
            "allowed: a UTF-8 YAML file"
        ) from exc
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{path} line {mark.line + 1}, column {mark.column + 1}" if mark else str(path)
        problem = " ".join(str(exc.problem or exc).split())
        allowed = "each key once" if "duplicate key" in problem else "a YAML mapping of keys"
        raise UserInputError(f"invalid YAML at {where}: {problem}; allowed: {allowed}") from exc
    except yaml.YAMLError as exc:
        raise UserInputError(
            f"invalid YAML at {path}: {exc}; allowed: a YAML mapping of keys"
        ) from exc
