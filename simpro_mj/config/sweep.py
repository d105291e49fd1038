"""Sweeps: one scenario file, many variants (``simpro-sim batch``).

A scenario file may carry a ``sweep:`` block next to its scenario keys::

    sweep:
      grid:                          # cartesian product, first path slowest
        controller.outer.type: [I, PI]
        controller.outer.gains: [2, 4, 8]
      monte_carlo:
        samples: 20
        seed: 7                      # base seed of the draws (default 0)
        parameters:
          plant.payload.mass_kg: {distribution: uniform, low: 200, high: 300}
          sensors.potentiometer.offset_mm: {distribution: normal, mean: 0, std: 1.5}
          actuator.pneumatics.supply_pressure_bar_gauge:
            {distribution: normal, mean: 6, std: 0.2, low: 5.5, high: 6.5}

Rules
-----
* **Paths** are the dotted paths of ``--set`` (``controller.outer.gains``),
  checked against :data:`simpro_mj.config.models.DEFAULT_SCENARIO`; an
  unknown one is refused with the closest valid key. ``name`` and ``sweep``
  cannot be swept. The block itself is the typed :class:`Sweep` (pydantic:
  its numbers are the scenario's :data:`~simpro_mj.config.rules.Real`).
* **Grid**: every path maps to a non-empty list of values; the variants are
  the cartesian product in the order of the file (first path slowest). A
  number given where the scenario has a list of numbers (``gains``,
  per-leg offsets) applies to every element: ``gains: [2, 4]`` is
  ``[2, 2, 2]`` and ``[4, 4, 4]``; ``gains: [[1, 2, 3]]`` is one variant.
* **Monte Carlo**: ``samples`` draws of every listed parameter, crossed
  with the grid (each grid point sees the same ``samples`` plants: the
  comparison between grid points is paired). Distributions:

  - ``uniform``: ``low``, ``high`` (``low <= high``);
  - ``normal``: ``mean``, ``std >= 0``, optional ``low``/``high`` to clip;
  - ``choice``: ``values``, a non-empty list (drawn with equal weights).

  For a parameter whose default is a list of numbers the draw has the
  list's length, one independent value per element; the distribution's
  numbers may be scalars or lists of that length.
* **Seeds**: sample ``i`` of parameter ``p`` draws from
  ``numpy.random.default_rng(SeedSequence(seed, spawn_key=(i, crc32(p))))``,
  so a draw depends on neither the number of samples, nor the other
  parameters, nor the grid point. The scenario ``seed`` (sensor noise) of
  sample ``i`` is the variant's seed before the draw plus ``i``; grid-only
  variants keep the scenario's seed (same noise on every grid point).
* **Order of application** for one variant: defaults, the file, the
  command's ``--set`` overrides (the base of every variant), the grid
  values, the Monte Carlo draws and seed; then the usual resolution and
  validation (:func:`simpro_mj.config.scenario.resolve_scenario`). A variant that
  fails validation is reported on its own (``Variant.error``); a malformed
  ``sweep:`` block makes the whole file invalid.
* **Names** (the variant's folder): ``<label>=<value>`` per grid path
  joined by ``_`` (label: the shortest suffix of the path that tells the
  grid paths apart, e.g. ``type=PI_gains=4``), prefixed with ``mc007`` for
  Monte Carlo sample 7 (``mc007_mode=joint_only``); ``base`` when the file
  has no sweep. A list whose elements are equal is written as one number,
  others joined by ``,``; characters other than letters, digits and
  ``.,+=-_`` become ``-``; names over 80 characters are cut and end in a
  hash of the values; a repeated name gets ``_2``, ``_3``, ... The name
  depends only on the sweep block, so it is stable between runs.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import math
import re
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BeforeValidator,
    Field,
    TypeAdapter,
    ValidationError,
    ValidationInfo,
    model_validator,
)

from simpro_mj.config.cueing import sweep_defaults
from simpro_mj.config.messages import validated
from simpro_mj.config.models import DEFAULT_SCENARIO
from simpro_mj.config.rules import Entry
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import Block, Problem, Real, Whole, closest, key_text, param

_NOT_SWEPT = ("name", "sweep")
#: Most variants of one file (grid product times samples) and of one batch.
MAX_VARIANTS = 10_000
_MAX_SAMPLES = MAX_VARIANTS
_MAX_NAME = 80
_UNSAFE = re.compile(r"[^A-Za-z0-9.,+=_-]")
_REAL = TypeAdapter(Real)


# ------------------------------------------------------------------ spec


@dataclass(frozen=True)
class Distribution:
    """One Monte Carlo parameter: its ``draw`` (the distribution and its numbers, scalars
    or per-element lists) at the scenario value ``path``."""

    path: str
    draw: Uniform | Normal | Choice
    size: int | None  # None: scalar leaf; n: list of n numbers

    def sample(self, seed: int, index: int) -> Any:
        """The draw of sample ``index`` (reproducible, see the module docstring)."""
        key = (int(index), zlib.crc32(self.path.encode("utf-8")))
        rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=key))
        shape = None if self.size is None else (self.size,)
        d = self.draw
        if isinstance(d, Uniform):
            x = rng.uniform(d.low, d.high, size=shape)
        elif isinstance(d, Normal):
            x = rng.normal(d.mean, d.std, size=shape)
            if d.low is not None or d.high is not None:
                low = -np.inf if d.low is None else d.low
                x = np.clip(x, low, np.inf if d.high is None else d.high)
        else:  # choice: one pick per sample, whatever the leaf
            return copy.deepcopy(d.values[int(rng.integers(len(d.values)))])
        return float(x) if shape is None else [float(v) for v in np.atleast_1d(x)]


@dataclass(frozen=True)
class SweepSpec:
    """A validated ``sweep:`` block."""

    grid: dict = field(default_factory=dict)  # path -> list of values
    samples: int = 0  # 0: no Monte Carlo
    seed: int = 0
    parameters: tuple[Distribution, ...] = ()

    @property
    def count(self) -> int:
        """Number of variants."""
        n = math.prod(len(v) for v in self.grid.values())
        return n * (self.samples or 1)

    @property
    def paths(self) -> list[str]:
        """Swept paths: grid first, then Monte Carlo, in the file's order."""
        return list(self.grid) + [d.path for d in self.parameters]


