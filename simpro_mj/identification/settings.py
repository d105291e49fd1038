"""The settings of ``simpro-sim identify`` and their checks, without MuJoCo or SciPy.

The experiment itself (:mod:`simpro_mj.identification.identify`) loads MuJoCo
and SciPy; the tree it runs on is built and checked here, so that a command
refuses a mistyped ``--start``, ``--preset`` or ``--set`` within a second,
before either is imported.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from controllers.design import READINGS
from simpro_mj.config.messages import validated
from simpro_mj.config.models import merge as _merge
from simpro_mj.config.presets import DEFAULT_PRESET, load_preset
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import check_number
from simpro_mj.plant.model_params import DEFAULT_MODEL_PARAMS
from simpro_mj.plant.pneumatics.params import DEFAULT_PNEUMATIC_PARAMS, Pneumatics

__all__ = [
    "DEFAULT_IDENTIFY_PARAMS",
    "Settings",
    "EXCITATIONS",
    "FIT_METHODS",
    "Experiment",
    "default_tree",
    "check_tree",
    "leg_values",
]

#: The values of ``identify.excitation`` (:data:`DEFAULT_IDENTIFY_PARAMS`).
EXCITATIONS = ("one_leg", "all_legs")
#: The values of ``identify.fit_method``: the fit's solver
#: (:func:`simpro_mj.identification.identify.fit_eq19`).
FIT_METHODS = ("trust_region", "levenberg_marquardt")


@dataclass(frozen=True)
class Settings:
    """The experiment's settings, ``identify.*`` of the tree (the paper does not print
    them: our choices); :data:`DEFAULT_IDENTIFY_PARAMS` is the defaults' dict."""

    duration_s: float = 20.0  # excitation time per actuator
    settle_s: float = 1.0  # P loops alone before the PRBS starts
    position_mm: float = 250.0  # operating point: mid-stroke
    # P gains (V/m). Low enough for the loop to stay stable with the paper's
    # plants too (eq. 35 needs K_p b < a1 a0: K_p < 4.9 V/m).
    kp_v_per_m: Any = field(default_factory=lambda: [15.0, 3.0, 3.0])
    # PRBS: ±amplitude on the excited valve, one bit per clock; a 20 ms clock
    # gives a flat spectrum up to ~ 0.44/20 ms = 22 Hz (> the 2.5-6 Hz of ω_n)
    prbs_amplitude_v: Any = field(default_factory=lambda: [0.3, 0.3, 0.3])
    prbs_clock_ms: float = 20.0
    prbs_bits: int = 10  # sequence period 1023 bits = 20.5 s
    # the valves' dither during the experiment (controllers.dither), V and ms: a run
    # identifies its plant with its own joint loops' dither (plant_tree), so that the
    # model is of the plant the loops drive; 0: none
    dither_v: float = 0.0
    dither_period_ms: float = 40.0
    seed: int = 1  # shift of the sequence
    # one_leg: each leg in turn, the others held (the paper's Fig. 12: three records);
    # all_legs: the three at once, each its own shift of the sequence (a third of the
    # sequence's period apart: uncorrelated), one record
    excitation: str = "one_leg"
    actuator_kind: str = "nonlinear"
    # discard the first part of the record in the fit (initial transient), s
    fit_skip_s: float = 0.2
    # the fit's solver (FIT_METHODS): scipy's bounded trust region, or our
    # Levenberg-Marquardt (identify.levenberg_marquardt: the same minimum within
    # 0.5 %, about half the CPU; not the default: docs there)
    fit_method: str = "trust_region"
    # loop-closure bound checked during the run, mm
    loop_bound_mm: float = 1.0

    @classmethod
    def of(cls, tree: dict) -> Settings:
        """The settings of an identify tree (its keys are the fields: ``--set`` and
        the presets refuse any other)."""
        return cls(**tree["identify"])


#: The experiment's default settings as the tree's ``identify`` block.
DEFAULT_IDENTIFY_PARAMS: dict = asdict(Settings())


@dataclass(frozen=True)
class Experiment:
    """A checked identify tree (:func:`check_tree`): the plant's ``model`` and
    ``pneumatics`` parameter trees (as :func:`simpro_mj.plant.model.load_model` and
    :func:`simpro_mj.plant.pneumatics.factory.make_actuators` read them), the
    experiment's ``settings``, the reading ``paper_units`` under which eqs. (34)-(35)
    are compared and the plant's ``preset``. A changed copy
    (``dataclasses.replace``) is checked again where it runs."""

    model: dict
    pneumatics: dict
    settings: Settings
    paper_units: str
    preset: Any = None

    def tree(self) -> dict:
        """The tree this record checks (:func:`default_tree`'s form)."""
        return {"paper_units": self.paper_units, "preset": self.preset, "model": self.model,
                "pneumatics": self.pneumatics, "identify": asdict(self.settings)}  # fmt: skip


