"""A sweep file's variants, resolved (``simpro-sim batch``).

:func:`load_sweep` reads a scenario file, expands its ``sweep:`` block
(:mod:`simpro_mj.config.sweep`: the block's rules, counting, names) and resolves
every variant (:func:`simpro_mj.config.scenario.resolve_scenario`). It lives above
both so that imports run one way: ``variants -> scenario -> sweep``
(:func:`simpro_mj.config.scenario.load_scenario` counts a file's variants for its
note; the sweep's paths are checked against the scenario's defaults in
:data:`simpro_mj.config.models.DEFAULT_SCENARIO`).
"""

from __future__ import annotations

import copy
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from simpro_mj.config.models import DEFAULT_SCENARIO
from simpro_mj.config.models import merge as _merge
from simpro_mj.config.presets import scenario_overlay
from simpro_mj.config.scenario import _set, read_document, resolve_scenario
from simpro_mj.config.sweep import SweepSpec, _is_number, broadcast_value, expand, parse_sweep
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import parse_set
from simpro_mj.core.messages import one_line


@dataclass
class Variant:
    """One resolved variant of a scenario file.

    ``scenario`` is the resolved scenario (plain JSON data, what a worker
    runs) or ``None`` with ``error`` the one-line reason it is invalid.
    """

    file: str
    scenario_name: str
    name: str
    values: dict
    sample: int | None
    seed: int | None
    scenario: dict | None
    error: str | None = None


@dataclass
class SweepFile:
    """A scenario file and its variants (``error``: the file itself is invalid)."""

    path: str
    scenario_name: str
    spec: SweepSpec | None
    variants: list[Variant]
    error: str | None = None


def load_sweep(name_or_path: str | Path, sets: Iterable[str] = ()) -> SweepFile:
    """Read a scenario file and expand its ``sweep:`` block into resolved variants.

    Parameters
    ----------
    name_or_path : str or Path
        A YAML path or a shipped scenario name (as :func:`simpro_mj.config.scenario.load_scenario`).
    sets : iterable of str
        ``KEY=VALUE`` overrides applied to the base of every variant.

    Returns
    -------
    SweepFile
        ``variants`` in expansion order; a variant that fails validation has
        ``scenario=None`` and its reason in ``error``.

    Raises
    ------
    UserInputError
        The file cannot be found or read, is not a mapping, its ``sweep:``
        block is malformed, or a ``--set`` is malformed.
    """
    path, doc = read_document(str(name_or_path))
    doc = dict(doc)
    block = doc.pop("sweep", None)
    spec = parse_sweep(block) if block is not None else None
    defaults = DEFAULT_SCENARIO
    preset = (_merge(DEFAULT_SCENARIO, doc).get("plant") or {}).get("preset")
    if isinstance(preset, str):
        # the preset lies between the defaults and the file, as in resolve_scenario;
        # merging the bare defaults first would pin the preset's keys to them
        try:
            defaults = _merge(DEFAULT_SCENARIO, scenario_overlay(preset))
        except UserInputError:
            pass  # an unknown preset: resolve_scenario reports it for each variant
    base = _merge(defaults, doc)
    for expr in sets or ():
        key, value = parse_set(expr)
        _set(base, key, value)
    sname = str(base.get("name") or path.stem)
    base_seed = base.get("seed")
    variants = []
    for point in expand(spec):
        tree = copy.deepcopy(base)
        for p, v in point.values.items():
            _set(tree, p, broadcast_value(p, v))
        if point.sample is not None and _is_number(tree.get("seed")):
            tree["seed"] = int(tree["seed"]) + point.sample
        seed = tree.get("seed") if _is_number(tree.get("seed")) else base_seed
        try:
            resolved = resolve_scenario(tree, (), default_name=path.stem, base=path.parent)
            error = None
        except UserInputError as exc:
            resolved, error = None, one_line(exc)
        variants.append(
            Variant(
                file=str(path),
                scenario_name=sname,
                name=point.name,
                values=point.values,
                sample=point.sample,
                seed=seed,
                scenario=resolved,
                error=error,
            )
        )
    return SweepFile(path=str(path), scenario_name=sname, spec=spec, variants=variants)