def _defaults_at(path: str, where: str) -> Any:
    """The default value at a dotted scenario path; unknown keys name the closest one."""
    parts = path.split(".")
    if parts[0] in _NOT_SWEPT:
        raise UserInputError(
            f"invalid key at {where}: '{parts[0]}' cannot be swept; allowed: any other "
            "dotted scenario path such as controller.outer.gains"
        )
    node: Any = DEFAULT_SCENARIO
    done: list[str] = []
    for part in parts:
        if done == ["setpoint"] and part == "cueing":  # the washout parameters
            node = {"cueing": sweep_defaults()}
        if not isinstance(node, Mapping):
            raise UserInputError(
                f"unknown key at {where}: '{'.'.join(done)}' has no sub-keys; allowed: a dotted "
                "path ending at a scenario value"
            )
        if part not in node:
            raise UserInputError(
                f"unknown key at {where}: allowed keys at '{'.'.join(done) or 'top level'}' are "
                f"{sorted(node)}{closest(part, node)}"
            )
        node = node[part]
        done.append(part)
    return node


def broadcast_value(path: str, value: Any) -> Any:
    """The value a variant sets at ``path``: a copy of ``value``, or ``value`` repeated
    when the default there is a list of numbers and ``value`` one number (gains, per-leg
    offsets: see the module docstring)."""
    try:
        default = _defaults_at(path, path)
    except UserInputError:
        default = None  # reported by the validation of the variant
    n = _numeric_list_len(default)
    if n is not None and _is_number(value):
        return [value] * n
    return copy.deepcopy(value)


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _numeric_list_len(default: Any) -> int | None:
    if isinstance(default, list) and default and all(_is_number(v) for v in default):
        return len(default)
    return None


def _number_or_list(value: Any) -> Any:
    """A distribution's number: a finite number, or a list of them (its length is checked
    against the swept leaf once the path is known)."""
    try:
        if isinstance(value, list | tuple):
            return [_REAL.validate_python(v) for v in value]
        return _REAL.validate_python(value)
    except ValidationError:
        raise Problem.wrong_type(value, "a finite number or a list of them") from None


