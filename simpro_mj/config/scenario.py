"""Scenarios: YAML documents describing one run, validated on load.

A scenario names the controller, actuator model, as-built plant, sensors,
set-point profile, duration and seed of one co-simulation run. Files carry
units in the key names (``duration_s``, ``pitch_deg``, ``heave_mm``);
:func:`~simpro_mj.config.reference.reference` turns the set-point profile into SI
poses; :func:`scenario_model` gives the typed view of a resolved scenario
(``scenario_model(s).controller.outer.gains``).

Resolution order (:func:`load_scenario`)
----------------------------------------
1. :data:`DEFAULT_SCENARIO` (every key, every default, in one place);
2. the file, deep-merged over it (mappings merge key by key; lists and
   scalars replace);
3. ``--set KEY=VALUE`` overrides in order (a mapping value merges, anything
   else replaces);
4. validation by the typed models (:class:`~simpro_mj.config.models.Scenario`,
   pydantic v2: unknown keys with the closest valid key, types, ranges,
   enumerations, set-point components, faults, cross-field rules), then the
   reachability of the set-point profile on the 1 ms physics grid (unless
   ``controller.clamp_setpoints``; :mod:`simpro_mj.config.reference`).

The result is the *resolved* scenario, a typed
:class:`~simpro_mj.config.models.Scenario`; its ``model_dump()`` is a plain,
JSON-compatible dict (what ``scenario.yaml`` holds) with every key present,
numbers normalised to the defaults' types (so that :func:`scenario_hash` does
not depend on ``15`` vs ``15.0``) and every set-point component spelled out with
its optional keys. :func:`scenario_with` applies ``--set``-like changes to a
resolved scenario.

Set-point components
--------------------
Each axis (``setpoint.roll_deg``, ``pitch_deg``, ``heave_mm``) is a list of
components summed on top of the home pose (heave relative to the home height
1265 mm), in the axis' unit:

* ``{type: step, time_s, value}``: ``value`` from ``time_s`` on (t >= time_s);
* ``{type: ramp, start_s, end_s, value}``: 0 before ``start_s``, linear to
  ``value`` at ``end_s``, held after;
* ``{type: sine, amplitude, period_s, phase_deg: 0, start_s: 0, end_s: null}``:
  ``amplitude sin(2 pi (t - start_s) / period_s + phase)`` for
  ``start_s <= t < end_s`` (``null``: to the end), 0 elsewhere; the phase is
  counted from ``start_s``, so phase 0 starts at zero;
* ``{type: table, times_s: [...], values: [...]}``: piecewise linear through
  the points, times strictly increasing, the first/last value held outside.

Faults
------
``faults`` is a list of events, each a mapping with a ``type`` and the time
``time_s`` (>= 0, < ``duration_s``) from which it acts; ``end_s`` (where
allowed; ``null``: to the end of the run) ends it. Every optional key is
spelled out in the resolved scenario (:mod:`simpro_mj.config.entries`):

* ``{type: supply_drop, time_s, pressure_bar_gauge, ramp_s: 0}``: the supply
  pressure falls from ``actuator.pneumatics.supply_pressure_bar_gauge`` to
  ``pressure_bar_gauge`` (0 <= p < supply), linearly over ``ramp_s``;
* ``{type: valve_stuck, time_s, leg, voltage_v, end_s: null}``: valve ``leg``
  (1..3) stays at ``voltage_v`` (0..10 V) whatever the controller commands;
* ``{type: sensor_frozen | sensor_dropout | sensor_bias, time_s, sensor, ...}``
  with ``sensor`` one of ``potentiometer`` (``leg`` 1..3, null: all three),
  ``height_encoder`` or ``imu`` (``axis`` roll | pitch, null: both);
  ``sensor_dropout`` takes ``probability`` (0 < p <= 1) that a sample is lost,
  ``sensor_bias`` takes ``bias_mm`` (potentiometer, height encoder) or
  ``bias_deg`` (imu);
* ``{type: potentiometer_failure, time_s, leg, mode: open, end_s: null}``:
  the potentiometer of ``leg`` reads a rail, ``open`` 0 V (0 mm), ``short``
  the 10 V feed (500 mm, clipped to the ADC range).

What each fault does to the loop is defined in :mod:`simpro_mj.plant.faults`.

Sweeps
------
A file may also carry a ``sweep:`` block (grid and/or Monte Carlo variants,
:mod:`simpro_mj.config.sweep`), which ``simpro-sim batch`` expands.
:func:`load_scenario` validates the block, drops it, says so in one line on
stderr and returns the base scenario (its hash is that of the base only).

Every error is a :class:`~simpro_mj.core.errors.UserInputError` whose one-line
message reads ``<what> at <dotted.path>: <what is allowed>``.

Every parameter as rows (:func:`parameters`, what ``simpro-sim show`` prints) is
read from the typed scenario's fields: the defaults, units, constraints and one-line
descriptions declared with :func:`~simpro_mj.config.rules.param`; nothing is written
twice. What ships (:func:`catalogue`, ``simpro-sim list``): the scenarios, presets and
telemetry files with the one line that says what each is, found through the functions
that load them, so the listing is what ``run``, ``plant.preset`` and
``setpoint.cueing.telemetry`` accept.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import re
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

import yaml
from pydantic.fields import FieldInfo

from simpro_mj.config.cueing import resolve_paths
from simpro_mj.config.messages import (
    is_model,
    item_meta,
    range_text,
    strip,
    tagged_members,
    unit_of,
)
from simpro_mj.config.models import DEFAULT_SCENARIO, Scenario, as_tree, scenario_model
from simpro_mj.config.models import merge as _merge
from simpro_mj.config.presets import scenario_overlay, shipped_presets
from simpro_mj.config.reference import check_setpoints
from simpro_mj.config.rig import rig_value
from simpro_mj.config.rules import ONE_FOR_ALL, PHYSICS_DT_MS, check_period
from simpro_mj.config.sweep import broadcast_value, parse_sweep
from simpro_mj.core.cache import file_digest
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import Block, closest, key_text, parse_set, read_yaml
from simpro_mj.core.shipped import (
    PRESETS_DIR,
    SCENARIOS_DIR,
    TELEMETRY_DIR,
    model_digest,
    user_path,
)

# ------------------------------------------------------------------ finding files


def scenarios_dir() -> Path:
    """The folder of shipped scenarios (``$SIMPRO_SCENARIOS`` or the package's ``scenarios/``).

    The scenarios are package data, so a plain (non-editable) ``pip install``
    finds them as an editable one does.
    """
    env = os.environ.get("SIMPRO_SCENARIOS")
    if env:
        return Path(env).expanduser()
    return SCENARIOS_DIR


def shipped_scenarios() -> list[str]:
    """Names (file stems) of the shipped scenarios, sorted."""
    folder = scenarios_dir()
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.iterdir() if p.suffix in (".yaml", ".yml"))


#: local files already named as shadowing a shipped scenario (said once per process)
_SHADOWS_SAID: set[Path] = set()


def find_scenario(name_or_path: str) -> Path:
    """The scenario file a name or path stands for.

    A path that exists is that file; a bare name (no folder) that no file here
    matches is a shipped scenario (``step_pitch`` or ``step_pitch.yaml``). A
    file here that has a shipped scenario's name is used, and a ``note:`` line
    on stderr says that it shadows the shipped one.

    Raises
    ------
    UserInputError
        A path (with a folder) that does not exist, or a bare name that is
        neither a file here nor a shipped scenario (with "did you mean").
    """
    path = user_path(name_or_path, "scenario")
    text = str(name_or_path)
    stem = re.sub(r"\.ya?ml$", "", text)
    bare = "/" not in text and os.sep not in text
    shipped = None
    if bare:
        for ext in (".yaml", ".yml"):
            candidate = scenarios_dir() / f"{stem}{ext}"
            if candidate.is_file():
                shipped = candidate
                break
    if path.is_file():
        if shipped is not None and path.resolve() != shipped.resolve():
            here = path.resolve()
            if here not in _SHADOWS_SAID:
                _SHADOWS_SAID.add(here)
                sys.stderr.write(
                    f"note: running {here}, a file in this folder, not the shipped scenario "
                    f"{shipped.name} ({shipped}); rename the file to run the shipped one\n"
                )
        return path
    if path.exists() and not path.is_dir():  # a FIFO, a device, a socket: never opened
        from simpro_mj.core.safe_files import read_bytes

        read_bytes(path, 0, "scenario")  # refuses it in one line, without blocking
    if shipped is not None:
        return shipped
    names = shipped_scenarios()
    hint = closest(Path(stem).name, names)
    if not bare:
        where = "a folder" if path.is_dir() else "no such file"
        raise UserInputError(
            f"{where} at '{text}' ({path.absolute()}); allowed: a path to an existing YAML "
            f"file, or a shipped scenario by name {names}{hint}"
        )
    raise UserInputError(
        f"unknown scenario at '{text}': no such file here and no shipped scenario of that "
        f"name; allowed: a path to a YAML file or a shipped scenario {names} "
        f"(in {scenarios_dir()}){hint}"
    )


# ------------------------------------------------------------------ public entry points


def read_document(name_or_path: str) -> tuple[Path, Mapping]:
    """Find a scenario file (path or shipped name) and read it as a mapping.

    Returns ``(path, document)``; an empty file is refused. Shared by
    :func:`load_scenario` and :func:`simpro_mj.config.sweep.load_sweep`.

    Raises
    ------
    UserInputError
        Unknown scenario (listing the shipped ones), invalid YAML (line and
        column), or a top level that is not a mapping.
    """
    path = find_scenario(str(name_or_path))
    doc = read_yaml(path, "scenario")
    if not isinstance(doc, Mapping):
        raise UserInputError(
            f"wrong type at {path.name} (top level): got {type(doc).__name__}; "
            "allowed: a mapping of scenario keys"
        )
    return path, doc


def load_scenario(name_or_path: str, sets: Iterable[str] = ()) -> Scenario:
    """Load, merge, override and validate a scenario.

    Parameters
    ----------
    name_or_path : str
        A path to a YAML file, or the name of a shipped scenario
        (``"step_pitch"`` or ``"step_pitch.yaml"``, see :func:`shipped_scenarios`).
    sets : iterable of str
        ``KEY=VALUE`` overrides (dotted KEY, YAML VALUE), applied after the
        file and before validation.

    Returns
    -------
    Scenario
        The resolved scenario, typed (see the module docstring); its
        ``model_dump()`` is the dict ``scenario.yaml`` holds.

    Raises
    ------
    UserInputError
        Unknown scenario (the message lists the shipped ones), invalid YAML
        (line and column), unknown keys, wrong types or values (dotted path and
        what is allowed). :class:`SetpointError` (also a ``UserInputError``)
        for a set-point outside the workspace.
    """
    path, doc = read_document(name_or_path)
    if "sweep" in doc:
        # the variants are batch's job (simpro_mj.config.variants); a run is of the base scenario
        doc = dict(doc)
        n = parse_sweep(doc.pop("sweep")).count
        sys.stderr.write(
            f"note: {path.name} declares {n} variants in its sweep: block; running the base "
            f"scenario (simpro-sim batch {path} runs them)\n"
        )
    return resolve(doc, sets, default_name=path.stem, base=path.parent)


def resolve_scenario(
    doc: Mapping,
    sets: Iterable[str] = (),
    default_name: str = "scenario",
    base: Path | None = None,
) -> dict:
    """:func:`resolve`'s scenario as the plain dict ``scenario.yaml`` holds."""
    return resolve(doc, sets, default_name, base).model_dump()


def resolve(
    doc: Mapping,
    sets: Iterable[str] = (),
    default_name: str = "scenario",
    base: Path | None = None,
) -> Scenario:
    """Resolve a scenario document given as a dict (same rules as :func:`load_scenario`).

    ``base``: the scenario file's folder, where a relative
    ``setpoint.cueing.telemetry`` is looked for first.
    """
    sets = list(sets or ())
    tree = _overlay(DEFAULT_SCENARIO, doc, sets)
    preset = (tree.get("plant") or {}).get("preset") if isinstance(tree, Mapping) else None
    if isinstance(preset, str):  # another type is reported by the validation
        # the preset lies between the defaults and the file (simpro_mj.config.presets)
        tree = _overlay(_merge(DEFAULT_SCENARIO, scenario_overlay(preset)), doc, sets)
    plant = tree.get("plant")
    if isinstance(plant, dict) and isinstance(plant.get("rig"), str):
        plant["rig"] = rig_value(plant["rig"], base)  # a rig file beside the scenario first
    if not tree.get("name"):
        tree["name"] = default_name
    resolved = scenario_model(tree)
    if resolved.setpoint.cueing is not None:
        resolve_paths(resolved.setpoint.cueing, base)
    if not resolved.controller.clamp_setpoints:
        check_setpoints(resolved)
    return resolved


def scenario_with(scenario: Scenario | Mapping, changes: Mapping[str, Any]) -> Scenario:
    """The resolved ``scenario`` with ``changes`` (dotted key to value, as ``--set``'s
    ``KEY=VALUE`` once read) applied and resolved again: a new scenario, validated as a
    loaded one is (``scenario_with(s, {"controller.mode": "joint_only"})``).

    Raises
    ------
    UserInputError
        As :func:`load_scenario` for a key or a value it refuses.
    """
    tree = copy.deepcopy(dict(as_tree(scenario)))
    for key, value in changes.items():
        _set(tree, key, broadcast_value(key, value))
    return resolve(tree, default_name=str(tree.get("name") or "scenario"))


def _overlay(base: Mapping, doc: Mapping, sets: list) -> dict:
    """``base``, the document merged over it, the ``--set`` overrides applied (one number
    for a list of numbers, as in a sweep: ``gains=30`` is ``[30, 30, 30]``)."""
    tree = _merge(base, doc)
    for expr in sets:
        key, value = parse_set(expr)
        _set(tree, key, broadcast_value(key, value))
    return _merge(base, tree)  # a replaced mapping keeps its other defaults


def _set(tree: dict, key: str, value: Any) -> None:
    """Apply one override: create missing keys (validation reports them), merge mappings."""
    parts = key.split(".")
    node: Any = tree
    for depth, part in enumerate(parts[:-1]):
        if not isinstance(node, dict):
            here = ".".join(parts[:depth])
            raise UserInputError(
                f"unknown key at {key_text(key)}: '{key_text(here)}' has no sub-keys"
            )
        node = node.setdefault(part, {})
    if not isinstance(node, dict):
        here = ".".join(parts[:-1])
        raise UserInputError(f"unknown key at {key_text(key)}: '{key_text(here)}' has no sub-keys")
    last = parts[-1]
    if isinstance(value, Mapping) and isinstance(node.get(last), Mapping):
        node[last] = _merge(node[last], value)
    else:
        node[last] = value


#: dotted keys left out of the hash where they hold their default
_HASHED_UNLESS_DEFAULT = (
    "controller.outer.joint_lag",
    "controller.inner.anti_windup",
    "controller.inner.tracking_time_ms",
    "controller.inner.dead_band_release",
    "controller.outer.dead_band.kind",
    "controller.outer.dead_band.release",
    "actuator.pneumatics.cylinder.stick_time_constant_ms",
    "actuator.pneumatics.cylinder.stick_impedance",
    "actuator.pneumatics.cylinder.stick_noslip_iterations",
)


def scenario_hash(resolved: Scenario | Mapping) -> str:
    """SHA-256 (hex) of the canonical JSON of a resolved scenario (sorted keys), typed
    or its dict.

    A telemetry file (``setpoint.cueing.telemetry``) enters by its contents, not its
    path: the same recording hashes the same wherever it lies, and an edited or
    regenerated one does not, so ``batch --resume`` never keeps a run of the old
    recording. A file that cannot be read enters by its path. The MJCF enters by its
    SHA-256 too (``SIMPRO_MODEL`` or the shipped one): a heavier rod is another run.
    """
    tree = copy.deepcopy(dict(as_tree(resolved)))
    cue = (tree.get("setpoint") or {}).get("cueing") or {}
    if isinstance(cue, dict) and cue.get("telemetry"):
        digest = file_digest(cue["telemetry"])
        if digest is not None:
            cue["telemetry"] = f"sha256:{digest}"
    plant = tree.get("plant")
    if isinstance(plant, dict) and "rig" in plant and plant["rig"] is None:
        # null is the shipped MJCF's rig, which enters by the MJCF's digest below
        del plant["rig"]
    # a key at a default that steps as the scenario without it hashes as that
    # scenario: the same run, the same hash
    for key in _HASHED_UNLESS_DEFAULT:
        *path, last = key.split(".")
        node: Any = tree
        default: Any = DEFAULT_SCENARIO
        for part in path:
            node = node.get(part) if isinstance(node, dict) else None
            default = default[part]
        if isinstance(node, dict) and last in node and node[last] == default[last]:
            del node[last]
    tree["mjcf"] = f"sha256:{model_digest()}"  # the model it compiles
    text = json.dumps(tree, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


# ------------------------------------------------------------------ every parameter


@dataclass(frozen=True)
class Parameter:
    """One parameter of a scenario."""

    key: str  #: dotted path (``actuator.pneumatics.supply_pressure_bar_gauge``)
    value: Any  #: the run's value (the resolved scenario's)
    default: Any  #: the schema's default (before any preset or file)
    unit: str  #: edge unit ("" for a number without one, a choice or a flag)
    allowed: str  #: the allowed values or range
    meaning: str  #: one line


def _allowed(field: FieldInfo) -> str:
    tp, meta = strip(field.annotation)
    meta = [*field.metadata, *meta]
    if get_origin(tp) is Literal:
        return "one of " + ", ".join(map(str, get_args(tp)))
    if tp is bool:
        return "true or false"
    if tp is str:
        return "text"
    if any(getattr(m, "func", None) is check_period for m in meta):
        return f"a whole number of {PHYSICS_DT_MS:g} ms steps, <= 10000"
    rng = range_text(meta)
    extra = field.json_schema_extra
    if not rng and isinstance(extra, dict) and extra.get("range"):
        rng = str(extra["range"]).split(" (", 1)[0]  # the plant's range, its reason left out
    if get_origin(tp) is list:
        item = get_args(tp)[0]
        if tagged_members(item):
            return "list of: " + ", ".join(tagged_members(item))
        n = next((m.min_length for m in meta if hasattr(m, "min_length")), None)
        each = range_text(item_meta(tp))
        text = f"{n} numbers" if n else "numbers"
        if any(m is ONE_FOR_ALL for m in meta):
            text = f"one or {text}"
        return f"{text}, each {each}" if each else text
    if tp is int:
        return f"integer {rng}".strip()
    return rng or "number"


def _rows(model: type[Block], value: Mapping, default: Mapping, prefix: str) -> list[Parameter]:
    out = []
    for name, field in model.model_fields.items():
        if name not in value:  # a block the scenario does not have (setpoint.cueing)
            continue
        key = f"{prefix}{name}"
        tp, _ = strip(field.annotation)
        here, base = value.get(name), default.get(name)
        if is_model(tp) and issubclass(tp, Block) and isinstance(here, Mapping):
            out += _rows(tp, here, base if isinstance(base, Mapping) else {}, f"{key}.")
            continue
        out.append(
            Parameter(key, here, base, unit_of(field), _allowed(field), field.description or "")
        )
    return out


def parameters(resolved: Scenario | Mapping) -> list[Parameter]:
    """Every parameter of a resolved scenario (:func:`~simpro_mj.config.scenario.load_scenario`),
    in the order of the scenario's blocks."""
    return _rows(Scenario, as_tree(resolved), Scenario.defaults(), "")


def text(value: Any) -> str:
    """A value as one short line (YAML-like flow: null, true, [1.0, 2.0])."""
    return json.dumps(value, separators=(", ", ": ")) if not isinstance(value, str) else value


# ------------------------------------------------------------------ what ships


def _yaml_description(path: Path) -> str:
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except (OSError, yaml.YAMLError) as exc:
        return f"(unreadable: {type(exc).__name__})"
    text = str(doc.get("description", "") if isinstance(doc, dict) else "")
    if isinstance(doc, dict) and isinstance(doc.get("sweep"), dict):
        text += " [sweep: simpro-sim batch]"
    return " ".join(text.split())


def _csv_description(path: Path) -> str:
    try:
        with path.open(encoding="utf-8") as fh:
            first = fh.readline().strip()
    except OSError as exc:
        return f"(unreadable: {type(exc).__name__})"
    return first.lstrip("#").strip() if first.startswith("#") else ""


def catalogue() -> dict[str, list[tuple[str, str]]]:
    """``scenarios``, ``presets``, ``telemetry``: (name, one-line description) each, sorted."""
    folder = scenarios_dir()
    scenarios = []
    for name in shipped_scenarios():
        path = next(
            folder / f"{name}{e}" for e in (".yaml", ".yml") if (folder / f"{name}{e}").is_file()
        )
        scenarios.append((name, _yaml_description(path)))
    presets = [(n, _yaml_description(PRESETS_DIR / f"{n}.yaml")) for n in shipped_presets()]
    telemetry = [(p.name, _csv_description(p)) for p in sorted(Path(TELEMETRY_DIR).glob("*.csv"))]
    return {"scenarios": scenarios, "presets": presets, "telemetry": telemetry}
