"""Scenarios: YAML documents describing one run, validated on load.

A scenario names the controller, actuator model, as-built plant, sensors,
set-point profile, duration and seed of one co-simulation run. Files carry
units in the key names (``duration_s``, ``pitch_deg``, ``heave_mm``);
:func:`reference` turns the set-point profile into SI poses.

Resolution order (:func:`load_scenario`)
----------------------------------------
1. :data:`DEFAULT_SCENARIO` (every key, every default, in one place);
2. the file, deep-merged over it (mappings merge key by key; lists and
   scalars replace);
3. ``--set KEY=VALUE`` overrides in order (a mapping value merges, anything
   else replaces);
4. validation: unknown keys (with the closest valid key), types, ranges,
   enumerations, set-point components, and the reachability of the set-point
   profile on the 1 ms physics grid (unless ``controller.clamp_setpoints``).

The result is the *resolved* scenario: a plain, JSON-compatible dict with
every key present, numbers normalised to the defaults' types (so that
:func:`scenario_hash` does not depend on ``15`` vs ``15.0``) and every
set-point component spelled out with its optional keys.

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
spelled out in the resolved scenario (:data:`FAULT_TYPES`):

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
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import re
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from controllers.errors import WorkspaceError
from controllers.geometry import nominal_geometry
from controllers.kinematics import check_reachable, reachable
from controllers.task_space import INTEGRATORS
from simpro_mj.config.defaults import DEFAULT_SCENARIO
from simpro_mj.config.defaults import merge as _merge
from simpro_mj.config.presets import scenario_overlay
from simpro_mj.config.sweep import count_variants
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import (
    check_keys,
    check_tagged,
    closest,
    key_text,
    parse_set,
    read_yaml,
    value_text,
)

__all__ = [
    "late_setpoints",
    "DEFAULT_SCENARIO",
    "PHYSICS_DT_S",
    "MODES",
    "OUTER_TYPES",
    "INNER_VARIANTS",
    "DISCRETISATIONS",
    "ACTUATOR_MODELS",
    "COMPONENT_TYPES",
    "FAULT_TYPES",
    "FAULT_SENSORS",
    "MAX_DURATION_S",
    "MIN_DURATION_S",
    "MAX_PERIOD_MS",
    "SetpointError",
    "scenarios_dir",
    "shipped_scenarios",
    "load_scenario",
    "resolve_scenario",
    "validate_scenario",
    "check_setpoints",
    "reference",
    "scenario_hash",
]

#: Physics step of ``simpro_mj/models/simpro_platform.xml`` (s); periods are multiples of it.
PHYSICS_DT_S = 0.001
_PHYSICS_DT_MS = 1

MODES = ("joint_only", "task_space", "feedforward")
OUTER_TYPES = ("I", "PI")
FEEDFORWARD_LAGS = ("model", "joints")  # controllers.task_space.LAGS
INNER_VARIANTS = ("printed", "corrected", "redesigned")
DISCRETISATIONS = ("tustin", "zoh")
DESIGN_PLANTS = ("paper", "identified")
IDENTIFY_CHOICES = ("auto", "preset")  # controller.inner.identify (simpro_mj.identification.auto)
ACTUATOR_MODELS = ("nonlinear", "linear")
PAPER_UNITS = ("volts", "metres")  # controllers.design.READINGS
SETPOINT_FILTERS = ("none", "first_order", "ramp", "zero_cancel")  # controllers.setpoint_filter
DELAY_SAMPLES = (1, 2)
SETPOINT_AXES = ("roll_deg", "pitch_deg", "heave_mm")

#: Set-point component types: required keys, optional keys with their defaults.
COMPONENT_TYPES: dict[str, tuple[tuple[str, ...], dict[str, Any]]] = {
    "step": (("time_s", "value"), {}),
    "ramp": (("start_s", "end_s", "value"), {}),
    "sine": (("amplitude", "period_s"), {"phase_deg": 0.0, "start_s": 0.0, "end_s": None}),
    "table": (("times_s", "values"), {}),
}


#: Fault types: required keys, optional keys with their defaults (module docstring).
FAULT_TYPES: dict[str, tuple[tuple[str, ...], dict[str, Any]]] = {
    "supply_drop": (("time_s", "pressure_bar_gauge"), {"ramp_s": 0.0}),
    "valve_stuck": (("time_s", "leg", "voltage_v"), {"end_s": None}),
    "sensor_frozen": (("time_s", "sensor"), {"leg": None, "axis": None, "end_s": None}),
    "sensor_dropout": (
        ("time_s", "sensor"),
        {"leg": None, "axis": None, "end_s": None, "probability": 1.0},
    ),
    "sensor_bias": (
        ("time_s", "sensor"),
        {"leg": None, "axis": None, "end_s": None, "bias_mm": None, "bias_deg": None},
    ),
    "potentiometer_failure": (("time_s", "leg"), {"mode": "open", "end_s": None}),
}
FAULT_SENSORS = ("potentiometer", "height_encoder", "imu")
_FAULT_AXES = ("roll", "pitch")
_POT_MODES = ("open", "short")
_FAULT_STRINGS = {"sensor": FAULT_SENSORS, "axis": _FAULT_AXES, "mode": _POT_MODES}

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


_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
# YAML 1.1 reads 5e-3 (no dot) as a string; accept it in numeric fields
_EXP_RE = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")
_FREE_FORM = ("actuator.pneumatics",)


class SetpointError(UserInputError, WorkspaceError):
    """A set-point outside the reachable workspace.

    Both a :class:`~simpro_mj.core.errors.UserInputError` (the user's scenario is
    wrong) and a :class:`~controllers.errors.WorkspaceError` (the message of
    :func:`controllers.kinematics.check_reachable` names the limit).
    """


# ------------------------------------------------------------------ finding files


def scenarios_dir() -> Path:
    """The folder of shipped scenarios (``$SIMPRO_SCENARIOS`` or the package's ``scenarios/``).

    The scenarios are package data, so a plain (non-editable) ``pip install``
    finds them as an editable one does.
    """
    env = os.environ.get("SIMPRO_SCENARIOS")
    if env:
        return Path(env).expanduser()
    return Path(__file__).resolve().parents[1] / "scenarios"


def shipped_scenarios() -> list[str]:
    """Names (file stems) of the shipped scenarios, sorted."""
    folder = scenarios_dir()
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.iterdir() if p.suffix in (".yaml", ".yml"))


def _find(name_or_path: str) -> Path:
    path = Path(name_or_path).expanduser()
    if path.is_file():
        return path
    text = str(name_or_path)
    stem = re.sub(r"\.ya?ml$", "", text)
    if "/" not in text and os.sep not in text:
        for ext in (".yaml", ".yml"):
            candidate = scenarios_dir() / f"{stem}{ext}"
            if candidate.is_file():
                return candidate
    shipped = shipped_scenarios()
    raise UserInputError(
        f"unknown scenario at '{text}': allowed: a path to a YAML file or a shipped "
        f"scenario {shipped} (in {scenarios_dir()}){closest(Path(stem).name, shipped)}"
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
    path = _find(str(name_or_path))
    doc = read_yaml(path, "scenario")
    if not isinstance(doc, Mapping):
        raise UserInputError(
            f"wrong type at {path.name} (top level): got {type(doc).__name__}; "
            "allowed: a mapping of scenario keys"
        )
    return path, doc


def load_scenario(name_or_path: str, sets: Iterable[str] = ()) -> dict:
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
    dict
        The resolved scenario (see the module docstring).

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
        n = count_variants(doc.pop("sweep"))
        sys.stderr.write(
            f"note: {path.name} declares {n} variants in its sweep: block; running the base "
            f"scenario (simpro-sim batch {path} runs them)\n"
        )
    return resolve_scenario(doc, sets, default_name=path.stem, base=path.parent)


def resolve_scenario(
    doc: Mapping,
    sets: Iterable[str] = (),
    default_name: str = "scenario",
    base: Path | None = None,
) -> dict:
    """Resolve a scenario document given as a dict (same rules as :func:`load_scenario`).

    ``base``: the scenario file's folder, where a relative
    ``setpoint.cueing.telemetry`` is looked for first (issue 16).
    """
    sets = list(sets or ())
    tree = _overlay(DEFAULT_SCENARIO, doc, sets)
    preset = (tree.get("plant") or {}).get("preset") if isinstance(tree, Mapping) else None
    if isinstance(preset, str):  # another type is reported by the validation
        # the preset lies between the defaults and the file (simpro_mj.config.presets)
        tree = _overlay(_merge(DEFAULT_SCENARIO, scenario_overlay(preset)), doc, sets)
    if not tree.get("name"):
        tree["name"] = default_name
    resolved = validate_scenario(tree)
    if resolved["setpoint"].get("cueing"):
        from simpro_mj.config.cueing import resolve_paths

        resolve_paths(resolved, base)
    if not resolved["controller"]["clamp_setpoints"]:
        check_setpoints(resolved)
    return resolved


def _overlay(base: Mapping, doc: Mapping, sets: list) -> dict:
    """``base``, the document merged over it, the ``--set`` overrides applied."""
    tree = _merge(base, doc)
    for expr in sets:
        key, value = parse_set(expr)
        _set(tree, key, value)
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


def scenario_hash(resolved: Mapping) -> str:
    """SHA-256 (hex) of the canonical JSON of a resolved scenario (sorted keys)."""
    text = json.dumps(resolved, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


# ------------------------------------------------------------------ validation


def _type_name(value: Any) -> str:
    return "null" if value is None else type(value).__name__


def _wrong_type(path: str, value: Any, allowed: str) -> UserInputError:
    return UserInputError(
        f"wrong type at {path}: got {_type_name(value)} {value_text(value)}; allowed: {allowed}"
    )


def _invalid(path: str, value: Any, allowed: str) -> UserInputError:
    return UserInputError(f"invalid value at {path}: {value_text(value)}; allowed: {allowed}")


def _number(value: Any, path: str) -> float:
    if isinstance(value, str) and _EXP_RE.match(value.strip()):
        value = float(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _wrong_type(path, value, "a number")
    x = float(value)
    if not math.isfinite(x):
        raise _invalid(path, value, "a finite number")
    return x


def _integer(value: Any, path: str) -> int:
    x = _number(value, path)
    if x != int(x):
        raise _invalid(path, value, "an integer")
    return int(x)


#: Per-leg lists that also take one number for all legs.
_ONE_FOR_ALL = frozenset({"controller.setpoint_filter.time_ms"})


def _check_tree(value: Any, default: Any, path: str) -> Any:
    """Check ``value`` against the default's structure and type; return it normalised."""
    if isinstance(default, dict):
        if not isinstance(value, Mapping):
            raise _wrong_type(path or "top level", value, "a mapping")
        if path in _FREE_FORM:
            return _check_pneumatics(value, path)
        out = {}
        for key, sub in value.items():
            here = f"{path}.{key_text(key)}" if path else key_text(key)
            if path == "setpoint" and key == "cueing":  # issue 16: simpro_mj.config.cueing
                out[key] = _check_cueing(sub, here)
                continue
            if key not in default:
                raise UserInputError(
                    f"unknown key at {here}: allowed keys are {sorted(default)}"
                    f"{closest(str(key), default)}"
                )
            if path == "setpoint":
                out[key] = _check_components(sub, here)
            elif here == "faults":
                out[key] = _check_faults(sub, here)
            else:
                out[key] = _check_tree(sub, default[key], here)
        return out
    if isinstance(default, list):
        n = len(default)
        if path in _ONE_FOR_ALL and not isinstance(value, (list, tuple, Mapping, str)):
            value = [_number(value, path)] * n  # one number: every leg's
        if not isinstance(value, (list, tuple)) or len(value) != n:
            one = "one number or " if path in _ONE_FOR_ALL else ""
            raise _wrong_type(path, value, f"{one}a list of {n} numbers like {default}")
        return [_number(v, f"{path}[{i}]") for i, v in enumerate(value)]
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise _wrong_type(path, value, "true or false")
        return value
    if isinstance(default, int):
        return _integer(value, path)
    if isinstance(default, float):
        return _number(value, path)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise _wrong_type(path, value, "a string")
        return value
    if default is None:  # free value (none in the schema today)
        return value
    raise TypeError(f"unsupported default at {path}: {default!r}")  # pragma: no cover


def _check_cueing(value: Any, path: str) -> dict | None:
    """``setpoint.cueing`` (issue 16): checked by :func:`simpro_mj.config.cueing.check_cueing`.

    ``null`` is no cueing. Only present in the resolved scenario when given, so
    the scenarios without it keep their hash.
    """
    if value is None:
        return None
    from simpro_mj.config.cueing import check_cueing

    return check_cueing(value, path)


def _check_pneumatics(value: Mapping, path: str) -> dict:
    """``actuator.pneumatics``: keys against the actuator tree, leaf types, then the
    plant's own range checks (run here so that a bad value is a load-time error)."""
    try:
        from simpro_mj.plant.pneumatics import DEFAULT_PNEUMATIC_PARAMS as ref
        from simpro_mj.plant.pneumatics import PneumaticParams
    except ImportError:  # the actuator module is optional at this level
        return copy.deepcopy(dict(value))

    check_keys(value, ref, path)
    out = _check_pneumatic_leaves(value, ref, path)
    try:
        PneumaticParams.from_tree(out)
    except UserInputError as exc:
        # the plant names its own tree "pneumatics"; here it hangs under "actuator"
        msg = str(exc).replace(" at pneumatics.", f" at {path}.")
        raise UserInputError(msg) from exc
    except (ValueError, TypeError, ArithmeticError) as exc:
        raise UserInputError(
            f"invalid value at {path}: {exc}; allowed: see simpro_mj.plant.pneumatics"
        ) from exc
    return out


def _check_pneumatic_leaves(value: Mapping, ref: Mapping, path: str) -> dict:
    """Leaf types of a pneumatics subtree; per-leg keys take a number or 3 numbers."""
    out: dict = {}
    for key, sub in value.items():
        here = f"{path}.{key}"
        default = ref[key]
        if isinstance(default, Mapping):
            out[key] = _check_pneumatic_leaves(sub, default, here)
        elif isinstance(default, bool):
            if not isinstance(sub, bool):
                raise _wrong_type(here, sub, "true or false")
            out[key] = sub
        elif isinstance(default, list) or default is None:
            if default is None and sub is None:
                out[key] = None
            elif isinstance(sub, (list, tuple)):
                if len(sub) != 3:
                    raise _wrong_type(here, sub, "a number or a list of 3 numbers (one per leg)")
                out[key] = [_number(v, f"{here}[{i}]") for i, v in enumerate(sub)]
            else:
                out[key] = _number(sub, here)
        else:
            out[key] = _number(sub, here)
    return out


def _tagged_list(value: Any, path: str, kinds: Mapping, noun: str, example: str):
    """Yield ``(path[i], entry, (kind, required, optional))`` for a list of tagged
    mappings (set-point components, faults); ``None`` is an empty list.

    Each entry is checked by :func:`~simpro_mj.core.keys.check_tagged`.
    """
    if value is None:
        return
    if not isinstance(value, (list, tuple)):
        raise _wrong_type(path, value, f"a list of {noun}s like {example}")
    for i, entry in enumerate(value):
        here = f"{path}[{i}]"
        if not isinstance(entry, Mapping):
            raise _wrong_type(here, entry, f"a {noun} mapping like {example[1:-1]}")
        yield here, entry, check_tagged(entry, here, "type", kinds)


def _check_components(value: Any, path: str) -> list[dict]:
    """Validate and normalise one axis' list of set-point components."""
    example = "[{type: step, time_s: 1.0, value: 3.0}]"
    out = []
    for here, comp, (kind, required, optional) in _tagged_list(
        value, path, COMPONENT_TYPES, "component", example
    ):
        c: dict[str, Any] = {"type": kind}
        for key in (*required, *optional):
            raw = comp.get(key, optional.get(key))
            if kind == "table":
                if not isinstance(raw, (list, tuple)) or not raw:
                    raise _wrong_type(f"{here}.{key}", raw, "a non-empty list of numbers")
                c[key] = [_number(v, f"{here}.{key}[{j}]") for j, v in enumerate(raw)]
            elif raw is None and key == "end_s":
                c[key] = None
            else:
                c[key] = _number(raw, f"{here}.{key}")
        _check_component_values(c, here)
        out.append(c)
    return out


def _check_component_values(c: dict, path: str) -> None:
    kind = c["type"]
    if kind == "step" and c["time_s"] < 0:
        raise _invalid(f"{path}.time_s", c["time_s"], ">= 0 s")
    if kind == "ramp":
        if c["start_s"] < 0:
            raise _invalid(f"{path}.start_s", c["start_s"], ">= 0 s")
        if c["end_s"] <= c["start_s"]:
            raise _invalid(f"{path}.end_s", c["end_s"], f"> start_s = {c['start_s']} s")
    if kind == "sine":
        lo, hi = SINE_PERIOD_RANGE_S
        if not lo <= c["period_s"] <= hi:
            allowed = f"> 0 s: {lo:g} s (two physics steps) .. {hi:g} s"
            raise _invalid(f"{path}.period_s", c["period_s"], allowed)
        if c["start_s"] < 0:
            raise _invalid(f"{path}.start_s", c["start_s"], ">= 0 s")
        if c["end_s"] is not None and c["end_s"] <= c["start_s"]:
            raise _invalid(f"{path}.end_s", c["end_s"], f"null or > start_s = {c['start_s']} s")
    if kind == "table":
        times, values = c["times_s"], c["values"]
        if len(values) != len(times):
            raise _invalid(f"{path}.values", values, f"as many values as times_s ({len(times)})")
        for j in range(1, len(times)):
            if times[j] <= times[j - 1]:
                raise _invalid(
                    f"{path}.times_s",
                    times,
                    f"strictly increasing times (times_s[{j}] = {times[j]} <= "
                    f"times_s[{j - 1}] = {times[j - 1]})",
                )


def _check_faults(value: Any, path: str) -> list[dict]:
    """Validate the structure and types of the ``faults`` list (module docstring).

    Cross-field ranges (times within the run, pressure below the supply) are
    checked by :func:`_check_fault_values` once the whole scenario is known.
    """
    example = "[{type: supply_drop, time_s: 5.0, pressure_bar_gauge: 2.0}]"
    out = []
    for here, entry, (kind, required, optional) in _tagged_list(
        value, path, FAULT_TYPES, "fault", example
    ):
        f: dict[str, Any] = {"type": kind}
        for key in (*required, *optional):
            raw = entry.get(key, optional.get(key))
            where = f"{here}.{key}"
            if key in _FAULT_STRINGS:
                choices = list(_FAULT_STRINGS[key])
                if raw is None and key != "sensor" and optional.get(key, "") is None:
                    f[key] = None
                elif raw not in choices:
                    raise _invalid(where, raw, f"one of {choices}{closest(str(raw), choices)}")
                else:
                    f[key] = raw
            elif key == "leg":
                if raw is None and key in optional:
                    f[key] = None
                else:
                    leg = _integer(raw, where)
                    if not 1 <= leg <= 3:
                        raise _invalid(where, raw, "a leg number 1, 2 or 3")
                    f[key] = leg
            elif raw is None and optional.get(key, 0.0) is None:
                f[key] = None
            else:
                f[key] = _number(raw, where)
        _check_fault_entry(f, here)
        out.append(f)
    return out


def _check_fault_entry(f: dict, path: str) -> None:
    """Ranges of one fault that do not depend on the rest of the scenario."""
    kind = f["type"]
    if f["time_s"] < 0:
        raise _invalid(f"{path}.time_s", f["time_s"], ">= 0 s")
    if f.get("end_s") is not None and f["end_s"] <= f["time_s"]:
        raise _invalid(f"{path}.end_s", f["end_s"], f"null or > time_s = {f['time_s']} s")
    if kind == "supply_drop":
        if f["ramp_s"] < 0:
            raise _invalid(f"{path}.ramp_s", f["ramp_s"], ">= 0 s")
    elif kind == "valve_stuck":
        if not 0.0 <= f["voltage_v"] <= 10.0:
            raise _invalid(f"{path}.voltage_v", f["voltage_v"], "0..10 V (the MPYE's input range)")
    elif kind.startswith("sensor_"):
        sensor = f["sensor"]
        if f["leg"] is not None and sensor != "potentiometer":
            raise _invalid(
                f"{path}.leg", f["leg"], f"null for sensor {sensor} (potentiometers only)"
            )
        if f["axis"] is not None and sensor != "imu":
            raise _invalid(f"{path}.axis", f["axis"], f"null for sensor {sensor} (imu only)")
        if kind == "sensor_dropout" and not 0.0 < f["probability"] <= 1.0:
            raise _invalid(f"{path}.probability", f["probability"], "0 < probability <= 1")
        if kind == "sensor_bias":
            unit, other = ("bias_deg", "bias_mm") if sensor == "imu" else ("bias_mm", "bias_deg")
            if f[other] is not None:
                raise _invalid(f"{path}.{other}", f[other], f"null for sensor {sensor}; use {unit}")
            if f[unit] is None:
                raise UserInputError(f"missing key at {path}.{unit}: a {sensor} bias needs {unit}")
            bound = 90.0 if unit == "bias_deg" else 500.0
            if abs(f[unit]) > bound:
                raise _invalid(f"{path}.{unit}", f[unit], f"|{unit}| <= {bound:g}")


def _check_fault_values(s: Mapping) -> None:
    """Fault times within the run and a supply drop below the supply pressure."""
    duration = s["duration_s"]
    supply = _supply_bar_gauge(s)
    for i, f in enumerate(s["faults"]):
        here = f"faults[{i}]"
        if f["time_s"] >= duration:
            raise _invalid(f"{here}.time_s", f["time_s"], f"< duration_s = {duration} s")
        if f.get("end_s") is not None and f["end_s"] > duration:
            raise _invalid(f"{here}.end_s", f["end_s"], f"null or <= duration_s = {duration} s")
        if f["type"] == "supply_drop" and not 0.0 <= f["pressure_bar_gauge"] < supply:
            raise _invalid(
                f"{here}.pressure_bar_gauge",
                f["pressure_bar_gauge"],
                f"0 (atmospheric) <= p < the supply {supply:g} bar gauge "
                "(actuator.pneumatics.supply_pressure_bar_gauge)",
            )


def late_setpoints(s: Mapping) -> list[str]:
    """Set-point components that start after the run ends: they never act.

    Not an error (a short run of a shipped scenario cuts its steps off on
    purpose), but never silent: :func:`simpro_mj.analysis.preflight.preflight` turns
    each into a warning line, recorded in ``metrics.json``.
    """
    duration = s["duration_s"]
    out = []
    for axis in SETPOINT_AXES:  # not setpoint.cueing (issue 16), which has no components
        for i, c in enumerate(s["setpoint"].get(axis) or ()):
            key = {"step": "time_s", "ramp": "start_s", "sine": "start_s"}.get(c["type"])
            if key is not None and c[key] > duration:
                out.append(
                    f"setpoint.{axis}[{i}].{key} = {c[key]:g} s is after the end of the run "
                    f"(duration_s = {duration:g} s): this {c['type']} never acts"
                )
    return out


def _supply_bar_gauge(s: Mapping) -> float:
    value = (s["actuator"].get("pneumatics") or {}).get("supply_pressure_bar_gauge")
    if value is None:
        try:
            from simpro_mj.plant.pneumatics import DEFAULT_PNEUMATIC_PARAMS
        except ImportError:  # pragma: no cover
            return 6.0
        value = DEFAULT_PNEUMATIC_PARAMS["supply_pressure_bar_gauge"]
    return float(value)


def _check_redesign(s: Mapping) -> None:
    """The pole placement of ``variant: redesigned`` must be feasible for every leg."""
    inner = s["controller"]["inner"]
    if inner["variant"] != "redesigned":
        return
    from controllers.design import ACTUATORS, Plant, paper_plant, redesigned_design
    from controllers.errors import DesignError

    for act in ACTUATORS:
        if inner["design_plant"] == "identified":
            plant = Plant(**inner["identified"][act])
        else:
            plant = paper_plant(act, s["paper_units"])
        try:
            redesigned_design(act, zeta=inner["zeta"], wn=inner["wn_rad_s"], plant=plant)
        except DesignError as exc:
            raise UserInputError(
                f"infeasible joint design at controller.inner.wn_rad_s: zeta = {inner['zeta']}, "
                f"wn = {inner['wn_rad_s']} rad/s for {act}: {exc}; allowed: a zeta, wn_rad_s "
                "pair the pole placement can meet (e.g. the paper's 0.7, 10)"
            ) from exc


def _require(tree: Mapping, path: str, ok, allowed: str) -> None:
    node: Any = tree
    for part in path.split("."):
        node = node[part]
    values = node if isinstance(node, list) else [node]
    if not all(ok(v) for v in values):
        raise _invalid(path, node, allowed)


def _enum(tree: Mapping, path: str, choices: tuple) -> None:
    node: Any = tree
    for part in path.split("."):
        node = node[part]
    if node not in choices:
        raise _invalid(path, node, f"one of {list(choices)}{closest(str(node), map(str, choices))}")


def _setpoint_filter_times(tree: Mapping, path: str) -> None:
    """One time for every leg or three (controllers.setpoint_filter.leg_times), each
    an integer multiple of the 1 ms step (the ramp averages whole steps)."""
    node: Any = tree
    for part in path.split("."):
        node = node[part]
    values = node if isinstance(node, list) else [node]
    ok = len(values) in (1, 3) and all(
        abs(float(v) / _PHYSICS_DT_MS - round(float(v) / _PHYSICS_DT_MS)) < 1e-9 for v in values
    )
    if not ok:
        raise _invalid(
            path, node, f"one or 3 (per leg) multiples of the {_PHYSICS_DT_MS:g} ms physics step"
        )


def _multiple_of_step(tree: Mapping, path: str) -> None:
    node: Any = tree
    for part in path.split("."):
        node = node[part]
    ratio = float(node) / _PHYSICS_DT_MS
    # isfinite first: round(inf) raises (found by the hypothesis loader test)
    if not (math.isfinite(ratio) and ratio >= 1 and abs(ratio - round(ratio)) < 1e-9) or (
        float(node) > MAX_PERIOD_MS
    ):
        raise _invalid(
            path,
            node,
            f"a positive integer multiple of the {_PHYSICS_DT_MS} ms physics step, "
            f"<= {MAX_PERIOD_MS} ms",
        )


def validate_scenario(tree: Mapping) -> dict:
    """Validate a merged scenario tree and return it normalised.

    Parameters
    ----------
    tree : mapping
        A scenario with every key present (defaults merged).

    Returns
    -------
    dict
        The normalised scenario (numbers as the defaults' types, components
        spelled out). Does not check reachability (:func:`check_setpoints`).

    Raises
    ------
    UserInputError
        Naming the dotted path of the first offending field and what is allowed.
    """
    # periods are integers in ms but "2.5" must say "multiple of 1 ms", not "integer"
    for path in (
        "controller.outer.period_ms",
        "sensors.potentiometer.rate_ms",
        "sensors.height_encoder.rate_ms",
        "sensors.imu.rate_ms",
    ):
        node: Any = tree
        for part in path.split("."):
            node = node.get(part) if isinstance(node, Mapping) else None
        if isinstance(node, (int, float)) and not isinstance(node, bool):
            _multiple_of_step(tree, path)

    s = _check_tree(tree, DEFAULT_SCENARIO, "")
    if not _NAME_RE.match(s["name"]) or len(s["name"]) > 100:
        raise _invalid(
            "name",
            s["name"],
            "letters, digits, '_', '-', '.' (a file-name-safe word of at most 100 characters)",
        )
    _require(s, "duration_s", lambda v: v > 0, "> 0 s")
    _require(s, "duration_s", lambda v: v >= MIN_DURATION_S, f">= {MIN_DURATION_S:g} s")
    _require(s, "duration_s", lambda v: v <= MAX_DURATION_S, f"<= {MAX_DURATION_S:g} s (one hour)")
    _require(s, "seed", lambda v: 0 <= v < 2**63, "an integer >= 0")
    c = "controller"
    _enum(s, "paper_units", PAPER_UNITS)
    _enum(s, f"{c}.mode", MODES)
    _enum(s, f"{c}.outer.type", OUTER_TYPES)
    _require(s, f"{c}.outer.gains", lambda v: v >= 0, "3 numbers >= 0 (K K_I, 1/s)")
    _require(s, f"{c}.outer.pi_zero", lambda v: -1 < v < 1, "-1 < c < 1")
    _enum(s, f"{c}.outer.integrator", INTEGRATORS)
    _multiple_of_step(s, f"{c}.outer.period_ms")
    _enum(s, f"{c}.outer.delay_samples", DELAY_SAMPLES)
    _enum(s, f"{c}.inner.variant", INNER_VARIANTS)
    _enum(s, f"{c}.inner.identify", IDENTIFY_CHOICES)
    _enum(s, f"{c}.inner.discretisation", DISCRETISATIONS)
    _enum(s, f"{c}.inner.design_plant", DESIGN_PLANTS)
    _enum(s, f"{c}.setpoint_filter.type", SETPOINT_FILTERS)
    _require(s, f"{c}.setpoint_filter.time_ms", lambda v: 0 < v <= 1e4, "0 < ms <= 1e4")
    _setpoint_filter_times(s, f"{c}.setpoint_filter.time_ms")
    for act in ("actuator1", "actuator2", "actuator3"):
        _require(s, f"{c}.inner.identified.{act}.b", lambda v: v > 0, "> 0 m/V")
        _require(s, f"{c}.inner.identified.{act}.a1", lambda v: v >= 0, ">= 0 1/s")
        _require(s, f"{c}.inner.identified.{act}.a0", lambda v: v > 0, "> 0 1/s^2")
    _require(s, f"{c}.feedforward.model_tau_ms", lambda v: 0 <= v <= 10_000, "0..10000 ms")
    _require(s, f"{c}.feedforward.gains", lambda v: v >= 0, "3 numbers >= 0 (K K_I, 1/s)")
    _enum(s, f"{c}.feedforward.lag", FEEDFORWARD_LAGS)
    _require(s, f"{c}.inner.zeta", lambda v: 0 < v < 2, "0 < zeta < 2")
    _require(s, f"{c}.inner.wn_rad_s", lambda v: v > 0, "> 0 rad/s")
    _enum(s, "actuator.model", ACTUATOR_MODELS)

    p = "plant"
    _require(s, f"{p}.payload.mass_kg", lambda v: v >= 0, ">= 0 kg")
    _require(s, f"{p}.platform_mass_kg", lambda v: v > 0, "> 0 kg")
    _require(s, f"{p}.loop_timeconst_s", lambda v: v > 0, "> 0 s")
    _require(s, f"{p}.guide.radius_offset_mm", lambda v: v > -1000, "> -1000 mm")

    pot = "sensors.potentiometer"
    _require(s, f"{pot}.bits", lambda v: 4 <= v <= 24, "an integer 4..24")
    _require(s, f"{pot}.range_v", lambda v: v > 0, "> 0 V")
    _require(s, f"{pot}.volts_per_mm", lambda v: v > 0, "> 0 V/mm")
    _require(s, f"{pot}.noise_lsb", lambda v: v >= 0, ">= 0 LSB")
    _require(s, f"{pot}.gain_error_pct", lambda v: v > -100, "3 numbers > -100 %")
    enc = "sensors.height_encoder"
    _require(s, f"{enc}.resolution_mm", lambda v: v >= 0, ">= 0 mm (0: no quantisation)")
    _require(s, f"{enc}.noise_mm", lambda v: v >= 0, ">= 0 mm")
    imu = "sensors.imu"
    _require(s, f"{imu}.noise_deg", lambda v: v >= 0, ">= 0 deg")
    _require(s, f"{imu}.bandwidth_hz", lambda v: v > 0, "> 0 Hz")
    for sensor in (pot, enc, imu):
        _multiple_of_step(s, f"{sensor}.rate_ms")
    _require(
        s,
        "logging.decimation",
        lambda v: 1 <= v <= MAX_DECIMATION,
        f"an integer 1..{MAX_DECIMATION}",
    )
    _check_redesign(s)
    _check_fault_values(s)
    return s


# ------------------------------------------------------------------ set-points


def _component(c: Mapping, t: np.ndarray) -> np.ndarray:
    kind = c["type"]
    if kind == "step":
        return np.where(t >= c["time_s"], c["value"], 0.0)
    if kind == "ramp":
        frac = np.clip((t - c["start_s"]) / (c["end_s"] - c["start_s"]), 0.0, 1.0)
        return c["value"] * frac
    if kind == "sine":
        start = c.get("start_s", 0.0)
        end = math.inf if c.get("end_s") is None else c["end_s"]
        phase = math.radians(c.get("phase_deg", 0.0))
        wave = c["amplitude"] * np.sin(2.0 * np.pi * (t - start) / c["period_s"] + phase)
        return np.where((t >= start) & (t < end), wave, 0.0)
    if kind == "table":
        return np.interp(t, np.asarray(c["times_s"], float), np.asarray(c["values"], float))
    raise UserInputError(f"invalid value at setpoint: component type {kind!r}")  # pragma: no cover


def _clamp(pose: np.ndarray, geometry, iterations: int = 40) -> np.ndarray:
    """Pull unreachable poses back along the segment from home (bisection, vectorised)."""
    ok = reachable(pose, geometry)
    if ok.all():
        return pose
    home = np.asarray(geometry.home, dtype=float)
    bad = pose[~ok]
    d = bad - home
    lo = np.zeros(len(bad))
    hi = np.ones(len(bad))
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        inside = reachable(home + mid[:, None] * d, geometry)
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    out = pose.copy()
    out[~ok] = home + lo[:, None] * d
    return out


def reference(scenario: Mapping, t, *, clamp: bool | None = None) -> np.ndarray:
    """The set-point pose at times ``t``, SI, vectorised.

    Parameters
    ----------
    scenario : mapping
        A resolved scenario (:func:`load_scenario`).
    t : array_like, (n,)
        Times (s).
    clamp : bool, optional
        Pull unreachable poses back to the workspace boundary along the segment
        from the home pose (40 bisection steps on the nominal geometry).
        Default: ``scenario["controller"]["clamp_setpoints"]``.

    Returns
    -------
    ndarray, (n, 3)
        (roll rad, pitch rad, heave m); heave absolute, home height + ``heave_mm``.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    geometry = nominal_geometry()
    sp = scenario["setpoint"]
    if sp.get("cueing"):  # issue 16: the washout's set-points, inside its workspace box
        from simpro_mj.config.cueing import cue_poses

        return cue_poses(scenario, t)
    out = np.empty((t.size, 3))
    for j, (axis, scale) in enumerate(
        zip(SETPOINT_AXES, (math.pi / 180.0, math.pi / 180.0, 1e-3), strict=True)
    ):
        total = np.zeros(t.size)
        for c in sp.get(axis) or ():
            total += _component(c, t)
        out[:, j] = geometry.home[j] + scale * total
    if clamp is None:
        clamp = bool(scenario["controller"]["clamp_setpoints"])
    if clamp:
        out = _clamp(out, geometry)
    return out


#: Poses per block of :func:`check_setpoints` (memory bound, not a result).
_CHECK_BLOCK = 20_000


def check_setpoints(scenario: Mapping, t=None) -> None:
    """Raise :class:`SetpointError` if the set-point leaves the reachable workspace.

    Parameters
    ----------
    scenario : mapping
        A resolved scenario.
    t : array_like, optional
        Times to check; default the 1 ms physics grid over ``[0, duration_s]``
        (every sample the controllers can see).
    """
    if t is None:
        n = int(round(scenario["duration_s"] / PHYSICS_DT_S))
        t = np.arange(n + 1) * PHYSICS_DT_S
    t = np.atleast_1d(np.asarray(t, dtype=float))
    geometry = nominal_geometry()
    # in blocks: the vectorised IK holds ~350 B of temporaries per pose, which
    # over a whole 600 s grid would be 200 MB for a check that keeps nothing
    for k0 in range(0, t.size, _CHECK_BLOCK):
        pose = reference(scenario, t[k0 : k0 + _CHECK_BLOCK], clamp=False)
        ok = reachable(pose, geometry)
        if not ok.all():
            break
    else:
        return
    k = int(np.argmin(ok))
    t = t[k0:]
    try:
        check_reachable(pose[k], geometry)
        why = "outside the guide arc or stroke limits"
    except WorkspaceError as exc:
        why = str(exc)
    roll, pitch, heave = pose[k]
    raise SetpointError(
        f"unreachable set-point at setpoint (t = {t[k]:.3f} s: roll {math.degrees(roll):.2f} deg, "
        f"pitch {math.degrees(pitch):.2f} deg, heave {(heave - geometry.home[2]) * 1e3:+.1f} mm "
        f"from home): {why} (see simpro-sim workspace); or set "
        "controller.clamp_setpoints=true to clamp"
    )
