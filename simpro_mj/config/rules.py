"""The vocabulary of the typed scenario: limits, one-line messages, checked leaves, rules.

The scenario's models (:mod:`simpro_mj.config.models`, :mod:`simpro_mj.config.entries`)
are pydantic v2 models built from these pieces:

* :class:`Block`: a block that holds its keys and their defaults as its fields
  (the one source of every default and of every leaf's type: a float default
  takes any finite number, an int default an integral one, a list default that
  many numbers), unknown keys refused with the closest valid one;
* :class:`Entry`: a tagged mapping (``{type: step, ...}``) whose fields without
  a default are required, checked by :func:`tagged` before its model sees it;
* :func:`rule` and :func:`one_of`: ranges and enumerations with the text of
  what is allowed.

Messages keep the contract of ``docs/robustness.md``: one line,
``<what> at <dotted.path>: <what is allowed>``. A rule raises :class:`Problem`
(its text relative to where it sits) or a
:class:`~simpro_mj.core.errors.UserInputError` (an absolute message, for rules
that name another field); :func:`user_error` turns pydantic's first error into
the one line.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    ValidationError,
    field_validator,
    model_validator,
)

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import closest, key_text, value_text
from simpro_mj.core.rates import PHYSICS_DT_MS, PHYSICS_DT_S, whole_steps

MODES = ("joint_only", "task_space", "feedforward")
OUTER_TYPES = ("I", "PI")
# controller.inner.design_plant: "auto" is "paper" on the paper preset and
# "identified" on any other (config.models.Scenario resolves it at load)
DESIGN_PLANTS = ("auto", "paper", "identified")
IDENTIFY_CHOICES = ("auto", "preset")  # controller.inner.identify (simpro_mj.identification.auto)
DELAY_SAMPLES = (1, 2)
SETPOINT_AXES = ("roll_deg", "pitch_deg", "heave_mm")
FAULT_SENSORS = ("potentiometer", "height_encoder", "imu")
FAULT_AXES = ("roll", "pitch")
POT_MODES = ("open", "short")

#: Longest run accepted (s): the 1 ms log of one hour is about 1 GB of memory.
MAX_DURATION_S = 3600.0
#: Shortest run accepted (s): ten physics steps.
MIN_DURATION_S = 0.01
#: Longest controller period or sensor sampling period (ms): 10 s, as ``analyze``.
MAX_PERIOD_MS = 10_000
#: Largest logging decimation (a sample every 10 s of a 1 ms run).
MAX_DECIMATION = 10_000
#: Sine periods (s): two physics steps (the Nyquist limit of the 1 ms grid) .. 1e6 s.
SINE_PERIOD_RANGE_S = (0.002, 1e6)

NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
# YAML 1.1 reads 5e-3 (no dot) as a string; accept it in numeric fields
_EXP_RE = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")


# ------------------------------------------------------------------ messages


class Problem(ValueError):
    """A rule's refusal, relative to where the rule sits.

    The message is ``<head> at <path><suffix><rest>``, ``path`` the dotted
    location pydantic reports (:func:`user_error` fills it in): ``suffix``
    names a key below it (``.time_s``), ``rest`` says what is allowed.
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


def _dotted(loc: tuple) -> str:
    out = ""
    for i, part in enumerate(loc):
        if isinstance(part, int):
            out += f"[{part}]"
        elif i and isinstance(loc[i - 1], int):
            # a key after a list index is the tag pydantic adds inside a tagged union
            # (the only lists of mappings are the tagged ones): not a key of the file
            continue
        else:
            out += f".{part}" if out else str(part)
    return out


