"""Plant presets: named sets of the plant's uncertain parameters (YAML, package data).

A preset holds what the paper does not print and a calibration fits (Table 1
is lost): the moving masses, leg friction, valve flow. Scenarios name one in
``plant.preset``; ``simpro-sim identify --preset`` and ``simpro-sim
calibrate`` use the same files. Shipped presets (``scenarios/presets/``):

* ``paper`` (default): calibrated so that ``simpro-sim identify`` reproduces
  eqs. (34)-(35) under the potentiometer-volts reading
  (``docs/paper-notes.md`` section 3);
* ``heavy_cabin``: a driving-simulator cabin with its driver (230 kg), the
  catalogue valve and spool, the seals' breakaway and Stribeck friction, each
  value physically argued (``docs/paper-notes.md`` section 3.8); its identified
  models are far from eqs. 34-35.

A preset file is a mapping::

    name: paper
    description: ...
    plant: {payload: {mass_kg: ...}, ...}         # over simpro_mj.plant.model.DEFAULT_MODEL_PARAMS
    pneumatics: {cylinder: {...}, valve: {...}}   # over DEFAULT_PNEUMATIC_PARAMS
    sensors: {imu: {...}, potentiometer: {...}}   # the rig's sensor errors, over the scenario's
    identified: {actuator1: {b, a1, a0}, ...}     # what identify measures on it (SI)
    controller: {outer: {dead_band: ...}, ...}    # the controller options this plant needs
    calibration: {...}                            # free-form record (targets, residuals)

Values in a scenario's own ``plant``, ``actuator.pneumatics``, ``sensors`` and
``controller`` override the preset's. A preset's ``controller`` block holds what
its plant needs beyond the joint loops placed on its identified models (the
dead band against its seal friction, the set-point filter that matches its
legs' lags: docs/paper-notes.md, controllers for the heavy cabin).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import closest, read_yaml
from simpro_mj.core.shipped import PRESETS_DIR, user_path

DEFAULT_PRESET = "paper"
PRESET_KEYS = (
    "name",
    "description",
    "plant",
    "pneumatics",
    "sensors",
    "identified",
    "controller",
    "calibration",
)
_ACTS = ("actuator1", "actuator2", "actuator3")


@dataclass(frozen=True)
class Preset:
    """A plant preset, read and checked (:func:`load_preset`): its ``name`` and
    ``description``; the partial trees it lays over the defaults, ``plant``,
    ``pneumatics``, ``sensors`` and ``controller``; the models ``identified`` on its
    plant (``{actuator: {b, a1, a0}}``, empty if none) and the ``calibration`` record
    ``simpro-sim calibrate`` wrote."""

    name: str
    description: str = ""
    plant: dict = field(default_factory=dict)
    pneumatics: dict = field(default_factory=dict)
    sensors: dict = field(default_factory=dict)
    identified: dict = field(default_factory=dict)
    controller: dict = field(default_factory=dict)
    calibration: Any = None


def shipped_presets() -> list[str]:
    """Names of the shipped presets, sorted."""
    return sorted(p.stem for p in PRESETS_DIR.glob("*.yaml"))


def _path(name_or_path: str) -> Path:
    text = str(name_or_path)
    if text in shipped_presets():
        return PRESETS_DIR / f"{text}.yaml"
    p = user_path(text, "plant.preset")
    if text.endswith((".yaml", ".yml")) and p.is_file():
        return p
    raise UserInputError(
        f"unknown preset at plant.preset: {text!r}; allowed: {shipped_presets()} or a path "
        f"to a preset YAML file{closest(text, shipped_presets())}"
    )


def load_preset(name_or_path: str) -> Preset:
    """Read and check a preset (shipped name or path).

    Raises
    ------
    UserInputError
        Unknown name (listing the shipped ones), unreadable or invalid YAML,
        unknown top-level keys, an ``identified`` block that is not three
        ``{b, a1, a0}`` mappings of positive numbers. The plant and pneumatics
        values are checked where they are used (the scenario, the model).
    """
    path = _path(name_or_path)
    doc = read_yaml(path, "preset")
    if not isinstance(doc, Mapping):
        raise UserInputError(
            f"wrong type at {path.name} (top level): {type(doc).__name__}; allowed: a mapping "
            f"with keys {list(PRESET_KEYS)}"
        )
    for k in doc:
        if k not in PRESET_KEYS:
            raise UserInputError(
                f"unknown key at {path.name}: {k!r}; allowed keys are {list(PRESET_KEYS)}"
            )
    for k in ("plant", "pneumatics", "sensors", "controller"):
        if not isinstance(doc.get(k) or {}, Mapping):
            raise UserInputError(f"wrong type at {path.name}: {k}; allowed: a mapping")
    ident = doc.get("identified")
    if ident is not None:
        ok = isinstance(ident, Mapping) and set(ident) == set(_ACTS)
        for a in _ACTS if ok else ():
            node = ident[a]
            ok = ok and isinstance(node, Mapping) and set(node) == {"b", "a1", "a0"}
            ok = ok and all(
                isinstance(v, int | float) and not isinstance(v, bool) and v >= 0
                for v in node.values()
            )
        if not ok:
            raise UserInputError(
                f"invalid value at {path.name}: identified; allowed: {{b, a1, a0}} (SI, >= 0) "
                f"for each of {list(_ACTS)}"
            )
    blocks = {k: copy.deepcopy(v) for k, v in doc.items() if v is not None}
    return Preset(**{"name": path.stem, **blocks})


def scenario_overlay(name_or_path: str) -> dict:
    """The preset as a partial scenario tree (plant, actuator.pneumatics, controller
    with the identified models)."""
    p = load_preset(name_or_path)
    out: dict = {"plant": {**p.plant, "preset": str(name_or_path)}}
    if p.pneumatics:
        out |= {"actuator": {"pneumatics": p.pneumatics}}
    if p.sensors:  # the rig's sensor errors (simpro_mj.plant.sensor_errors)
        out |= {"sensors": p.sensors}
    controller = dict(p.controller)
    if p.identified:
        ident = {a: {k: float(v) for k, v in p.identified[a].items()} for a in _ACTS}
        controller |= {"inner": {**dict(controller.get("inner") or {}), "identified": ident}}
    return out | ({"controller": controller} if controller else {})