def _not_negative(value: Any) -> Any:
    if (
        _is_number(value)
        and value < 0
        or isinstance(value, list)
        and any(_is_number(v) and v < 0 for v in value)
    ):
        raise Problem.invalid(value, ">= 0")
    return value


Bound = Annotated[float | list[float], BeforeValidator(_number_or_list)]


class Uniform(Entry):
    """Uniform between ``low`` and ``high`` (``low <= high``)."""

    distribution: Literal["uniform"]
    low: Bound
    high: Bound


class Normal(Entry):
    """Normal of ``mean`` and ``std`` (>= 0), clipped to ``low``/``high`` when given."""

    distribution: Literal["normal"]
    mean: Bound
    std: Annotated[Bound, BeforeValidator(_not_negative)]
    low: Bound | None = None
    high: Bound | None = None


class Choice(Entry):
    """One of ``values``, with equal weights."""

    distribution: Literal["choice"]
    values: Annotated[list, Field(min_length=1)]


Draw = Annotated[Uniform | Normal | Choice, Field(discriminator="distribution")]


class MonteCarlo(Block):
    """``samples`` draws of every listed parameter, crossed with the grid."""

    samples: Whole = Field(ge=1, le=_MAX_SAMPLES, description="draws of every parameter")
    seed: Whole = param(0, "", "base seed of the draws", ge=0, le=2**63 - 1)
    parameters: Annotated[dict[str, Draw], Field(min_length=1)]


class Sweep(Block):
    """A ``sweep:`` block: a grid (dotted path -> values) and/or Monte Carlo draws."""

    grid: dict[str, Annotated[list, Field(min_length=1)]] = param({}, "", "path -> values")
    monte_carlo: MonteCarlo | None = None

    @model_validator(mode="after")
    def _paths(self, info: ValidationInfo):
        """Every path a scenario value, in one of grid or monte_carlo; sizes; the count."""
        where = (info.context or {}).get("where", "sweep")
        if not self.grid and self.monte_carlo is None:
            raise UserInputError(
                f"missing key at {where}: allowed: a non-empty 'grid' and/or 'monte_carlo'"
            )
        for path in self.grid:
            here = f"{where}.grid.{key_text(path)}"
            _defaults_at(_checked_path(path, here), here)
        for path, draw in (self.monte_carlo.parameters if self.monte_carlo else {}).items():
            here = f"{where}.monte_carlo.parameters.{key_text(path)}"
            _checked_path(path, here)
            if path in self.grid:
                raise UserInputError(
                    f"invalid key at {here}: also swept in {where}.grid; allowed: each path "
                    "in one of grid or monte_carlo"
                )
            _check_draw(path, draw, here)
        return self


def _checked_path(path: str, where: str) -> str:
    if not path or any(not p for p in path.split(".")):
        raise UserInputError(
            f"invalid key at {where}: {path!r}; allowed: a dotted path like controller.outer.gains"
        )
    return path


def _check_draw(path: str, draw: Entry, where: str) -> None:
    """A draw's numbers against the swept leaf: scalars, or lists of the leaf's length."""
    size = _numeric_list_len(_defaults_at(path, where))
    for key in ("low", "high", "mean", "std"):
        value = getattr(draw, key, None)
        if isinstance(value, list) and (size is None or len(value) != size):
            n = "a number" if size is None else f"a number or a list of {size} numbers"
            raise UserInputError(
                f"wrong type at {where}.{key}: got a list of {len(value)}; allowed: {n}"
            )
    low, high = getattr(draw, "low", None), getattr(draw, "high", None)
    if low is not None and high is not None and np.any(np.asarray(low) > np.asarray(high)):
        raise UserInputError(f"invalid value at {where}.high: {high!r}; allowed: >= low ({low!r})")


