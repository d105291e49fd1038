"""The settings of ``simpro-sim identify`` and their checks, without MuJoCo or SciPy.

The experiment itself (:mod:`simpro_mj.identification.identify`) loads MuJoCo
and SciPy; the tree it runs on is built and checked here, so that a command
refuses a mistyped ``--start``, ``--preset`` or ``--set`` within a second,
before either is imported.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Annotated, Any

import numpy as np
from pydantic import AfterValidator, ConfigDict, ValidationError
from pydantic.dataclasses import dataclass as pydantic_dataclass

from controllers.design import READINGS
from simpro_mj.config.messages import user_error, validated
from simpro_mj.config.models import merge as _merge
from simpro_mj.config.presets import DEFAULT_PRESET, load_preset
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import Problem, Real, Whole, param
from simpro_mj.plant.model_params import DEFAULT_MODEL_PARAMS
from simpro_mj.plant.pneumatics.params import DEFAULT_PNEUMATIC_PARAMS, Pneumatics
from simpro_mj.plant.pneumatics.parts import Legs, PerLeg

#: The values of ``identify.excitation`` (:data:`DEFAULT_IDENTIFY_PARAMS`).
EXCITATIONS = ("one_leg", "all_legs")
#: The values of ``identify.fit_method``: the fit's solver
#: (:func:`simpro_mj.identification.identify.fit_eq19`).
FIT_METHODS = ("trust_region", "levenberg_marquardt")


def _one_of(*choices: str) -> Any:
    def check(value: str) -> str:
        if value not in choices:
            raise Problem.invalid(value, ", ".join(choices))
        return value

    return AfterValidator(check)


_LEGS = "a number or 3 numbers >= 0"


@pydantic_dataclass(frozen=True, config=ConfigDict(extra="forbid"))
class Settings:
    """The experiment's settings, ``identify.*`` of the tree (the paper does not print
    them: our choices); :data:`DEFAULT_IDENTIFY_PARAMS` is the defaults' dict.

    The P gains are low enough for the loop to stay stable with the paper's plants
    too (eq. 35 needs K_p b < a1 a0: K_p < 4.9 V/m). A 20 ms PRBS clock gives a flat
    spectrum up to ~ 0.44/20 ms = 22 Hz (> the 2.5-6 Hz of omega_n). A run identifies
    its plant with its own joint loops' dither (plant_tree), so that the model is of
    the plant the loops drive. ``all_legs`` excites the three legs at once, each its
    own shift of the sequence (a third of its period apart: uncorrelated), one record.
    The Levenberg-Marquardt fit (identify.levenberg_marquardt) finds the same minimum
    within 0.5 % in about half the CPU; not the default: docs there.
    """

    duration_s: Real = param(20.0, "s", "excitation time per actuator", ge=0.5, le=3600.0)
    settle_s: Real = param(1.0, "s", "P loops alone before the PRBS starts", ge=0.0, le=3600.0)
    position_mm: Real = param(250.0, "mm", "operating point: mid-stroke", ge=50.0, le=450.0)
    kp_v_per_m: Annotated[PerLeg, Legs(ge=0.0)] = param(
        [15.0, 3.0, 3.0], "V/m", "P gain of each leg's loop", why=_LEGS
    )
    prbs_amplitude_v: Annotated[PerLeg, Legs(ge=0.0, le=5.0)] = param(
        [0.3, 0.3, 0.3], "V", "+-amplitude on the excited valve", why="the valve's half range"
    )
    prbs_clock_ms: Real = param(20.0, "ms", "one PRBS bit per clock", ge=1.0, le=1e6)
    prbs_bits: Whole = param(10, "", "register length, an integer (10: 1023 bits)", ge=2, le=24)
    dither_v: Real = param(0.0, "V", "the valves' dither (controllers.dither); 0: none", ge=0.0,
                           le=5.0)  # fmt: skip
    dither_period_ms: Real = param(40.0, "ms", "the dither's period", ge=2.0, le=1e6)
    seed: Whole = param(1, "", "shift of the sequence", ge=0, le=2**31)
    excitation: Annotated[str, _one_of(*EXCITATIONS)] = param(
        "one_leg", "", "one_leg: each leg in turn, the others held (Fig. 12); all_legs"
    )
    actuator_kind: str = "nonlinear"
    fit_skip_s: Real = param(0.2, "s", "the record's start left out of the fit", ge=0.0)
    fit_method: Annotated[str, _one_of(*FIT_METHODS)] = param(
        "trust_region", "", "the fit's solver: scipy's bounded trust region or ours"
    )
    loop_bound_mm: Real = param(1.0, "mm", "loop-closure bound checked in the run", gt=0.0)

    def __post_init__(self) -> None:
        """The rules across the keys and on the 1 ms grid."""
        if self.prbs_clock_ms != round(self.prbs_clock_ms):
            rest = "a positive integer multiple of the 1 ms physics step"
            raise Problem.invalid(self.prbs_clock_ms, rest, ".prbs_clock_ms")
        if self.fit_skip_s >= self.duration_s:
            rest = f">= 0 s and < {self.duration_s:g} s (identify.duration_s)"
            raise Problem.invalid(self.fit_skip_s, rest, ".fit_skip_s")
        period = self.dither_period_ms
        if period != round(period) or round(period) % 2:
            rest = "an even number of 1 ms physics steps"
            raise Problem.invalid(period, rest, ".dither_period_ms")

    @classmethod
    def of(cls, tree: dict) -> Settings:
        """The settings of an identify tree, checked (one line naming the key)."""
        try:
            return cls(**tree["identify"])
        except ValidationError as exc:
            raise user_error(exc, cls, "identify") from None


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
    s = Settings.of(tree)
    return Experiment(model, pneumatics, s, units, tree.get("preset"))
