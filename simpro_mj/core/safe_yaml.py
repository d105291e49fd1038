"""Reading YAML a user wrote, with bounds: no input can make the reader hang.

Every scenario file and every ``--set`` value goes through :func:`load`:
:class:`BoundedLoader`, built on libyaml's ``CSafeLoader`` (several times
faster) when PyYAML has it, else on ``yaml.SafeLoader``, that

* refuses duplicate mapping keys;
* refuses nesting deeper than :data:`MAX_DEPTH` levels before it composes
  (PyYAML's composer recurses: 5,000 nested brackets were a RecursionError);
* allows anchors and aliases but counts the document as expanded (every use
  of an alias counts its whole value again) and refuses more than
  :data:`MAX_NODES` nodes, an expanded depth over :data:`MAX_DEPTH` or an
  alias inside its own anchor, before anything is built: a "billion laughs"
  document of nested anchors expanding to 9^9 items is refused in
  milliseconds, not expanded;
* reads ``1e9`` as a float (YAML 1.2; PyYAML's YAML 1.1 made it a string);
* refuses a number written with more than :data:`MAX_NUMBER_CHARS`
  characters (a 401-digit integer overflowed a float, a 5,000-digit one
  exceeded Python's integer-string limit).

:func:`read_file` opens the file without blocking and reads only a regular
file (:mod:`simpro_mj.core.safe_files`: a FIFO, a device or a socket is refused
at once), refuses a file larger than :data:`MAX_FILE_BYTES`
before reading it (the pure-Python reader parses about 1 MB/s) and one that
holds no document (empty or comments only).

Each refusal is a :class:`YAMLLimitError`, a ``yaml.MarkedYAMLError``
carrying the position and what is ``allowed``, so callers print
``invalid YAML at <file> line L, column C: <problem>; allowed: <bound>``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml
from yaml.events import (
    MappingEndEvent,
    MappingStartEvent,
    SequenceEndEvent,
    SequenceStartEvent,
)
from yaml.nodes import MappingNode, SequenceNode

#: Largest scenario file read (bytes): 20 times the largest shipped scenario's
#: table room; the reader parses it in about a second.
MAX_FILE_BYTES = 500_000
#: Deepest nesting of mappings and lists (a scenario needs 6).
MAX_DEPTH = 50
#: Most nodes of a document, aliases expanded (a 10,000-point table is 20,000).
MAX_NODES = 200_000
#: Longest number (characters): float precision needs 17 digits plus sign and exponent.
MAX_NUMBER_CHARS = 40


_OPEN = (MappingStartEvent, SequenceStartEvent)
_CLOSE = (MappingEndEvent, SequenceEndEvent)


class YAMLLimitError(yaml.MarkedYAMLError):
    """A document over one of the bounds (``problem``) with what is ``allowed``."""

    def __init__(self, problem: str, allowed: str, mark=None):
        super().__init__(problem=problem, problem_mark=mark)
        self.allowed = allowed


#: libyaml's parser and composer when PyYAML has them (about 7 times faster), else PyYAML's own
_BASE: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class BoundedLoader(_BASE):
    """``yaml.SafeLoader`` (or its libyaml twin) with the bounds of the module docstring;
    the depth is checked on the event stream first (:func:`_check_depth_events`)."""

    def construct_document(self, node):
        _check_expansion(node)
        return super().construct_document(node)


def _children(node) -> list:
    if isinstance(node, MappingNode):
        return [n for pair in node.value for n in pair]
    return list(node.value)


def _check_expansion(root) -> None:
    """Size and depth of the document with every alias expanded (a scalar counts 1),
    memoised over the unique collections: linear in the file, not in the expansion."""
    if not isinstance(root, (MappingNode, SequenceNode)):
        return
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    on_path: set[int] = set()
    stack = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            on_path.discard(key)
            n, d = 1, 1
            for kid in _children(node):
                if isinstance(kid, (MappingNode, SequenceNode)):
                    n += size[id(kid)]
                    d = max(d, 1 + depth[id(kid)])
                else:
                    n += 1
                    d = max(d, 2)
            size[key], depth[key] = n, d
            if n > MAX_NODES:
                raise YAMLLimitError(
                    f"the document expands to more than {MAX_NODES:,} values "
                    "(aliases counted each time they are used)",
                    f"at most {MAX_NODES:,} values",
                    node.start_mark,
                )
            if d > MAX_DEPTH:
                raise YAMLLimitError(
                    f"nesting deeper than {MAX_DEPTH} levels once aliases are expanded",
                    f"at most {MAX_DEPTH} levels of mappings and lists",
                    node.start_mark,
                )
            continue
        if key in size:
            continue
        on_path.add(key)
        stack.append((node, True))
        for kid in _children(node):
            if not isinstance(kid, (MappingNode, SequenceNode)):
                continue
            if id(kid) in on_path:
                raise YAMLLimitError(
                    "an alias inside its own anchor (a recursive structure)",
                    "aliases to finished anchors only",
                    kid.start_mark,
                )
            if id(kid) not in size:
                stack.append((kid, False))


def _check_depth_events(text: str) -> None:
    """Nesting depth from the parser's event stream (iterative), before the
    composer (which recurses) sees the document."""
    depth = 0
    try:
        for event in yaml.parse(text, Loader=_BASE):
            if isinstance(event, _OPEN):
                depth += 1
                if depth > MAX_DEPTH:
                    raise _too_deep(event.start_mark)
            elif isinstance(event, _CLOSE):
                depth -= 1
    except yaml.MarkedYAMLError as exc:
        # libyaml 0.2.5 and later stop at 1000 levels in the scanner, which reads
        # a flow collection's brackets ahead of the events counted here: the
        # same limit, reported in this module's words.
        if "maximum nesting depth" not in str(exc.problem):
            raise
        raise _too_deep(exc.problem_mark) from None


def _too_deep(mark) -> YAMLLimitError:
    return YAMLLimitError(
        f"nesting deeper than {MAX_DEPTH} levels",
        f"at most {MAX_DEPTH} levels of mappings and lists",
        mark,
    )


def _unique_mapping(loader, node, deep=False):
    seen = set()
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":  # '<<: *base', merged below
            continue
        key = loader.construct_object(key_node, deep=True)
        if isinstance(key, (str, int, float, bool)) or key is None:
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {_short(repr(key))}", key_node.start_mark
                )
            seen.add(key)
    return loader.construct_mapping(node, deep=deep)


#: A number as YAML 1.2 writes it (and ``.inf``, ``.nan``): PyYAML's YAML 1.1 also
#: reads ``0_3`` as 3, ``0x1F`` as 31, ``010`` as 8 and ``1:30`` as 90.
_YAML12_NUMBER = re.compile(
    r"^[-+]?(?:0|[1-9][0-9]*)$|^[-+]?(?:\.[0-9]+|[0-9]+\.[0-9]*)(?:[eE][-+]?[0-9]+)?$"
    r"|^[-+]?[0-9]+[eE][-+]?[0-9]+$"
    r"|^[-+]?\.(?:inf|Inf|INF)$|^\.(?:nan|NaN|NAN)$"
)


def _bounded_number(construct):
    def build(loader, node):
        text = str(node.value)
        if len(text) > MAX_NUMBER_CHARS:
            raise YAMLLimitError(
                f"a number written with {len(text):,} characters ({_short(text, 24)})",
                f"at most {MAX_NUMBER_CHARS} characters (use an exponent: 1.5e300)",
                node.start_mark,
            )
        if not _YAML12_NUMBER.match(text):
            raise YAMLLimitError(
                f"the number {_short(text, 24)} is written the YAML 1.1 way (an underscore, "
                "hex, octal, a leading 0 or base 60), which reads it otherwise than it looks",
                "plain decimal numbers (YAML 1.2): 3, 0.3, 1.5e3; or quote it as text",
                node.start_mark,
            )
        return construct(loader, node)

    return build


def _short(text: str, limit: int = 60) -> str:
    return text if len(text) <= limit else f"{text[: limit - 16]}...{text[-10:]}"


#: ``1e9``, ``-2E-3``: floats in YAML 1.2, strings in PyYAML's YAML 1.1 (where
#: ``--set outer.gain=-1e9`` was "a string"); read as floats here.
_EXP_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$")

BoundedLoader.add_implicit_resolver("tag:yaml.org,2002:float", _EXP_FLOAT, list("-+0123456789"))
BoundedLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _unique_mapping)
BoundedLoader.add_constructor(
    "tag:yaml.org,2002:int", _bounded_number(yaml.SafeLoader.construct_yaml_int)
)
BoundedLoader.add_constructor(
    "tag:yaml.org,2002:float", _bounded_number(yaml.SafeLoader.construct_yaml_float)
)


def load(text: str) -> Any:
    """Parse one YAML document with :class:`BoundedLoader`.

    Raises
    ------
    yaml.YAMLError
        Invalid YAML; :class:`YAMLLimitError` for a document over a bound.
    """
    _check_depth_events(text)
    return yaml.load(text, Loader=BoundedLoader)  # noqa: S506 - a SafeLoader subclass


def read_file(path: Path, what: str = "scenario") -> Any:
    """Read and parse a YAML file within the bounds.

    Raises
    ------
    YAMLLimitError
        A file over :data:`MAX_FILE_BYTES` (checked before reading) or a
        document over the other bounds; one holding no document (empty or
        comments only).
    OSError, UnicodeDecodeError
        The file cannot be read as UTF-8.
    """
    from simpro_mj.core.safe_files import UnreadableFile, read_bytes

    try:
        data = read_bytes(path, MAX_FILE_BYTES, what)
    except UnreadableFile as exc:
        if str(exc).startswith("file too large"):
            size = Path(path).stat().st_size
            raise YAMLLimitError(
                f"a file of {size:,} bytes", f"a {what} file of at most {MAX_FILE_BYTES:,} bytes"
            ) from None
        raise
    doc = load(data.decode("utf-8"))
    if doc is None:
        raise YAMLLimitError(
            "the file holds no keys (empty or comments only)",
            f"a mapping of {what} keys" + (", e.g. 'duration_s: 10'" if what == "scenario" else ""),
        )
    return doc
