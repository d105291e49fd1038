"""The tagged entries of a scenario: set-point components and faults (pydantic v2).

Set-point components (``setpoint.roll_deg``, ``pitch_deg``, ``heave_mm``: a list
each, in the axis' unit) and faults (``faults``) are lists of mappings tagged by
``type``; each type is a model here, its fields without a default required,
its optional keys spelled out in the resolved scenario with their defaults.
What they mean: :mod:`simpro_mj.config.scenario` (module docstring) and
:mod:`simpro_mj.plant.faults`.
"""

from __future__ import annotations

import math
from typing import Annotated, ClassVar, Literal

import numpy as np
from pydantic import BeforeValidator, Field, model_validator

from simpro_mj.config.rules import (
    SINE_PERIOD_RANGE_S,
    Entry,
    FaultAxis,
    FaultSensor,
    PotMode,
    none_as_empty,
)
from simpro_mj.core.keys import Problem, Real, Whole

#: Largest sensor bias of a fault: 90 deg (imu), 500 mm (a whole stroke).
_BIAS_BOUND = {"bias_deg": 90.0, "bias_mm": 500.0}

Time = Annotated[Real, Field(ge=0, json_schema_extra={"unit": "s"})]
NumberList = Annotated[list[Real], Field(min_length=1)]


# ------------------------------------------------------------------ set-point components


class ComponentEntry(Entry):
    """A set-point component (summed on its axis)."""

    noun: ClassVar[str] = "component"


class Step(ComponentEntry):
    """``value`` from ``time_s`` on (t >= time_s)."""

    type: Literal["step"]
    time_s: Time
    value: Real

    def at(self, t: np.ndarray) -> np.ndarray:
        """The component at times ``t`` (s), in its axis' unit."""
        return np.where(t >= self.time_s, self.value, 0.0)


class Ramp(ComponentEntry):
    """0 before ``start_s``, linear to ``value`` at ``end_s``, held after."""

    type: Literal["ramp"]
    start_s: Time
    end_s: Real
    value: Real

    def at(self, t: np.ndarray) -> np.ndarray:
        """The component at times ``t`` (s), in its axis' unit."""
        return self.value * np.clip((t - self.start_s) / (self.end_s - self.start_s), 0.0, 1.0)

    @model_validator(mode="after")
    def _times(self):
        if self.end_s <= self.start_s:
            raise Problem.invalid(self.end_s, f"> start_s = {self.start_s} s", ".end_s")
        return self


class Sine(ComponentEntry):
    """``amplitude sin(2 pi (t - start_s) / period_s + phase)`` for ``start_s <= t < end_s``."""

    type: Literal["sine"]
    amplitude: Real
    period_s: Real = Field(
        ge=SINE_PERIOD_RANGE_S[0],
        le=SINE_PERIOD_RANGE_S[1],
        description="two physics steps (the 1 ms grid's Nyquist limit) at least",
        json_schema_extra={"unit": "s"},
    )
    phase_deg: Real = 0.0
    start_s: Time = 0.0
    end_s: Real | None = None

    def at(self, t: np.ndarray) -> np.ndarray:
        """The component at times ``t`` (s), in its axis' unit (the phase from ``start_s``)."""
        end = math.inf if self.end_s is None else self.end_s
        phase = math.radians(self.phase_deg)
        wave = self.amplitude * np.sin(2.0 * np.pi * (t - self.start_s) / self.period_s + phase)
        return np.where((t >= self.start_s) & (t < end), wave, 0.0)

    @model_validator(mode="after")
    def _times(self):
        if self.end_s is not None and self.end_s <= self.start_s:
            raise Problem.invalid(self.end_s, f"null or > start_s = {self.start_s} s", ".end_s")
        return self


class Table(ComponentEntry):
    """Piecewise linear through the points, the first/last value held outside."""

    type: Literal["table"]
    times_s: NumberList
    values: NumberList

    def at(self, t: np.ndarray) -> np.ndarray:
        """The component at times ``t`` (s), in its axis' unit."""
        return np.interp(t, np.asarray(self.times_s, float), np.asarray(self.values, float))

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


Component = Annotated[Step | Ramp | Sine | Table, Field(discriminator="type")]
#: A set-point axis: components such as [{type: step, time_s: 1.0, value: 3.0}] (null: none).
Components = Annotated[list[Component], BeforeValidator(none_as_empty)]


# ------------------------------------------------------------------ faults

Leg = Annotated[Whole, Field(ge=1, le=3, description="a leg number 1, 2 or 3")]


class Fault(Entry):
    """A scheduled event from ``time_s`` (>= 0) on (:mod:`simpro_mj.plant.faults`)."""

    noun: ClassVar[str] = "fault"
    time_s: Time

    @model_validator(mode="after")
    def _window(self):
        end = getattr(self, "end_s", None)
        if end is not None and end <= self.time_s:
            raise Problem.invalid(end, f"null or > time_s = {self.time_s} s", ".end_s")
        return self


class SupplyDrop(Fault):
    type: Literal["supply_drop"]
    pressure_bar_gauge: Real
    ramp_s: Time = 0.0


class ValveStuck(Fault):
    type: Literal["valve_stuck"]
    leg: Leg
    voltage_v: Real = Field(ge=0, le=10, description="the MPYE's input range",
                            json_schema_extra={"unit": "V"})  # fmt: skip
    end_s: Real | None = None


class SensorFault(Fault):
    sensor: FaultSensor
    leg: Leg | None = None
    axis: FaultAxis | None = None
    end_s: Real | None = None

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
    probability: Real = Field(1.0, gt=0, le=1, description="that a sample is lost")


class SensorBias(SensorFault):
    type: Literal["sensor_bias"]
    bias_mm: Real | None = None
    bias_deg: Real | None = None

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
    mode: PotMode = "open"
    end_s: Real | None = None


AnyFault = Annotated[
    SupplyDrop | ValveStuck | SensorFrozen | SensorDropout | SensorBias | PotentiometerFailure,
    Field(discriminator="type"),
]
#: Scheduled faults such as [{type: supply_drop, time_s: 5.0, pressure_bar_gauge: 2.0}].
Faults = Annotated[list[AnyFault], BeforeValidator(none_as_empty)]