def parse_sweep(block: Any, where: str = "sweep") -> SweepSpec:
    """Validate a ``sweep:`` block (:class:`Sweep`).

    Parameters
    ----------
    block : any
        The block as read from YAML.
    where : str
        Dotted prefix of the error messages.

    Returns
    -------
    SweepSpec

    Raises
    ------
    UserInputError
        ``<what> at sweep.<...>: <what is allowed>`` for the first problem.
    """
    sweep = validated(Sweep, block, where, context={"where": where})
    mc = sweep.monte_carlo
    params = tuple(
        Distribution(path=p, draw=d, size=_numeric_list_len(_defaults_at(p, p)))
        for p, d in (mc.parameters if mc else {}).items()
    )
    spec = SweepSpec(
        grid=copy.deepcopy(sweep.grid),
        samples=mc.samples if mc else 0,
        seed=mc.seed if mc else 0,
        parameters=params,
    )
    if spec.count > MAX_VARIANTS:  # counted, not expanded
        factors = [str(len(v)) for v in spec.grid.values()] + ([str(spec.samples)] if mc else [])
        raise UserInputError(
            f"too many variants at {where}: {' x '.join(factors)} = {spec.count:,}; allowed: "
            f"at most {MAX_VARIANTS:,} variants per file"
        )
    return spec


# ------------------------------------------------------------------ names


def _fmt_number(x: float) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def format_value(value: Any) -> str:
    """Compact text of a swept value (names and ``summary.csv``).

    Numbers as ``%g``, a list of equal numbers as that number, other lists
    joined by ``,`` (``1,2,3``), booleans ``true``/``false``.
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    if _is_number(value):
        return _fmt_number(value)
    if isinstance(value, (list, tuple)):
        if value and all(_is_number(v) for v in value) and len(set(value)) == 1:
            return _fmt_number(value[0])
        return ",".join(format_value(v) for v in value)
    if isinstance(value, Mapping):
        return ",".join(f"{k}={format_value(v)}" for k, v in value.items())
    return str(value)


def _labels(paths: list[str]) -> dict[str, str]:
    """Shortest dotted suffix of each path that is unique among ``paths``."""
    out = {}
    for path in paths:
        parts = path.split(".")
        for k in range(1, len(parts) + 1):
            label = ".".join(parts[-k:])
            if not any(o != path and (o == label or o.endswith("." + label)) for o in paths):
                break
        out[path] = label
    return out


def _name(parts: list[str]) -> str:
    name = _UNSAFE.sub("-", "_".join(parts)) or "base"
    if len(name) > _MAX_NAME:
        digest = hashlib.sha1(name.encode("utf-8")).hexdigest()[:8]
        name = f"{name[: _MAX_NAME - 9]}-{digest}"
    return name


# ------------------------------------------------------------------ expansion


@dataclass(frozen=True)
class Point:
    """One variant before resolution: folder name, values to apply, MC sample."""

    name: str
    values: dict  # path -> value as declared (grid) or drawn (Monte Carlo)
    sample: int | None


def draw(spec: SweepSpec, index: int) -> dict:
    """Values of Monte Carlo sample ``index`` (path -> value)."""
    return {d.path: d.sample(spec.seed, index) for d in spec.parameters}


def expand(spec: SweepSpec | None) -> list[Point]:
    """All variants of a sweep, grid-major (the grid's first path slowest), then samples."""
    if spec is None or spec.count == 0:
        return [Point("base", {}, None)]
    labels = _labels(list(spec.grid))
    combos = list(itertools.product(*spec.grid.values())) if spec.grid else [()]
    samples = range(spec.samples) if spec.samples else [None]
    width = max(3, len(str(max(spec.samples - 1, 0))))
    out: list[Point] = []
    seen: dict[str, int] = {}
    for combo in combos:
        gvals = dict(zip(spec.grid, combo, strict=True))
        glabel = [f"{labels[p]}={format_value(v)}" for p, v in gvals.items()]
        for i in samples:
            values = dict(gvals)
            parts = list(glabel)
            if i is not None:
                values.update(draw(spec, i))
                parts.insert(0, f"mc{i:0{width}d}")
            name = _name(parts)
            n = seen.get(name, 0) + 1
            seen[name] = n
            if n > 1:
                name = f"{name}_{n}"
            out.append(Point(name, values, i))
    return out