def user_error(exc: ValidationError, prefix: str = "") -> UserInputError:
    """The one-line :class:`UserInputError` for pydantic's first error.

    ``prefix``: the dotted path of what was validated, when that is a block on
    its own rather than the whole scenario (``setpoint.cueing``).
    """
    err = exc.errors(include_url=False)[0]
    path = ".".join(p for p in (prefix, _dotted(err["loc"])) if p)
    cause = (err.get("ctx") or {}).get("error")
    if isinstance(cause, UserInputError):  # an absolute message (names its own path)
        return UserInputError(str(cause))
    if isinstance(cause, Problem):
        where = f"{path}{cause.suffix}" if path else cause.suffix.lstrip(".") or "top level"
        return UserInputError(f"{cause.head} at {where}{cause.rest}")
    # not expected from these models (every rule raises Problem): still one line
    msg = " ".join(str(err["msg"]).split())
    return UserInputError(
        f"invalid value at {path or 'top level'}: {value_text(err.get('input'))}; allowed: {msg}"
    )


# ------------------------------------------------------------------ leaves


def number(value: Any) -> float:
    """A finite number (booleans refused; ``'5e-3'``, which YAML 1.1 reads as a string, taken)."""
    if isinstance(value, str) and _EXP_RE.match(value.strip()):
        value = float(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise Problem.wrong_type(value, "a number")
    x = float(value)
    if not math.isfinite(x):
        raise Problem.invalid(value, "a finite number")
    return x


def integer(value: Any) -> int:
    x = number(value)
    if x != int(x):
        raise Problem.invalid(value, "an integer")
    return int(x)


def below(check: Callable, value: Any, suffix: str) -> Any:
    """``check(value)`` with a :class:`Problem` moved down to ``suffix``."""
    try:
        return check(value)
    except Problem as p:
        raise Problem(p.head, p.rest, suffix + p.suffix) from None


def multiple_of_step(value: Any) -> Any:
    """A period (ms): a positive integer multiple of the 1 ms physics step, <= MAX_PERIOD_MS.

    The one check of a period or sampling rate; ``2.5`` says so, not "integer".
    """
    if whole_steps(float(value) * 1e-3, PHYSICS_DT_S) is None or float(value) > MAX_PERIOD_MS:
        raise Problem.invalid(
            value,
            f"a positive integer multiple of the {PHYSICS_DT_MS} ms physics step, "
            f"<= {MAX_PERIOD_MS} ms",
        )
    return value


def _leaf(value: Any, default: Any, name: str) -> Any:
    """``value`` checked against the type of its default (the block's field), normalised."""
    if isinstance(default, list):
        n = len(default)
        one = name in _ONE_FOR_ALL
        if one and not isinstance(value, (list, tuple, Mapping, str)):
            value = [number(value)] * n  # one number: every leg's
        if not isinstance(value, (list, tuple)) or len(value) != n:
            raise Problem.wrong_type(
                value, f"{'one number or ' if one else ''}a list of {n} numbers like {default}"
            )
        return [below(number, v, f"[{i}]") for i, v in enumerate(value)]
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise Problem.wrong_type(value, "true or false")
        return value
    if isinstance(default, int):
        if name.endswith(("period_ms", "rate_ms")) and isinstance(value, (int, float)):
            if not isinstance(value, bool):
                multiple_of_step(value)
        return integer(value)
    if isinstance(default, float):
        return number(value)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise Problem.wrong_type(value, "a string")
        return value
    raise TypeError(f"unsupported default for {name}: {default!r}")  # pragma: no cover


#: Per-leg lists that also take one number for all legs.
_ONE_FOR_ALL = frozenset({"time_ms", "dead_band_mm"})


def rule(ok: Callable[[Any], bool], allowed: str) -> AfterValidator:
    """A range rule: every value (a list's elements) must pass ``ok``; else ``allowed``."""

    def check(value):
        if not all(ok(v) for v in (value if isinstance(value, list) else [value])):
            raise Problem.invalid(value, allowed)
        return value

    return AfterValidator(check)


def one_of(choices: tuple) -> AfterValidator:
    """An enumeration rule: the allowed values listed, the closest one suggested."""

    def check(value):
        if value not in choices:
            hint = closest(str(value), map(str, choices))
            raise Problem.invalid(value, f"one of {list(choices)}{hint}")
        return value

    return AfterValidator(check)


def listed(choices) -> BeforeValidator:
    """An enumeration checked before any type coercion, ``allowed: [...]`` (the words of
    the ``setpoint.cueing`` block; :func:`one_of` elsewhere)."""
    names = list(choices)

    def check(value):
        if value not in names:
            raise Problem.invalid(value, str(names))
        return value

    return BeforeValidator(check)


# ------------------------------------------------------------------ blocks


_DEFAULTS: dict[type, dict] = {}


class Block(BaseModel):
    """A block of the scenario: its fields are its keys, each with its default.

    ``_path`` is where the block sits in a scenario; a key the block does not
    have is refused with the closest valid one, every leaf is checked against
    the type of its default and normalised by :func:`_leaf` (so that ``15`` and
    ``15.0`` hash alike). Fields in ``_own`` check themselves.
    """

    model_config = ConfigDict(extra="forbid", protected_namespaces=(), validate_assignment=False)
    _path: ClassVar[str] = ""
    _own: ClassVar[frozenset] = frozenset()

    @classmethod
    def defaults(cls) -> Mapping:
        """The block's keys with their defaults, as a plain tree (computed once)."""
        tree = _DEFAULTS.get(cls)
        if tree is None:
            tree = _DEFAULTS[cls] = cls.model_construct().model_dump()
        return tree

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data: Any) -> Any:
        if not isinstance(data, Mapping):
            raise Problem.wrong_type(data, "a mapping")
        ref = cls.defaults()
        for key in data:
            if key not in cls.model_fields:
                raise Problem(
                    "unknown key",
                    f": allowed keys are {sorted(ref)}{closest(str(key), ref)}",
                    f".{key_text(key)}",
                )
        return data

    @field_validator("*", mode="before")
    @classmethod
    def _typed_leaf(cls, value: Any, info) -> Any:
        default = cls.defaults().get(info.field_name)
        if info.field_name in cls._own or isinstance(default, Mapping) or default is None:
            return value
        return _leaf(value, default, info.field_name)


