"""The vocabulary of the typed scenario: leaf types, parameters, the one error formatter.

A block of the scenario is a pydantic v2 model (:class:`Block`: unknown keys
refused) whose fields are declared with :func:`param`: default, unit, allowed
range (pydantic's own ``ge``, ``gt``, ``le``, ``lt``, ``min_length``, ...) and
one line of meaning. The leaf types say what a value is:

* :data:`Real`: a finite number; an integer is taken, a boolean or a string
  refused, except the exponent form ``5e-3`` (no dot), which YAML 1.1 reads as a
  string (the one number policy of the scenario and its sweeps);
* :data:`Whole`: an integer (``60.0`` taken as 60, ``2.5`` refused);
* :data:`Period`: a whole number of 1 ms physics steps (ms);
* :data:`Numbers` (``Numbers[list[float], Each(3, ge=0)]``): a list of numbers of
  fixed length, each in a range (``one=True``: one number stands for all);
* ``StrictBool``, ``StrictStr`` and ``Literal`` choices from pydantic.

A value refused is said in one line by
:func:`simpro_mj.config.messages.user_error`. A rule across fields raises
:class:`Problem` (its text relative to where the rule sits) or a
:class:`~simpro_mj.core.errors.UserInputError` (an absolute message, for rules
that name another field).
"""

from __future__ import annotations

import math
import re
import types
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, get_args

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
)

# the leaf types, blocks and refusals live in core.keys, where the plant's blocks reach them
from simpro_mj.core.keys import Problem, Real, integral, yaml_number
from simpro_mj.core.rates import PHYSICS_DT_MS, PHYSICS_DT_S, whole_steps

Mode = Literal["joint_only", "task_space", "feedforward"]
OuterType = Literal["I", "PI"]
# controller.inner.design_plant: "auto" is "paper" on the paper preset and
# "identified" on any other (config.models.Scenario resolves it at load)
DesignPlant = Literal["auto", "paper", "identified"]
# controller.inner.identify (simpro_mj.identification.auto)
IdentifyChoice = Literal["auto", "preset", "linearised", "reduced"]
IDENTIFY_CHOICES: tuple[IdentifyChoice, ...] = get_args(IdentifyChoice)
DelaySamples = Literal[1, 2]
SETPOINT_AXES = ("roll_deg", "pitch_deg", "heave_mm")
FaultSensor = Literal["potentiometer", "height_encoder", "imu"]
FaultAxis = Literal["roll", "pitch"]
PotMode = Literal["open", "short"]

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


# ------------------------------------------------------------------ a rule's refusal


# ------------------------------------------------------------------ leaf types


def check_period(value: float) -> Any:
    """A period (ms): a positive integer multiple of the 1 ms physics step, <= MAX_PERIOD_MS."""
    if whole_steps(value * 1e-3, PHYSICS_DT_S) is None or value > MAX_PERIOD_MS:
        raise Problem.invalid(
            value,
            f"a positive integer multiple of the {PHYSICS_DT_MS} ms physics step, "
            f"<= {MAX_PERIOD_MS} ms",
        )
    return value


def period_before(value: Any) -> Any:
    # 2.5 ms is "not a multiple of the step", not "not an integer"
    value = yaml_number(value)
    if isinstance(value, float) and math.isfinite(value) and value != int(value):
        check_period(value)
    return integral(value)


#: A period in ms: a positive whole number of physics steps, at most MAX_PERIOD_MS.
Period = Annotated[int, BeforeValidator(period_before), Strict(), AfterValidator(check_period)]


class _OneForAll:
    """Marks a list that also takes one number for all its items (:class:`Each`)."""


ONE_FOR_ALL = _OneForAll()


def _broadcast(n: int):
    def check(value: Any) -> Any:
        value = yaml_number(value)
        if isinstance(value, int | float) and not isinstance(value, bool):
            return [value] * n
        return value

    return BeforeValidator(check)


class Each:
    """The shape of a list of numbers (:data:`Numbers`): ``n`` numbers, each within
    ``bounds`` (``ge=0``, ...); ``one``: one number stands for all ``n`` (a per-leg
    value given once)."""

    def __init__(self, n: int, *, one: bool = False, **bounds: Any) -> None:
        self.n, self.one, self.bounds = n, one, bounds

    def annotation(self) -> Any:
        """The pydantic annotation: ``list[Real]`` of length ``n``, each item in range."""
        annotated: Any = Annotated  # built at run time: a value to the type checker
        item = annotated[Real, Field(**self.bounds)] if self.bounds else Real
        meta: list = [Field(min_length=self.n, max_length=self.n)]
        if self.one:
            meta[:0] = [_broadcast(self.n), ONE_FOR_ALL]
        return annotated[tuple([types.GenericAlias(list, (item,)), *meta])]


if TYPE_CHECKING:
    from typing import Annotated as Numbers
else:

    class Numbers:
        """``Numbers[list[float], Each(3, ge=0)]``: a list of numbers of the shape
        :class:`Each` says. The type checker reads it as ``Annotated`` (a
        ``list[float]``); pydantic reads the list, its length and its items' ranges."""

        def __class_getitem__(cls, args: tuple[Any, Each]) -> Any:
            return args[1].annotation()


# ------------------------------------------------------------------ blocks


class Entry(BaseModel):
    """A tagged mapping (``{type: step, ...}``) of a discriminated union: fields
    without a default are required."""

    model_config = ConfigDict(extra="forbid")
    #: what one entry is called in a message ("a list of components")
    noun: ClassVar[str] = "entry"


def none_as_empty(value: Any) -> Any:
    """``null`` for a list of entries: none."""
    return [] if value is None else value
