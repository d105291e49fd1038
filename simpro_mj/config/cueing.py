"""Motion cueing in a scenario: vehicle input -> washout -> set-points.

A scenario's ``setpoint`` may hold a ``cueing`` block instead of pose
components::

    setpoint:
      cueing:
        telemetry: braking_100kmh.csv   # a telemetry CSV (simpro_mj/config/telemetry.py), or
        manoeuvre: null                 # {type: braking|lane_change|slalom|bump, speed_kmh, ...}
        sine: null                      # or {channel: fx_mps2, amplitude: 0.3, period_s: 4.0}
        step: null                      # or {channel: fx_mps2, amplitude: -4, start_s: 1,
                                        #     ramp_s: 0, end_s: null}: a large-signal input
        algorithm: classical_washout    # or mpc (controllers/mpc_cueing.py)
        parameters: {}                  # PARAMETER_KEYS (mpc: MPC_PARAMETER_KEYS), YAML units
        columns: {}                     # telemetry column mapping (config/telemetry.py)

``sine`` is a synthetic vehicle input: the vehicle at rest (``f = (0, 0, g)``,
``w = 0``) plus ``amplitude * sin(2 pi t / period_s)`` on one ``channel``
(:data:`SINE_CHANNELS`, telemetry column names, SI); it is what
``simpro-sim response --chain`` runs, one channel and frequency at a time.

The block is validated by :class:`simpro_mj.config.models.Cueing` (with the
rest of the scenario; :func:`simpro_mj.config.models.check_cueing` for a block
alone). A relative ``telemetry`` path is found beside the scenario file, then
among the shipped files (``scenarios/telemetry/``). The resolved
scenario spells out every parameter. The vehicle input is resampled to the 1 ms
physics grid (linear), the washout runs at its own period on every
``period``-th sample and its set-point is held in between (what the rig's
computer would do); the chain is computed once per scenario and cached.

What the driver perceives, vehicle against simulator, is measured in
:mod:`simpro_mj.analysis.cue_metrics`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from controllers.cue_mpc_params import MpcParams
from controllers.geometry import geometry_from_rig
from controllers.washout import ClassicalWashout, WashoutParams
from simpro_mj.config.telemetry import read_telemetry, resample
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.rates import PHYSICS_DT_S, steps_per_period
from simpro_mj.core.shipped import TELEMETRY_DIR, user_path

if TYPE_CHECKING:
    from simpro_mj.config.cue_models import Cueing
    from simpro_mj.config.models import Scenario

__all__ = [
    "PARAMETER_KEYS",
    "MPC_PARAMETER_KEYS",
    "ALGORITHMS",
    "SINE_CHANNELS",
    "TELEMETRY_DIR",
    "default_parameters",
    "manoeuvre_spec",
    "resolve_paths",
    "washout_params",
    "vehicle_input",
    "cue_poses",
    "CUE_COLUMNS",
]

ALGORITHMS = ("classical_washout", "mpc")
#: Channels a ``sine`` vehicle input may drive (telemetry column names, SI) and their
#: largest amplitude: 1 g of specific force, 90 deg/s.
SINE_CHANNELS = {
    "fx_mps2": 9.80665,
    "fy_mps2": 9.80665,
    "fz_mps2": 9.80665,
    "wx_rad_s": math.pi / 2,
    "wy_rad_s": math.pi / 2,
}

#: YAML key -> (WashoutParams field, factor from the YAML unit to SI).
PARAMETER_KEYS = {
    "period_ms": ("period", 1e-3),
    "gain_x": ("gain_x", 1.0),
    "gain_y": ("gain_y", 1.0),
    "gain_z": ("gain_z", 1.0),
    "gain_rot": ("gain_rot", 1.0),
    "tilt_omega_rad_s": ("tilt_omega", 1.0),
    "tilt_zeta": ("tilt_zeta", 1.0),
    "tilt_rate_limit_deg_s": ("tilt_rate_limit", math.pi / 180.0),
    "tilt_limit_deg": ("tilt_limit", math.pi / 180.0),
    "tilt_accel_limit_deg_s2": ("tilt_accel_limit", math.pi / 180.0),
    "head_height_m": ("head_height", 1.0),
    "head_height_pitch_m": ("head_height_pitch", 1.0),
    "jolt_limit_mps2": ("jolt_limit", 1.0),
    "heave_omega_rad_s": ("heave_omega", 1.0),
    "heave_zeta": ("heave_zeta", 1.0),
    "heave_omega_b_rad_s": ("heave_omega_b", 1.0),
    "rot_order": ("rot_order", 1.0),
    "rot_omega_rad_s": ("rot_omega", 1.0),
    "rot_zeta": ("rot_zeta", 1.0),
    "heave_fraction": ("heave_fraction", 1.0),
    "stroke_margin_mm": ("stroke_margin", 1e-3),
    "knee": ("knee", 1.0),
}


#: YAML key -> (MpcParams field, factor from the YAML unit to SI), ``algorithm: mpc``.
MPC_PARAMETER_KEYS = {
    "period_ms": ("period", 1e-3),
    "horizon": ("horizon", 1.0),
    "gain_x": ("gain_x", 1.0),
    "gain_y": ("gain_y", 1.0),
    "gain_z": ("gain_z", 1.0),
    "gain_rot": ("gain_rot", 1.0),
    "weight_f": ("weight_f", 1.0),
    "weight_raw": ("weight_raw", 1.0),
    "weight_w": ("weight_w", 1.0),
    "weight_tilt": ("weight_tilt", 1.0),
    "weight_jerk": ("weight_jerk", 1.0),
    "tilt_rate_max_deg_s": ("tilt_rate_max", math.pi / 180.0),
    "tilt_accel_max_deg_s2": ("tilt_accel_max", math.pi / 180.0),
    "heave_rate_max_mm_s": ("heave_rate_max", 1e-3),
    "heave_accel_max_mps2": ("heave_accel_max", 1.0),
    "head_height_m": ("head_height", 1.0),
    "head_height_pitch_m": ("head_height_pitch", 1.0),
    "preview_s": ("preview", 1.0),
    "heave_fraction": ("heave_fraction", 1.0),
    "stroke_margin_mm": ("stroke_margin", 1e-3),
    "box_fraction": ("box_fraction", 1.0),
    "rotation_limit": ("rotation_limit", 1.0),
    "rotation_limit_pitch": ("rotation_limit_pitch", 1.0),
    "lead_s": ("lead", 1.0),
    "lead_x_s": ("lead_x", 1.0),
    "loop_omega_rad_s": ("loop_omega", 1.0),
    "loop_zeta": ("loop_zeta", 1.0),
    "loop_zero_s": ("loop_zero", 1.0),
    "loop_delay_s": ("loop_delay", 1.0),
    "loop_filter_s": ("loop_filter", 1.0),
    "knee_mps2": ("knee", 1.0),
    "jolt_limit_mps2": ("jolt_limit", 1.0),
    "heave_washout_rad_s": ("heave_washout", 1.0),
    "weight_heave": ("weight_heave", 1.0),
    "weight_heave_rate": ("weight_heave_rate", 1.0),
    "gain_y_sustained": ("gain_y_sustained", 1.0),
    "sustained_tau_s": ("sustained_tau", 1.0),
}
#: Whole-number parameters (an int in the resolved scenario).
_INTEGERS = ("rot_order", "horizon")


def parameter_keys(algorithm: str = "classical_washout") -> dict:
    """The YAML key -> (field, factor) table of ``algorithm``."""
    return MPC_PARAMETER_KEYS if algorithm == "mpc" else PARAMETER_KEYS


def default_parameters(algorithm: str = "classical_washout") -> dict:
    """The law's defaults (:class:`WashoutParams`, :class:`MpcParams`) as ``parameters``
    (YAML units).

    ``rot_order`` and ``horizon`` ints, the others floats rounded to 12 digits (so
    that a default reads as ``3.0`` deg/s, not ``3.0000000000000004``).
    """
    p = MpcParams() if algorithm == "mpc" else WashoutParams()
    out = {}
    for key, (name, factor) in parameter_keys(algorithm).items():
        v = getattr(p, name) / factor
        out[key] = int(round(v)) if name in _INTEGERS else float(round(v, 12))
    return out


def sine_input(sine: Mapping, t) -> tuple[np.ndarray, np.ndarray]:
    """``f``, ``w`` (len(t), 3) of a ``sine`` vehicle input at times ``t`` (V frame, SI)."""
    from controllers.frames import GRAVITY

    t = np.asarray(t, dtype=float)
    f = np.zeros((t.size, 3))
    w = np.zeros((t.size, 3))
    f[:, 2] = GRAVITY
    ch = sine["channel"]
    k = "xyz".index(ch[1])
    (f if ch[0] == "f" else w)[:, k] += sine["amplitude"] * np.sin(
        2.0 * math.pi * t / sine["period_s"]
    )
    return f, w


def step_input(step: Mapping, t) -> tuple[np.ndarray, np.ndarray]:
    """``f``, ``w`` (len(t), 3) of a ``step`` vehicle input: the vehicle at rest plus
    ``amplitude`` on one ``channel`` from ``start_s``, reached over ``ramp_s`` (0: a
    step), and back to rest the same way from ``end_s`` (null: held)."""
    from controllers.frames import GRAVITY

    t = np.asarray(t, dtype=float)
    f = np.zeros((t.size, 3))
    w = np.zeros((t.size, 3))
    f[:, 2] = GRAVITY
    ramp = float(step["ramp_s"])

    def edge(t0: float) -> np.ndarray:
        if ramp <= 0:
            return (t >= t0).astype(float)
        return np.clip((t - t0) / ramp, 0.0, 1.0)

    shape = edge(float(step["start_s"]))
    if step.get("end_s") is not None:
        shape = shape - edge(float(step["end_s"]))
    ch = step["channel"]
    k = "xyz".index(ch[1])
    (f if ch[0] == "f" else w)[:, k] += step["amplitude"] * shape
    return f, w


def manoeuvre_spec(man: Mapping):
    """The :class:`~simpro_mj.config.manoeuvres.ManoeuvreSpec` of a ``manoeuvre`` block."""
    # imported on use: manoeuvres loads scipy.signal and scipy.integrate (about 1.5 s),
    # which only a scenario with a manoeuvre needs
    from simpro_mj.config.manoeuvres import ManoeuvreSpec

    return ManoeuvreSpec(
        manoeuvre=man["type"],
        speed_kmh=man["speed_kmh"],
        vehicle=man["vehicle"],
        deceleration_mps2=man["deceleration_mps2"],
        bump_height_m=man["bump_height_m"],
        bump_length_m=man["bump_length_m"],
        lead_s=man["lead_s"],
        tyre_offsets=man["tyre_offsets"],
    )


def sweep_defaults() -> dict:
    """The sweepable tree under ``setpoint.cueing``: the algorithm, the vehicle input
    and the parameters (YAML units; the washout's keys, the MPC's too)."""
    return {
        "algorithm": "classical_washout",
        "telemetry": "",
        "parameters": {**default_parameters("mpc"), **default_parameters()},
    }


def resolve_paths(cue: Cueing, base: Path | None) -> None:
    """Make ``setpoint.cueing.telemetry`` an absolute path (beside the scenario, then shipped).

    Raises :class:`UserInputError` naming the key if the file is in neither place.
    """
    if not cue.telemetry:
        return
    name = user_path(cue.telemetry, "setpoint.cueing.telemetry")
    tries = [name] if name.is_absolute() else []
    if not name.is_absolute():
        if base is not None:
            tries.append(Path(base) / name)
        tries += [Path.cwd() / name, TELEMETRY_DIR / name]
    for p in tries:
        if p.is_file():
            cue.telemetry = str(p.resolve())
            return
        if p.exists() and not p.is_dir():  # a FIFO, a device: refused, never opened
            raise UserInputError(
                f"invalid value at setpoint.cueing.telemetry: {str(p)!r} is not a regular "
                "file (a FIFO, a device or a socket); allowed: a CSV file"
            )
    shipped = sorted(q.name for q in TELEMETRY_DIR.glob("*.csv"))
    raise UserInputError(
        f"invalid value at setpoint.cueing.telemetry: {str(name)!r} not found beside the "
        f"scenario or among the shipped files; allowed: a CSV path or one of {shipped}"
    )


def washout_params(cue: Cueing | Mapping) -> WashoutParams | MpcParams:
    """:class:`WashoutParams` (or :class:`MpcParams` for ``algorithm: mpc``) from a
    resolved block's ``parameters`` (YAML units), typed or its dict."""
    if not isinstance(cue, Mapping):
        cue = cue.model_dump()
    algorithm = cue.get("algorithm", "classical_washout")
    keys = parameter_keys(algorithm)
    kw: dict[str, Any] = {}
    for key, v in cue["parameters"].items():
        name, factor = keys[key]
        if name in _INTEGERS:  # a whole number as int; 1.5 stays 1.5 and is refused
            kw[name] = int(v) if float(v).is_integer() else float(v)
        else:
            kw[name] = float(v) * factor
    return MpcParams(**kw) if algorithm == "mpc" else WashoutParams(**kw)