# ------------------------------------------------------------------ tagged entries


class Entry(BaseModel):
    """A tagged mapping (``{type: step, ...}``): fields without a default are required."""

    model_config = ConfigDict(extra="forbid")

    @classmethod
    def required(cls) -> tuple[str, ...]:
        return tuple(k for k, f in cls.model_fields.items() if k != "type" and f.is_required())

    @classmethod
    def optional(cls) -> dict[str, Any]:
        return {k: f.default for k, f in cls.model_fields.items() if not f.is_required()}


def tagged(kinds: Mapping[str, type[Entry]], noun: str, example: str) -> BeforeValidator:
    """The tag, the keys and the required keys of one entry, before its model sees it
    (the messages of :func:`simpro_mj.core.keys.check_tagged`)."""
    names = list(kinds)

    def check(entry: Any) -> Any:
        if not isinstance(entry, Mapping):
            raise Problem.wrong_type(entry, f"a {noun} mapping like {example[1:-1]}")
        kind = entry.get("type")
        if not isinstance(kind, str) or kind not in kinds:
            if "type" not in entry:
                raise Problem("missing key", f": allowed: one of {names}", ".type")
            raise Problem.invalid(kind, f"one of {names}{closest(str(kind), names)}", ".type")
        model = kinds[kind]
        allowed = ["type", *model.required(), *model.optional()]
        for key in entry:
            if key not in allowed:
                rest = f": allowed keys of a {kind} are {allowed}{closest(str(key), allowed)}"
                raise Problem("unknown key", rest, f".{key_text(key)}")
        for key in model.required():
            if key not in entry:
                raise Problem(
                    "missing key", f": a {kind} needs {list(model.required())}", f".{key}"
                )
        return entry

    return BeforeValidator(check)


def tagged_list(noun: str, example: str) -> BeforeValidator:
    def check(value: Any) -> list:
        if value is None:
            return []
        if not isinstance(value, (list, tuple)):
            raise Problem.wrong_type(value, f"a list of {noun}s like {example}")
        return list(value)

    return BeforeValidator(check)
