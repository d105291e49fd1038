"""The numbers of ``simpro-sim analyze`` as typed records (:mod:`simpro_mj.analysis.analyze`).

A record's public fields are its part of the ``--json`` document
(:meth:`Record.to_json`, in the order declared); its ``_``-prefixed fields are
the arrays the figures draw (:mod:`simpro_mj.report.analyze`), left out of it.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np


def json_value(obj: Any) -> Any:
    """``obj`` for JSON: records as their :meth:`~Record.to_json`, private ``_`` keys
    dropped, a non-finite float as null, ``"inf"`` or ``"-inf"``."""
    if isinstance(obj, Record):
        return obj.to_json()
    if isinstance(obj, dict):
        return {k: json_value(v) for k, v in obj.items() if not str(k).startswith("_")}
    if isinstance(obj, list | tuple):
        return [json_value(v) for v in obj]
    if isinstance(obj, float) and not np.isfinite(obj):
        return None if np.isnan(obj) else ("inf" if obj > 0 else "-inf")
    return obj


@dataclass
class Record:
    """A result whose public fields make its JSON document."""

    #: fields left out of the document when they are None
    omit_none: ClassVar[tuple[str, ...]] = ()

    def to_json(self) -> dict:
        """The public fields, in their order, as JSON values (:func:`json_value`)."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name.startswith("_") or (value is None and f.name in self.omit_none):
                continue
            out[f.name] = json_value(value)
        return out


@dataclass
class InnerLoop(Record):
    """One joint loop, continuous, on the paper's plant: poles, damping, unit step."""

    controller: dict
    closed_loop_poles: list
    wn_rad_s: list
    zeta: list
    slowest_complex_pair: dict
    step: dict
    fraction_at_outer_period: float
    _t: np.ndarray
    _y: np.ndarray


@dataclass
class DelayLoop(Record):
    """The outer loop with the inner loop as a delay (eqs. 21, 24-27)."""

    omit_none = ("paper_stability_limit",)

    period_s: float
    delay_samples: int
    gain: float
    stability_limit: float
    stability_limit_closed_form: float | None
    #: the name of the --json contract; decided by the poles (schur_stable)
    jury_stable_at_gain: bool
    poles: list
    pole_magnitudes: list
    step: dict | None
    _t: np.ndarray
    _y: np.ndarray
    _ab: tuple
    paper_stability_limit: float | None = None


@dataclass
class RealLoop(Record):
    """The outer loop around the real (discretised, lifted) inner loops."""

    variant: str
    period_s: float
    gain: float
    stability_limit: float
    stability_limit_per_leg: dict
    spectral_radius_at_gain: float
    stable_at_gain: bool
    step_heave: dict | None
    _t: np.ndarray
    _y: np.ndarray


@dataclass
class Limits(Record):
    """The stability limit of one law around one joint controller, and per leg."""

    stability_limit: float
    per_leg: dict


@dataclass
class RealLoops(Record):
    """Both laws around the real inner loops, at both periods, and per joint controller."""

    jacobian_at_home: np.ndarray
    I: RealLoop
    PI: RealLoop
    alt_period: dict[str, RealLoop]
    by_variant: dict[str, dict[str, Limits]]


@dataclass
class FeedforwardLoop(Record):
    """The feed-forward scheme's correction: its limit, pitch step and frequency response."""

    gain: float
    model_tau_s: float
    lag: str
    leg_velocity: bool
    stability_limit: float
    stability_limit_note: str
    stable_at_gain: bool
    step_pitch: dict | None
    frequency_response: dict
    _t: np.ndarray
    _y: np.ndarray


@dataclass
class SweepRow(Record):
    """One inner bandwidth of the delay-assumption sweep."""

    wn_rad_s: float
    inner_fraction_at_T: float
    inner_settling_time_s: float
    I_stability_limit: float
    PI_stability_limit: float


@dataclass
class DelaySweep(Record):
    """When is the inner loop a one-sample delay: the delay model's limits and the sweep."""

    delay_model: dict
    rows: list[SweepRow]


@dataclass
class OuterLoops(Record):
    """The outer loop's analyses."""

    I: DelayLoop
    PI: DelayLoop
    alt_period: dict[str, DelayLoop]
    real_inner: RealLoops
    feedforward: FeedforwardLoop
    delay_assumption_sweep: DelaySweep


@dataclass
class ShippedLoop(Record):
    """The loop a scenario ships, in words and numbers."""

    scenario: str
    preset: str
    mode: str
    law: str
    period_ms: float
    gains: list
    setpoint_filter: str
    joint_controllers: str
    dead_band: dict
    joint_integrator_dead_band_mm: list


@dataclass
class PlantLimit(Record):
    """The shipped loop's limit and spectral radius on one plant assumption."""

    stability_limit: float
    spectral_radius_at_gains: float
    stable_at_gains: bool
    basis: str


@dataclass
class Shipped(Record):
    """The shipped loop on the plant its actuators stand for and on eqs. (34)-(35)."""

    loop: ShippedLoop
    actuator: PlantLimit
    paper: PlantLimit


@dataclass
class Analysis(Record):
    """Everything ``simpro-sim analyze`` computes."""

    omit_none = ("shipped",)

    shipped: Shipped | None
    paper: dict
    paper_units: dict
    inner: dict[str, dict[str, InnerLoop]]
    outer: OuterLoops