def default_tree(preset: str | None = None) -> dict:
    """The full parameter tree of ``identify``: paper_units, preset, model, pneumatics,
    identify; the model and pneumatics are the defaults with ``preset``'s values
    (default :data:`simpro_mj.config.presets.DEFAULT_PRESET`) over them."""

    preset = DEFAULT_PRESET if preset is None else preset
    p = load_preset(preset)
    # the joint loops' valve dither, under which the experiment identifies the plant
    inner = p.controller.get("inner") or {}
    dither = {k: float(v) for k, v in inner.items() if k in ("dither_v", "dither_period_ms")}
    return {
        # unit of Y in eqs. (34)-(35) for the comparison (controllers.design.READINGS)
        "paper_units": "volts",
        "preset": preset,
        "model": _merge(DEFAULT_MODEL_PARAMS, p.plant),
        "pneumatics": _merge(DEFAULT_PNEUMATIC_PARAMS, p.pneumatics),
        "identify": _merge(DEFAULT_IDENTIFY_PARAMS, dither),
    }


def leg_values(x, name: str) -> np.ndarray:
    arr = np.asarray(x, float)
    arr = np.full(3, arr) if arr.ndim == 0 else arr
    if arr.shape != (3,) or not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise UserInputError(
            f"invalid value at identify.{name}: {x!r}; expected a number or 3 numbers >= 0"
        )
    return arr


def check_tree(tree: dict | Experiment) -> Experiment:
    """Validate the ``identify`` settings and the pneumatics tree (the model's
    values are checked by :func:`simpro_mj.plant.model.load_model`); normalise
    ``tree``'s pneumatics in place and return its :class:`Experiment`.

    Raises
    ------
    UserInputError
        Naming the dotted path and what is allowed.
    """
    if isinstance(tree, Experiment):
        tree = tree.tree()
    units = tree.get("paper_units")
    if units not in READINGS:
        raise UserInputError(f"invalid value at paper_units: {units!r}; allowed: {list(READINGS)}")
    model = tree["model"]
    model.pop("preset", None)
    pneumatics = validated(Pneumatics, tree["pneumatics"], "pneumatics").model_dump()
    tree["pneumatics"] = pneumatics
    i, s = "identify", Settings.of(tree)
    check_number(tree, f"{i}.duration_s", 0.5, 3600.0, unit=" s")
    check_number(tree, f"{i}.settle_s", 0.0, 3600.0, unit=" s")
    check_number(tree, f"{i}.position_mm", 50.0, 450.0, unit=" mm")
    ms = check_number(tree, f"{i}.prbs_clock_ms", 1.0, 10**6, unit=" ms")
    if ms != round(ms):
        raise UserInputError(
            f"invalid value at {i}.prbs_clock_ms: {ms:g}; allowed: a positive integer "
            "multiple of the 1 ms physics step"
        )
    check_number(tree, f"{i}.prbs_bits", 2, 24, integer=True)
    check_number(tree, f"{i}.seed", 0, 2**31, integer=True)
    for key, choices in (("excitation", EXCITATIONS), ("fit_method", FIT_METHODS)):
        if (value := getattr(s, key)) not in choices:
            allowed = ", ".join(choices)
            raise UserInputError(f"invalid value at {i}.{key}: {value!r}; allowed: {allowed}")
    check_number(tree, f"{i}.fit_skip_s", 0.0, s.duration_s, hi_open=True, unit=" s")
    check_number(tree, f"{i}.loop_bound_mm", 0.0, lo_open=True, unit=" mm")
    if np.any(leg_values(s.prbs_amplitude_v, "prbs_amplitude_v") > 5.0):
        raise UserInputError(
            f"invalid value at {i}.prbs_amplitude_v: {s.prbs_amplitude_v!r}; "
            "allowed: <= 5 V (the valve's half range)"
        )
    leg_values(s.kp_v_per_m, "kp_v_per_m")
    check_number(tree, f"{i}.dither_v", 0.0, 5.0, unit=" V")
    period = check_number(tree, f"{i}.dither_period_ms", 2.0, 10**6, unit=" ms")
    if period != round(period) or round(period) % 2:
        raise UserInputError(
            f"invalid value at {i}.dither_period_ms: {period:g}; allowed: an even number of "
            "1 ms physics steps"
        )
    return Experiment(model, pneumatics, s, units, tree.get("preset"))
