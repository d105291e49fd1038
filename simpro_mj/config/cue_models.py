"""The ``setpoint.cueing`` block of the typed scenario (pydantic v2).

A scenario has the block or not (it is not in the default tree), so these
models list their own keys: a vehicle input (``telemetry``, ``manoeuvre``,
``sine`` or ``step``) through a motion-cueing ``algorithm`` and its
``parameters`` (:mod:`simpro_mj.config.cueing`). Their messages keep the
contract of docs/robustness.md (tests/data/scenario_messages.json, the
cue_braking cases): the washout's and the MPC's own checks are the one
statement of their parameters' ranges.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Annotated, Any, ClassVar

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    SerializeAsAny,
    SkipValidation,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_serializer,
    model_validator,
)

from controllers.cue_mpc_params import MpcParamError
from controllers.washout import WashoutParamError
from simpro_mj.config.cue_params import (
    ALGORITHMS,
    SINE_CHANNELS,
    default_parameters,
    manoeuvre_spec,
    washout_params,
)
from simpro_mj.config.messages import validated
from simpro_mj.core.keys import Problem, key_text
from simpro_mj.core.rates import PHYSICS_DT_MS, whole_steps


def listed(choices) -> BeforeValidator:
    """An enumeration checked before any type coercion, ``allowed: [...]``."""
    names = list(choices)

    def check(value):
        if value not in names:
            raise Problem.invalid(value, str(names))
        return value

    return BeforeValidator(check)


#: A cueing ``sine``'s period (s): 20 physics steps .. 10 minutes, on the 1 ms grid.
CUE_SINE_PERIOD_S = (0.02, 600.0)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


#: The default of a value a block requires: ``None``, validated (``validate_default``)
#: and refused by the field's own check, whose message says what is allowed.
REQUIRED: Any = None


class CueBlock(BaseModel):
    """A mapping of the cueing block: a mapping with its own keys, checked before its fields.

    ``_expected`` completes "expected ..." for a value that is not a mapping;
    ``_listed`` is the allowed keys in the order an unknown key's message
    lists them (default: sorted). A field left out takes its default, which
    is validated too (``None`` for a required value: its message says what
    is allowed).
    """

    model_config = ConfigDict(extra="forbid", validate_default=True)
    _expected: ClassVar[str] = "a mapping"
    _listed: ClassVar[tuple[str, ...]] = ()

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data: Any) -> Any:
        if not isinstance(data, Mapping):
            raise Problem("invalid value", f": expected {cls._expected}")
        allowed = list(cls._listed or sorted(cls.model_fields))
        for key in data:
            if key not in cls.model_fields:
                raise Problem("unknown key", f": allowed keys are {allowed}", f".{key_text(key)}")
        return cls._whole(data)

    @classmethod
    def _whole(cls, data: Mapping) -> Mapping:
        """A rule across the given keys, before the fields (none by default)."""
        return data


def _finite(value: Any) -> float:
    # not rules.number: a washout parameter is a YAML number; a string such as '5e-3' is refused
    if not _is_number(value) or not math.isfinite(value):
        raise Problem.invalid(value, "a finite number")
    return float(value)


def _whole_as_int(value: Any) -> int | float:
    # rot_order: an int when whole, as its default (the shipped scenarios' hashes)
    x = _finite(value)
    return int(x) if x == int(x) else x


class _WashoutCheck(CueBlock):
    """The washout's own ranges (:class:`controllers.washout.WashoutParams`), once every
    parameter is a number."""

    _algorithm: ClassVar[str] = "classical_washout"

    @model_validator(mode="after")
    def _washout(self):
        try:
            washout_params({"algorithm": self._algorithm, "parameters": dict(self)})
        except (WashoutParamError, MpcParamError) as exc:
            raise Problem("invalid value", f": {exc}") from None
        return self


class _MpcCheck(_WashoutCheck):
    """The MPC's own ranges (:class:`controllers.cue_mpc_params.MpcParams`)."""

    _algorithm: ClassVar[str] = "mpc"


def _parameters_model(name: str, base: type[_WashoutCheck], algorithm: str) -> type[_WashoutCheck]:
    fields: dict[str, Any] = {
        key: (
            Annotated[int | float, BeforeValidator(_whole_as_int)]
            if isinstance(default, int)
            else Annotated[float, BeforeValidator(_finite)],
            default,
        )
        for key, default in default_parameters(algorithm).items()
    }
    return create_model(name, __base__=base, __module__=__name__, **fields)


#: ``setpoint.cueing.parameters``: the keys of :data:`~simpro_mj.config.cue_params.PARAMETER_KEYS`
#: (YAML units), each a finite number, the defaults those of the washout.
if TYPE_CHECKING:  # built from the algorithm's defaults: the type checker sees its base
    WashoutParameters = _WashoutCheck
