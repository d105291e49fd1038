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
(:data:`~simpro_mj.config.cue_params.SINE_CHANNELS`, telemetry column names, SI); it is what
``simpro-sim response --chain`` runs, one channel and frequency at a time.

The block is validated by :class:`simpro_mj.config.models.Cueing` (with the
rest of the scenario; :func:`simpro_mj.config.cue_models.check_cueing` for a block
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
from typing import TYPE_CHECKING

import numpy as np

from controllers.cue_mpc_params import MpcParams
from controllers.geometry import geometry_from_rig
from controllers.washout import ClassicalWashout, WashoutParams
from simpro_mj.config.cue_models import Cueing, CueSine, CueStep
from simpro_mj.config.cue_params import default_parameters, manoeuvre_spec, washout_params
from simpro_mj.config.telemetry import read_telemetry, resample
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.rates import PHYSICS_DT_S, steps_per_period
from simpro_mj.core.shipped import TELEMETRY_DIR, user_path

if TYPE_CHECKING:
    from simpro_mj.config.models import Scenario


def _on_channel(channel: str, signal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``f``, ``w`` (len(signal), 3): the vehicle at rest (``f = (0, 0, g)``, ``w = 0``)
    plus ``signal`` on one ``channel`` (:data:`~simpro_mj.config.cue_params.SINE_CHANNELS`)."""
    from controllers.frames import GRAVITY

    f = np.zeros((signal.size, 3))
    w = np.zeros((signal.size, 3))
    f[:, 2] = GRAVITY
    (f if channel[0] == "f" else w)[:, "xyz".index(channel[1])] += signal
    return f, w


def sine_input(sine: CueSine | Mapping, t) -> tuple[np.ndarray, np.ndarray]:
    """``f``, ``w`` (len(t), 3) of a ``sine`` vehicle input at times ``t`` (V frame, SI)."""
    s = sine if isinstance(sine, CueSine) else CueSine.model_validate(sine)
    t = np.asarray(t, dtype=float)
    return _on_channel(s.channel, s.amplitude * np.sin(2.0 * math.pi * t / s.period_s))


def step_input(step: CueStep | Mapping, t) -> tuple[np.ndarray, np.ndarray]:
    """``f``, ``w`` (len(t), 3) of a ``step`` vehicle input: the vehicle at rest plus
    ``amplitude`` on one ``channel`` from ``start_s``, reached over ``ramp_s`` (0: a
    step), and back to rest the same way from ``end_s`` (null: held)."""
    s = step if isinstance(step, CueStep) else CueStep.model_validate(step)
    t = np.asarray(t, dtype=float)

    def edge(t0: float) -> np.ndarray:
        if s.ramp_s <= 0:
            return (t >= t0).astype(float)
        return np.clip((t - t0) / s.ramp_s, 0.0, 1.0)

    shape = edge(s.start_s)
    if s.end_s is not None:
        shape = shape - edge(s.end_s)
    return _on_channel(s.channel, s.amplitude * shape)


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


class _Chain:
    """What one vehicle-input chain is computed from (:func:`_chain`'s cache key):
    equal, and hashed alike, when the block, the length and the rig are."""

    def __init__(self, cue: Cueing, duration: float, rig: dict | None):
        self.cue, self.duration, self.rig = cue, float(duration), rig
        self.key = json.dumps(
            {"cue": cue.model_dump(), "duration": self.duration, "rig": rig},
            sort_keys=True,
            default=str,
        )

    def __hash__(self) -> int:
        return hash(self.key)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _Chain) and other.key == self.key


@lru_cache(maxsize=8)
def _chain(inputs: _Chain):
    cue, duration = inputs.cue, inputs.duration
    geometry = geometry_from_rig(inputs.rig)  # the workspace box of the scenario's rig
    n = int(round(duration / PHYSICS_DT_S))
    t = np.arange(n + 1) * PHYSICS_DT_S
    if cue.sine is not None:
        s = cue.sine
        f, w = sine_input(s, t)
        source = f"sine {s.channel} {s.amplitude:g} x {s.period_s:g} s"
    elif cue.step is not None:
        st = cue.step
        f, w = step_input(st, t)
        source = (
            f"{'ramp' if st.ramp_s > 0 else 'step'} {st.channel} {st.amplitude:g} "
            f"from {st.start_s:g} s"
        )
    else:
        if cue.telemetry:
            tel = read_telemetry(cue.telemetry, label=Path(cue.telemetry).name, columns=cue.columns)
        else:
            from simpro_mj.config.manoeuvres import generate

            assert cue.manoeuvre is not None  # exactly one vehicle input (Cueing)
            tel = generate(manoeuvre_spec(cue.manoeuvre))
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
    if cue.algorithm == "mpc":
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
        algorithm=cue.algorithm,
        box={k: list(map(float, v)) if k != "scale" else v for k, v in law.box.items()},
    )
    return t, f, w, pose, info


def vehicle_input(scenario: Scenario | Mapping):
    """(t, f, w, pose, info) of a cueing scenario, typed or its dict, on the 1 ms grid
    (cached, read-only arrays)."""
    if isinstance(scenario, Mapping):  # the resolved dict: its block read again, typed
        cue = Cueing.model_validate(scenario["setpoint"]["cueing"])
        duration, rig = scenario["duration_s"], scenario["plant"].get("rig")
    else:
        assert scenario.setpoint.cueing is not None, "a cueing scenario"
        cue, duration = scenario.setpoint.cueing, scenario.duration_s
        rig = scenario.plant.tree()["rig"]
    return _chain(_Chain(cue, duration, rig))


def cue_poses(scenario: Scenario | Mapping, t) -> np.ndarray:
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