def _key(cue: Mapping, duration: float, rig: Mapping | None = None) -> str:
    return json.dumps({"cue": cue, "duration": duration, "rig": rig}, sort_keys=True, default=str)


@lru_cache(maxsize=8)
def _chain(key: str):
    d = json.loads(key)
    cue, duration = d["cue"], d["duration"]
    geometry = geometry_from_rig(d["rig"])  # the workspace box of the scenario's rig
    n = int(round(duration / PHYSICS_DT_S))
    t = np.arange(n + 1) * PHYSICS_DT_S
    if cue.get("sine"):
        f, w = sine_input(cue["sine"], t)
        s = cue["sine"]
        source = f"sine {s['channel']} {s['amplitude']:g} x {s['period_s']:g} s"
    elif cue.get("step"):
        f, w = step_input(cue["step"], t)
        s = cue["step"]
        source = (
            f"{'ramp' if s['ramp_s'] > 0 else 'step'} {s['channel']} {s['amplitude']:g} "
            f"from {s['start_s']:g} s"
        )
    else:
        if cue.get("telemetry"):
            tel = read_telemetry(
                cue["telemetry"], label=Path(cue["telemetry"]).name, columns=cue.get("columns")
            )
        else:
            from simpro_mj.config.manoeuvres import generate

            tel = generate(manoeuvre_spec(cue["manoeuvre"]))
        if tel.t[-1] < t[-1] - 1e-9:
            # the longest run the file allows, on the physics grid
            longest = math.floor(tel.t[-1] / PHYSICS_DT_S + 1e-9) * PHYSICS_DT_S
            raise UserInputError(
                f"invalid value at duration_s: {duration:g} s is longer than the vehicle input "
                f"({tel.t[-1]:g} s, {tel.source}); allowed: <= {longest:.3f}"
            )
        f, w = resample(tel, t)
        source = tel.source
    params = washout_params(cue)
    every = steps_per_period(
        params.period * 1e3, PHYSICS_DT_S, "setpoint.cueing.parameters.period_ms"
    )
    if cue.get("algorithm") == "mpc":
        from controllers.mpc_cueing import ModelPredictiveCueing  # on use: imports osqp

        assert isinstance(params, MpcParams)
        mpc = ModelPredictiveCueing(params, geometry=geometry)
        law: ModelPredictiveCueing | ClassicalWashout = mpc
        # the model's own trajectory between solves: a set-point every 1 ms
        planned = mpc.run(f, w, PHYSICS_DT_S)
        pose = planned.pose
        none = np.zeros(t.size, bool)
        info = {
            "rate_limited": none,
            "softened": none,
            "rate_limited_fraction": 0.0,
            "softened_fraction": 0.0,
            "solve_time": planned.solve_time_stats(),
        }
    else:
        assert isinstance(params, WashoutParams)
        law = washout = ClassicalWashout(params, geometry=geometry)
        res = washout.run(f[::every], w[::every])
        pose = np.repeat(res.pose, every, axis=0)[: t.size]  # zero-order hold
        info = {
            "rate_limited": res.rate_limited,
            "softened": res.softened,
            "rate_limited_fraction": float(res.rate_limited.mean()),
            "softened_fraction": float(res.softened.mean()),
        }
    for arr in (f, w, pose):
        arr.setflags(write=False)
    info.update(
        source=source,
        every=every,
        algorithm=cue.get("algorithm", "classical_washout"),
        box={k: list(map(float, v)) if k != "scale" else v for k, v in law.box.items()},
    )
    return t, f, w, pose, info