else:
    WashoutParameters = _parameters_model("WashoutParameters", _WashoutCheck, "classical_washout")
#: ``setpoint.cueing.parameters`` of ``algorithm: mpc``: the keys of
#: :data:`~simpro_mj.config.cue_params.MPC_PARAMETER_KEYS`, the defaults those of the MPC.
MpcParameters = _parameters_model("MpcParameters", _MpcCheck, "mpc")


class CueManoeuvre(CueBlock):
    """A generated vehicle input (:mod:`simpro_mj.config.manoeuvres`): its
    ``ManoeuvreSpec``'s fields and defaults; ``type`` and ``speed_kmh`` required.

    The values are kept as given (an integral speed stays an int, as it always
    did: the scenario's hash) and checked by ``ManoeuvreSpec.check``, the one
    statement of their ranges.
    """

    _expected = "a mapping with type and speed_kmh"
    type: SkipValidation[str | None] = None
    speed_kmh: SkipValidation[int | float | None] = None
    vehicle: SkipValidation[str] = "bmw_320i"
    deceleration_mps2: SkipValidation[int | float] = 5.0
    bump_height_m: SkipValidation[int | float] = 0.06
    bump_length_m: SkipValidation[int | float] = 0.5
    lead_s: SkipValidation[int | float] = 1.0
    tyre_offsets: SkipValidation[str] = "none"

    @model_validator(mode="after")
    def _spec(self):
        # imported on use: manoeuvres loads scipy.signal and scipy.integrate (about
        # 1.5 s), which only a scenario with a manoeuvre needs
        from simpro_mj.config.manoeuvres import MANOEUVRES, ManoeuvreError

        if self.type not in MANOEUVRES:
            raise Problem.invalid(self.type, str(list(MANOEUVRES)), ".type")
        if self.speed_kmh is None:
            raise Problem("invalid value", ": missing; allowed: 10..180", ".speed_kmh")
        try:
            manoeuvre_spec(self).check()
        except ManoeuvreError as exc:
            # the spec names its field alone ("invalid value at lead_s: ..."): put it below
            key, _, rest = str(exc).removeprefix("invalid value at ").partition(":")
            raise Problem("invalid value", f":{rest}", f".{key}") from None
        return self


def _sine_period(value: Any) -> float:
    lo, hi = CUE_SINE_PERIOD_S
    if not (_is_number(value) and lo <= value <= hi) or whole_steps(value) is None:
        raise Problem.invalid(value, f"{lo:g}..{hi:g} s on the {PHYSICS_DT_MS:g} ms grid")
    return float(value)


class _OnAChannel(CueBlock):
    """A vehicle input on one ``channel`` (:data:`~simpro_mj.config.cue_params.SINE_CHANNELS`)
    of ``amplitude`` (SI; ``_signed``: of either sign)."""

    _signed: ClassVar[bool] = False
    channel: Annotated[str, listed(SINE_CHANNELS)] = REQUIRED
    amplitude: float = REQUIRED

    @field_validator("amplitude", mode="before")
    @classmethod
    def _up_to_the_channel(cls, value: Any, info: ValidationInfo) -> Any:
        """0 < amplitude (signed: |amplitude|) <= the channel's limit (1 g, 90 deg/s)."""
        channel = info.data.get("channel")
        if channel is None:  # the channel's own error is the one reported
            return value
        top = SINE_CHANNELS[channel]
        if not (_is_number(value) and 0 < (abs(value) if cls._signed else value) <= top):
            if cls._signed:
                raise Problem.invalid(value, f"0 < |amplitude| <= {top:.4g}")
            unit = channel.split("_", 1)[1].replace("mps2", "m/s^2").replace("rad_s", "rad/s")
            raise Problem.invalid(value, f"0 < amplitude <= {top:.4g} ({unit})")
        return float(value)


class CueSine(_OnAChannel):
    """A synthetic vehicle input: the vehicle at rest plus ``amplitude sin(2 pi t /
    period_s)`` (SI) on one ``channel`` (:data:`~simpro_mj.config.cue_params.SINE_CHANNELS`)."""

    _listed = ("channel", "amplitude", "period_s")
    _expected = f"a mapping with keys {list(_listed)}"
    period_s: Annotated[float, BeforeValidator(_sine_period)] = REQUIRED


