"""The tagged entries of a scenario: set-point components and faults (pydantic v2).

Set-point components (``setpoint.roll_deg``, ``pitch_deg``, ``heave_mm``: a list
each, in the axis' unit) and faults (``faults``) are lists of mappings tagged by
``type``; each type is a model here, its fields without a default required,
its optional keys spelled out in the resolved scenario with their defaults.
What they mean: :mod:`simpro_mj.config.scenario` (module docstring) and
:mod:`simpro_mj.plant.faults`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, model_validator

from simpro_mj.config.rules import (
    FAULT_AXES,
    FAULT_SENSORS,
    POT_MODES,
    SINE_PERIOD_RANGE_S,
    Entry,
    Problem,
    below,
    closest,
    integer,
    number,
    tagged,
    tagged_list,
)

__all__ = ["COMPONENTS", "FAULTS", "COMPONENT_TYPES", "FAULT_TYPES", "Components", "Faults"]

#: Largest sensor bias of a fault: 90 deg (imu), 500 mm (a whole stroke).
_BIAS_BOUND = {"bias_deg": 90.0, "bias_mm": 500.0}

Number = Annotated[float, BeforeValidator(number)]
OptionalNumber = Annotated[float | None, BeforeValidator(lambda v: v if v is None else number(v))]


def _numbers(value: Any) -> list[float]:
    if not isinstance(value, (list, tuple)) or not value:
        raise Problem.wrong_type(value, "a non-empty list of numbers")
    return [below(number, v, f"[{i}]") for i, v in enumerate(value)]


# ------------------------------------------------------------------ set-point components


class Step(Entry):
    """``value`` from ``time_s`` on (t >= time_s)."""

    type: Literal["step"]
    time_s: Number
    value: Number

    @model_validator(mode="after")
    def _times(self):
        if self.time_s < 0:
            raise Problem.invalid(self.time_s, ">= 0 s", ".time_s")
        return self


class Ramp(Entry):
    """0 before ``start_s``, linear to ``value`` at ``end_s``, held after."""

    type: Literal["ramp"]
    start_s: Number
    end_s: Number
    value: Number

    @model_validator(mode="after")
    def _times(self):
        if self.start_s < 0:
            raise Problem.invalid(self.start_s, ">= 0 s", ".start_s")
        if self.end_s <= self.start_s:
            raise Problem.invalid(self.end_s, f"> start_s = {self.start_s} s", ".end_s")
        return self


class Sine(Entry):
    """``amplitude sin(2 pi (t - start_s) / period_s + phase)`` for ``start_s <= t < end_s``."""

    type: Literal["sine"]
    amplitude: Number
    period_s: Number
    phase_deg: Number = 0.0
    start_s: Number = 0.0
    end_s: OptionalNumber = None

    @model_validator(mode="after")
    def _times(self):
        lo, hi = SINE_PERIOD_RANGE_S
        if not lo <= self.period_s <= hi:
            allowed = f"> 0 s: {lo:g} s (two physics steps) .. {hi:g} s"
            raise Problem.invalid(self.period_s, allowed, ".period_s")
        if self.start_s < 0:
            raise Problem.invalid(self.start_s, ">= 0 s", ".start_s")
        if self.end_s is not None and self.end_s <= self.start_s:
            raise Problem.invalid(self.end_s, f"null or > start_s = {self.start_s} s", ".end_s")
        return self


NumberList = Annotated[list[float], BeforeValidator(_numbers)]


class Table(Entry):
    """Piecewise linear through the points, the first/last value held outside."""

    type: Literal["table"]
    times_s: NumberList
    values: NumberList

    @model_validator(mode="after")
    def _points(self):
        times, values = self.times_s, self.values
        if len(values) != len(times):
            raise Problem.invalid(values, f"as many values as times_s ({len(times)})", ".values")
        for j in range(1, len(times)):
            if times[j] <= times[j - 1]:
                allowed = (
                    f"strictly increasing times (times_s[{j}] = {times[j]} <= "
                    f"times_s[{j - 1}] = {times[j - 1]})"
                )
                raise Problem.invalid(times, allowed, ".times_s")
        return self


COMPONENTS: dict[str, type[Entry]] = {"step": Step, "ramp": Ramp, "sine": Sine, "table": Table}
_COMPONENT_EXAMPLE = "[{type: step, time_s: 1.0, value: 3.0}]"
Component = Annotated[
    Annotated[Step | Ramp | Sine | Table, Field(discriminator="type")],
    tagged(COMPONENTS, "component", _COMPONENT_EXAMPLE),
]
Components = Annotated[list[Component], tagged_list("component", _COMPONENT_EXAMPLE)]


# ------------------------------------------------------------------ faults


def _leg(value: Any) -> int:
    leg = integer(value)
    if not 1 <= leg <= 3:
        raise Problem.invalid(value, "a leg number 1, 2 or 3")
    return leg


Leg = Annotated[int, BeforeValidator(_leg)]
OptionalLeg = Annotated[int | None, BeforeValidator(lambda v: v if v is None else _leg(v))]


def _choice(choices: tuple, nullable: bool):
    def check(value):
        if value is None and nullable:
            return None
        if value not in choices:
            raise Problem.invalid(value, f"one of {list(choices)}{closest(str(value), choices)}")
        return value

    return BeforeValidator(check)


class Fault(Entry):
    """A scheduled event from ``time_s`` (>= 0) on (:mod:`simpro_mj.plant.faults`)."""

    time_s: Number

    @model_validator(mode="after")
    def _window(self):
        if self.time_s < 0:
            raise Problem.invalid(self.time_s, ">= 0 s", ".time_s")
        end = getattr(self, "end_s", None)
        if end is not None and end <= self.time_s:
            raise Problem.invalid(end, f"null or > time_s = {self.time_s} s", ".end_s")
        return self


class SupplyDrop(Fault):
    type: Literal["supply_drop"]
    pressure_bar_gauge: Number
    ramp_s: Number = 0.0

    @model_validator(mode="after")
    def _ramp(self):
        if self.ramp_s < 0:
            raise Problem.invalid(self.ramp_s, ">= 0 s", ".ramp_s")
        return self


class ValveStuck(Fault):
    type: Literal["valve_stuck"]
    leg: Leg
    voltage_v: Number
    end_s: OptionalNumber = None

    @model_validator(mode="after")
    def _voltage(self):
        if not 0.0 <= self.voltage_v <= 10.0:
            raise Problem.invalid(self.voltage_v, "0..10 V (the MPYE's input range)", ".voltage_v")
        return self


class SensorFault(Fault):
    sensor: Annotated[str, _choice(FAULT_SENSORS, nullable=False)]
    leg: OptionalLeg = None
    axis: Annotated[str | None, _choice(FAULT_AXES, nullable=True)] = None
    end_s: OptionalNumber = None

    @model_validator(mode="after")
    def _which(self):
        if self.leg is not None and self.sensor != "potentiometer":
            allowed = f"null for sensor {self.sensor} (potentiometers only)"
            raise Problem.invalid(self.leg, allowed, ".leg")
        if self.axis is not None and self.sensor != "imu":
            raise Problem.invalid(self.axis, f"null for sensor {self.sensor} (imu only)", ".axis")
        return self


class SensorFrozen(SensorFault):
    type: Literal["sensor_frozen"]


class SensorDropout(SensorFault):
    type: Literal["sensor_dropout"]
    probability: Number = 1.0

    @model_validator(mode="after")
    def _probability(self):
        if not 0.0 < self.probability <= 1.0:
            raise Problem.invalid(self.probability, "0 < probability <= 1", ".probability")
        return self


class SensorBias(SensorFault):
    type: Literal["sensor_bias"]
    bias_mm: OptionalNumber = None
    bias_deg: OptionalNumber = None

    @model_validator(mode="after")
    def _bias(self):
        unit, other = ("bias_deg", "bias_mm") if self.sensor == "imu" else ("bias_mm", "bias_deg")
        if getattr(self, other) is not None:
            allowed = f"null for sensor {self.sensor}; use {unit}"
            raise Problem.invalid(getattr(self, other), allowed, f".{other}")
        value = getattr(self, unit)
        if value is None:
            raise Problem("missing key", f": a {self.sensor} bias needs {unit}", f".{unit}")
        if abs(value) > _BIAS_BOUND[unit]:
            raise Problem.invalid(value, f"|{unit}| <= {_BIAS_BOUND[unit]:g}", f".{unit}")
        return self


class PotentiometerFailure(Fault):
    type: Literal["potentiometer_failure"]
    leg: Leg
    mode: Annotated[str, _choice(POT_MODES, nullable=False)] = "open"
    end_s: OptionalNumber = None


FAULTS: dict[str, type[Entry]] = {
    "supply_drop": SupplyDrop,
    "valve_stuck": ValveStuck,
    "sensor_frozen": SensorFrozen,
    "sensor_dropout": SensorDropout,
    "sensor_bias": SensorBias,
    "potentiometer_failure": PotentiometerFailure,
}
_FAULT_EXAMPLE = "[{type: supply_drop, time_s: 5.0, pressure_bar_gauge: 2.0}]"
AnyFault = Annotated[
    Annotated[
        SupplyDrop | ValveStuck | SensorFrozen | SensorDropout | SensorBias | PotentiometerFailure,
        Field(discriminator="type"),
    ],
    tagged(FAULTS, "fault", _FAULT_EXAMPLE),
]
Faults = Annotated[list[AnyFault], tagged_list("fault", _FAULT_EXAMPLE)]

#: Set-point component and fault types: required keys, optional keys with their defaults.
COMPONENT_TYPES = {k: (m.required(), m.optional()) for k, m in COMPONENTS.items()}
FAULT_TYPES = {k: (m.required(), m.optional()) for k, m in FAULTS.items()}