def vehicle_input(scenario: Scenario | Mapping):
    """(t, f, w, pose, info) of a cueing scenario, typed or its dict, on the 1 ms grid
    (cached, read-only arrays)."""
    if not isinstance(scenario, Mapping):
        cue = scenario.setpoint.cueing
        assert cue is not None, "a cueing scenario"
        rig = scenario.plant.model_dump()["rig"]
        return _chain(_key(cue.model_dump(), scenario.duration_s, rig))
    cue = scenario["setpoint"]["cueing"]
    return _chain(_key(cue, float(scenario["duration_s"]), scenario["plant"].get("rig")))


def cue_poses(scenario: Mapping, t) -> np.ndarray:
    """The washout's set-points (n, 3) at times ``t`` (held between cueing periods)."""
    tg, _, _, pose, _ = vehicle_input(scenario)
    t = np.atleast_1d(np.asarray(t, dtype=float))
    k = np.clip(np.rint(t / PHYSICS_DT_S).astype(int), 0, tg.size - 1)
    return pose[k]


#: Extra logged columns of a cueing run (V frame, SI).
CUE_COLUMNS = (
    [f"veh_f{a}_mps2" for a in "xyz"]
    + [f"veh_w{a}_rad_s" for a in "xyz"]
    + [f"head_f{a}_mps2" for a in "xyz"]
    + [f"head_w{a}_rad_s" for a in "xyz"]
)