class CueStep(_OnAChannel):
    """A large-signal vehicle input: the vehicle at rest plus ``amplitude`` (SI, signed)
    on one ``channel`` from ``start_s``, reached over ``ramp_s`` (0: a step), back from
    ``end_s`` (null: held) (:func:`~simpro_mj.config.cueing.step_input`)."""

    _listed = ("channel", "amplitude", "start_s", "ramp_s", "end_s")
    _expected = f"a mapping with keys {list(_listed)}"
    _signed = True
    start_s: Annotated[float, BeforeValidator(_finite)] = 1.0
    ramp_s: Annotated[float, BeforeValidator(_finite)] = 0.0
    end_s: float | None = None

    @model_validator(mode="after")
    def _times(self):
        if self.start_s < 0:
            raise Problem.invalid(self.start_s, ">= 0 s", ".start_s")
        if self.ramp_s < 0:
            raise Problem.invalid(self.ramp_s, ">= 0 s (0: a step)", ".ramp_s")
        if self.end_s is not None and not self.end_s >= self.start_s + self.ramp_s:
            raise Problem.invalid(self.end_s, "null or >= start_s + ramp_s", ".end_s")
        return self


def _file_name(value: Any) -> str | None:
    # its existence is checked once the scenario's folder is known (cueing.resolve_paths)
    if value is not None and (not isinstance(value, str) or not value.strip()):
        raise Problem.invalid(value, "a file name")
    return value


class Cueing(CueBlock):
    """``setpoint.cueing``: a vehicle input, exactly one of ``telemetry`` (a CSV file),
    ``manoeuvre`` (generated) or ``sine``, through a motion-cueing ``algorithm`` and
    its ``parameters`` (:mod:`simpro_mj.config.cueing`)."""

    _expected = "a mapping with telemetry or manoeuvre"
    _listed = ("telemetry", "manoeuvre", "sine", "step", "algorithm", "parameters", "columns")
    # declared in the order they are checked (the first error is the one reported)
    telemetry: Annotated[str | None, BeforeValidator(_file_name)] = None
    algorithm: Annotated[str, listed(ALGORITHMS)] = "classical_washout"
    # null (or empty) parameters: every default (the default is validated too)
    parameters: SerializeAsAny[Annotated[WashoutParameters, BeforeValidator(lambda v: v or {})]] = (
        None  # type: ignore[assignment]
    )
    manoeuvre: CueManoeuvre | None = None
    sine: CueSine | None = None
    step: CueStep | None = None
    #: telemetry column mapping (:data:`~simpro_mj.config.telemetry.MAPPING_HELP`)
    columns: dict | None = None

    @field_validator("parameters", mode="wrap")
    @classmethod
    def _of_the_algorithm(cls, value: Any, handler, info: ValidationInfo) -> Any:
        """``parameters`` of the chosen ``algorithm``: the washout's, or the MPC's."""
        if info.data.get("algorithm") != "mpc":
            return handler(value)
        try:
            return MpcParameters.model_validate(value or {})
        except ValidationError as exc:
            err = exc.errors()[0]
            loc = "".join(f".{key_text(k)}" for k in err["loc"])
            msg = str(err.get("msg", "")).removeprefix("Value error, ")
            head, _, rest = msg.partition(" at <here>")
            raise Problem(head or "invalid value", rest, loc) from None

    @field_validator("columns", mode="before")
    @classmethod
    def _mapping(cls, value: Any) -> Any:
        from simpro_mj.config.telemetry import check_mapping

        if value is None or value == {}:
            return None
        try:
            return check_mapping(value)
        except ValueError as exc:
            raise Problem("invalid value", f": {exc}") from None

    @classmethod
    def _whole(cls, data: Mapping) -> Mapping:
        if sum(data.get(k) is not None for k in ("telemetry", "manoeuvre", "sine", "step")) != 1:
            raise Problem(
                "invalid value",
                ": give exactly one of telemetry (a CSV file), manoeuvre, sine or step",
            )
        return data

    @model_serializer(mode="wrap")
    def _as_resolved(self, handler):
        """Every key spelled out (``manoeuvre: null`` when absent), ``sine`` only when given:
        the block the rest of the code reads and the scenario's hash has always seen."""
        out = handler(self)
        resolved = {k: out[k] for k in ("telemetry", "manoeuvre", "algorithm", "parameters")}
        if self.sine is not None:
            resolved["sine"] = out["sine"]
        if self.step is not None:
            resolved["step"] = out["step"]
        if self.columns is not None:
            resolved["columns"] = out["columns"]
        return resolved


def check_cueing(value: Any) -> dict:
    """A ``setpoint.cueing`` block on its own, validated by :class:`Cueing` and spelled out.

    Parameters
    ----------
    value : Any
        The block as written (``{"sine": {...}}``).

    Returns
    -------
    dict
        The block as the resolved scenario holds it (every parameter given).

    Raises
    ------
    UserInputError
        One line naming the dotted key and what is allowed.
    """
    return validated(Cueing, value, "setpoint.cueing").model_dump()
