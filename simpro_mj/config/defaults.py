"""Every key of a scenario with its default (the first room of the scenario).

:data:`DEFAULT_SCENARIO` is the tree a scenario file is merged over
(:func:`simpro_mj.config.scenario.load_scenario`); what each key means is said
beside it. It is the one source of every default and of every leaf's type (a
float default takes any finite number, an int an integral one, a list that many
numbers); the ranges and choices are the typed models' (:mod:`simpro_mj.config.models`).
It lives apart from them so that :mod:`simpro_mj.config.sweep` can check a
sweep's paths against it while :mod:`simpro_mj.config.scenario` counts a sweep
file's variants: imports run ``scenario -> sweep -> defaults``.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping

from simpro_mj.config.presets import DEFAULT_PRESET
from simpro_mj.plant.model_params import DEFAULT_MODEL_PARAMS
from simpro_mj.plant.sensors import DEFAULT_SENSORS

__all__ = ["DEFAULT_SCENARIO", "merge"]


def merge(base: Mapping, over: Mapping) -> dict:
    """Deep merge: a copy of ``base`` with ``over`` applied (mappings merge, others replace)."""
    out = copy.deepcopy(dict(base))
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


#: Every key of a scenario with its default. A file is merged over this tree.
DEFAULT_SCENARIO: dict = {
    # a name for the run (file stem if empty); letters, digits, '_', '-', '.'
    "name": "",
    # Unit of Y in the paper's eqs. (34)-(37) (controllers.design.READINGS):
    # "volts" (default: the joint potentiometer's signal, 10 V over the 500 mm
    # stroke = 20 V/m, as the rig reads it through the MF624, section 5) or
    # "metres". Sets the SI gains of the printed joint controllers, the paper's
    # design plants and the linear actuators' default coefficients
    # (docs/paper-notes.md, section 3).
    "paper_units": "volts",
    "description": "",
    "duration_s": 15.0,
    # seed of every random draw of the run (sensor noise)
    "seed": 1,
    "controller": {
        # joint_only (Fig. 15a) | task_space (Fig. 15b) | feedforward (the set-point
        # through the IK every 1 ms, the outer law adding a correction: docs/feedforward.md)
        "mode": "task_space",
        "outer": {
            "type": "I",  # I (eq. 22) | PI (section 4)
            # K * K_I per axis (roll, pitch, heave), 1/s: section 5.2.3's 3 (the
            # analysed limit on the default plant is 11.8; docs/paper-notes.md)
            "gains": [3.0, 3.0, 3.0],
            # c of the PI law T (z + c)/(z - 1), section 4; used with type PI only
            "pi_zero": 0.2,
            # discretisation of eq. (22)'s integral (I law): backward T z/(z - 1), the
            # newest error reaches q_d at once and Fig. 13's ramp filter spreads it over
            # T | forward T/(z - 1), Fig. 7 as printed (one more period of delay:
            # 23.8 % vs 8 % pitch overshoot at K K_I = 3; docs/paper-notes.md)
            "integrator": "backward",
            # outer sampling period T, an integer multiple of the 1 ms physics step
            "period_ms": 60,
            # inner loop as a delay in the analysis: 1 sample (60 ms, eq. 21) or 2
            "delay_samples": 1,
        },
        "inner": {
            # joint controllers: eqs. (36)-(37) printed | corrected | redesigned
            "variant": "corrected",
            "discretisation": "tustin",  # tustin | zoh
            # plant the joint controllers are designed on: "paper" (eqs. 34-35) or
            # "identified" (the model this simulation identifies, `simpro-sim identify`,
            # which is what the paper's procedure - identify, then place poles - gives)
            "design_plant": "paper",
            # with design_plant identified: "auto" identifies the scenario's own plant
            # when it is not its preset's (Fig. 12's experiment, cached by the plant's
            # hash: simpro_mj.identification.auto) | "preset": the identified models below as given
            "identify": "auto",
            # b / (s (s^2 + a1 s + a0)) per actuator, SI (m/V); set by the plant
            # preset (plant.preset: what `simpro-sim identify` measures on it);
            # the numbers here are the schema's only
            "identified": {
                "actuator1": {"b": 12.51, "a1": 15.78, "a0": 78.92},
                "actuator2": {"b": 95.66, "a1": 17.37, "a0": 467.7},
                "actuator3": {"b": 95.66, "a1": 17.37, "a0": 467.7},
            },
            # dominant pair of the "redesigned" pole placement (section 5.2.2)
            "zeta": 0.7,
            "wn_rad_s": 10.0,
        },
        # mode feedforward (docs/feedforward.md): the correction, with its own
        # K K_I per axis (it only removes what the joint loops leave: slower than
        # the paper's I law), integrates y_d - y less the joint loops' lag (lag),
        # with lag model: M y_d - y, M a first-order lag of model_tau_ms (0: y_d - y),
        # and skips an outer step after which a valve was at its rail
        # (hold_on_saturation)
        "feedforward": {
            "gains": [1.0, 1.0, 1.0],
            "model_tau_ms": 200.0,
            "hold_on_saturation": True,
            # the joint loops' lag taken out of the error: joints (measured:
            # J^-1 (q_d - q_meas)) | model (M y_d, above); average: the correction
            # uses the means over the outer period instead of one sample. Chosen by
            # measurement (docs/feedforward.md): the steady-state error after a step
            # below the sensor floor, overshoot 0.4 %
            "lag": "joints",
            "average": True,
            # leg velocity feed-forward (controllers.velocity_feedforward): a valve
            # voltage (a0/b) J dy_d/dt per leg from the set-point's rate and the
            # identified plants (controller.inner.identified), through the set-point
            # filter when there is one; clipped to the valve's 5 V span. Chosen by
            # measurement (docs/feedforward.md): phase at 1 Hz -40 -> -10 deg,
            # track_cues RMS error halved, steps unchanged
            "leg_velocity": True,
        },
        # Fig. 13's "Filter" between the outer loop (or the joint-only IK) and the
        # joint loops (controllers.setpoint_filter): ramp (the mean of q_d over
        # time_ms; with time_ms = T the 60 ms steps of q_d become ramps: no valve
        # kick) | first_order (time constant time_ms) | zero_cancel (k_i/(s + k_i),
        # eq. 29's zero) | none. Chosen by analysis: docs/paper-notes.md
        # time_ms per leg: T for leg 1; T/2 for legs 2-3, whose k_p (640 V/m) is 8.3
        # times leg 1's, so a 60 ms step of their q_d kicks their valves 8 times less
        # while their ramp's delay halves (step_roll overshoot 11.4 % -> 7.9 %)
        "setpoint_filter": {"type": "ramp", "time_ms": [60.0, 30.0, 30.0]},
        # unreachable set-points: reject at load time (false) or clamp (true)
        "clamp_setpoints": False,
    },
    "actuator": {
        "model": "nonlinear",  # nonlinear (Richer & Hurmuzlu) | linear (eq. 19)
        # overrides of simpro_mj.plant.pneumatics.params.DEFAULT_PNEUMATIC_PARAMS (values
        # are validated by the plant, keys here)
        "pneumatics": {},
    },
    # The as-built plant: simpro_mj.plant.model.DEFAULT_MODEL_PARAMS with as-built
    # errors. The errors are assumptions chosen so that joint-only control
    # shows a Fig. 15a-like steady-state error; the controller keeps the
    # nominal geometry.
    "plant": merge(
        DEFAULT_MODEL_PARAMS,
        {
            # a shipped preset (simpro_mj/config/presets: "paper", calibrated to eqs. 34-35;
            # "heavy_cabin", 250 kg) or a preset YAML path (`simpro-sim calibrate`);
            # its plant, actuator.pneumatics and controller.inner.identified values
            # lie under the scenario's own (simpro_mj.config.presets)
            "preset": DEFAULT_PRESET,
            "payload": {"com_mm": [60.0, 0.0, 400.0]},
            "anchor_offsets_mm": {
                "A1": [0.0, 0.0, 0.0],
                "A2": [3.0, 0.0, -2.0],
                "A3": [-2.0, 0.0, 2.5],
                "C1": [2.0, 0.0, 3.0],
                "B2": [-2.5, 0.0, 3.0],
                "B3": [2.0, 0.0, -1.5],
            },
            "guide": {"radius_offset_mm": 4.0, "centre_offset_mm": [3.0, -2.0]},
        },
    ),
    # simpro_mj.plant.sensors.DEFAULT_SENSORS (MF624 14-bit potentiometers, 10 um height
    # encoder, 200 Hz IMU) with as-built potentiometer calibration errors per leg
    # (assumption, like the plant's errors above)
    "sensors": merge(
        DEFAULT_SENSORS,
        {"potentiometer": {"offset_mm": [1.5, -1.0, 2.0], "gain_error_pct": [0.8, -0.6, 0.5]}},
    ),
    # per axis, a list of components summed on top of the home pose
    "setpoint": {"roll_deg": [], "pitch_deg": [], "heave_mm": []},
    # scheduled faults (see "Faults" in the module docstring and simpro_mj.plant.faults)
    "faults": [],
    "logging": {"decimation": 1},
}
