"""The identified models of a scenario's own plant (``design_plant: identified``).

A plant preset (:mod:`simpro_mj.config.presets`) carries the models ``simpro-sim
identify`` measures on *its* plant (``controller.inner.identified``). A
scenario that changes the plant (a heavier payload, another valve, more
friction: ``plant.*`` or ``actuator.pneumatics.*``) makes them stale. With
``controller.inner.design_plant: identified`` the joint controllers are placed
on the identified models — the paper's procedure, identify then place poles —
so they must be the scenario's own: :func:`identified_models` runs Fig. 12's
experiment (:func:`simpro_mj.identification.identify.identify`) on the scenario's plant and
caches the result under the hash of everything the experiment depends on.

Which models a scenario uses (:func:`identified_models`):

* ``controller.inner.identify: auto`` (default): the preset's models when the
  scenario's plant is the preset's (no experiment), else the scenario's own,
  identified once and cached;
* ``preset``: the preset's models (or the scenario's ``controller.inner.identified``)
  as given, even for a changed plant.
* ``reduced``: as ``auto``, the experiment stepped on the chain reduced to the
  slides at its operating point with the step's own pneumatics and MuJoCo's
  friction rows (:mod:`simpro_mj.identification.reduced_experiment`: the
  stick-slip kept, its fits within the experiment's seed spread, about a twentieth
  of its stepping), cached apart from the experiment's;
* ``linearised``: the experiment's linear model
  (:mod:`simpro_mj.identification.linearised`), refused where the seals stick.

The cache is a folder of small JSON files, one per plant hash (the plant's
parameters, the MJCF's bytes, the sources that identify; a damaged file is said
in one line and identified again):
``$SIMPRO_CACHE_DIR``, else ``$XDG_CACHE_HOME/simpro-sim``, else
``~/.cache/simpro-sim``, sub-folder ``identified``. A file is written under a
temporary name and renamed, so concurrent runs (a batch) never read half a
file; an unwritable cache only costs the experiment again.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import threading
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np

from simpro_mj.config.models import DEFAULT_SCENARIO, Identified, Scenario, as_scenario
from simpro_mj.config.models import merge as _merge
from simpro_mj.config.presets import scenario_overlay
from simpro_mj.config.rules import IDENTIFY_CHOICES  # values of controller.inner.identify
from simpro_mj.core import cache, notices
from simpro_mj.core.shipped import model_digest
from simpro_mj.identification import identify as identify_module
from simpro_mj.identification.settings import Settings

__all__ = [
    "IDENTIFY_CHOICES",
    "cache_dir",
    "plant_tree",
    "plant_hash",
    "identified_models",
    "experiment_s",
    "with_identified",
]

_ACTS = ("actuator1", "actuator2", "actuator3")

_memo: dict[str, dict] = {}
_locks: dict[str, threading.Lock] = {}
_locks_lock = threading.Lock()


def _lock_of(h: str) -> threading.Lock:
    with _locks_lock:
        return _locks.setdefault(h, threading.Lock())


def cache_dir() -> Path:
    """The folder of cached identifications (module docstring)."""
    return cache.cache_dir("identified")


def plant_tree(scenario: Scenario | Mapping) -> dict:
    """The ``identify`` tree of the scenario's own plant: its preset's experiment
    settings (its 20 s record: a 5.1 s one leaves the 450/750 N cabin in a limit
    cycle, docs/paper-notes.md), the scenario's ``plant`` and ``actuator.pneumatics``
    values."""
    sc = as_scenario(scenario)
    inner = sc.controller.inner
    own = {
        "model": sc.plant.model_dump(exclude={"preset"}),
        "pneumatics": sc.actuator.pneumatics.model_dump(),
        "paper_units": sc.paper_units,
        # the plant as the joint loops drive it: with their valve dither (controllers.dither)
        "identify": {"dither_v": float(inner.dither_v),
                     "dither_period_ms": float(inner.dither_period_ms)},
    }  # fmt: skip
    return _merge(identify_module.default_tree(sc.plant.preset), own)


@lru_cache(maxsize=1)
def _code() -> str:
    """Digest of the sources the experiment runs: the identification, the plant, the
    joint design and the 1 ms step with the experiment's law (read as files)."""
    import controllers.design
    import controllers.experiment_law
    import controllers.step_functions

    here = Path(__file__).parent
    files = [*here.glob("*.py"), *(here.parent / "plant").rglob("*.py")]
    files += [
        Path(controllers.design.__file__),
        Path(controllers.experiment_law.__file__),
        Path(controllers.step_functions.__file__),
        here.parent / "sim" / "step.py",
    ]
    return cache.source_digest(files)


def plant_hash(tree: Mapping) -> str:
    """SHA-256 of what the experiment depends on: model parameters, the MJCF's bytes,
    pneumatics, identify settings, the sources that compute it and the versions of
    MuJoCo and NumPy."""

    key = {
        "model": tree["model"],
        "mjcf": model_digest(),
        "pneumatics": tree["pneumatics"],
        "identify": tree["identify"],
        "code": _code(),
        "versions": [mujoco.__version__, np.__version__],
    }
    text = json.dumps(key, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _is_presets_plant(sc: Scenario) -> bool:
    """The scenario's plant and pneumatics are what its preset resolves to with no
    plant key of the scenario's own (the shipped as-built errors included): the
    preset's models stand for it."""
    own = _plant_text(sc.plant.model_dump(), sc.actuator.pneumatics.model_dump())
    return own == _preset_plant(sc.plant.preset)


def _plant_text(plant, pneumatics) -> str:
    return json.dumps([plant, pneumatics or {}], sort_keys=True, default=str)


def _preset_plant(preset: str) -> str:
    """The plant and pneumatics a scenario with no plant key of its own gets from
    ``preset``, as text. Read every time: a tree kept for the process would keep the
    defaults it was merged with (a test's patch, say) after they change."""
    base = _merge(DEFAULT_SCENARIO, scenario_overlay(preset))
    base["plant"]["preset"] = preset
    return _plant_text(base["plant"], base["actuator"].get("pneumatics"))


def _models(doc) -> dict:
    """The three identified models of a cache file; ``KeyError``, ``TypeError`` or
    ``ValueError`` (a non-finite number) for anything else."""
    out = {a: {k: float(doc[a][k]) for k in ("b", "a1", "a0")} for a in _ACTS}
    if not all(math.isfinite(v) for m in out.values() for v in m.values()):
        raise ValueError("a number that is not finite")
    return out


def _read(path: Path) -> dict | None:
    """The cached models, or None: missing, or damaged (said; identified again)."""
    return cache.read_json(path, _models)


def identified_models(scenario: Scenario | Mapping, progress=None) -> tuple[dict, str]:
    """``({actuator: {b, a1, a0}}, source)`` for the scenario (module docstring).

    ``source`` is ``"preset"`` (the scenario's ``controller.inner.identified``), ``"linearised"``
    (the model's linearisation, :mod:`simpro_mj.identification.linearised`),
    ``"reduced"`` (the reduced experiment, run now or cached), ``"cache"`` or
    ``"identified"`` (the experiment ran now). ``progress``, when given, is called
    with a one-line message before an experiment.
    """
    sc = as_scenario(scenario)
    inner = sc.controller.inner
    given = inner.identified.model_dump()
    if inner.identify == "preset":
        return given, "preset"
    if inner.identify == "linearised":  # the model's own, no experiment
        from simpro_mj.identification.linearised import linearise

        got = linearise(plant_tree(sc))
        return {a: {k: float(got[a][k]) for k in ("b", "a1", "a0")} for a in _ACTS}, "linearised"
    if _is_presets_plant(sc):
        return given, "preset"
    tree = plant_tree(sc)
    h = plant_hash(tree)
    reduced = inner.identify == "reduced"
    if reduced:  # another model of the experiment: cached apart
        h = hashlib.sha256(f"reduced:{h}".encode()).hexdigest()
    # one experiment per plant in this process: a batch's threads that need the same
    # new plant wait for the first instead of running it again
    with _lock_of(h):
        if h in _memo:
            return copy.deepcopy(_memo[h]), "reduced" if reduced else "cache"
        path = cache_dir() / f"{h}.json"
        models = _read(path)
        source = "reduced" if reduced else "cache"
        if models is None and reduced:
            from simpro_mj.identification.reduced_experiment import identify_reduced

            notices.phase("identifying")
            got = identify_reduced(tree)
            models = {a: got[a].model() for a in _ACTS}
            cache.write_json(path, models)
        elif models is None:
            # in a batch, said once with the number of variants (simpro_mj.core.notices)
            notices.say(
                f"identifying the scenario's own plant (Fig. 12), cached in {path.parent}",
                progress,
            )
            notices.phase("identifying")
            got = identify_module.identify(tree)  # by attribute: tests replace it
            models = {a: got[a].model() for a in _ACTS}
            cache.write_json(path, models)
            source = "identified"
        _memo[h] = copy.deepcopy(models)
    return models, source


def experiment_s(scenario: Scenario | Mapping) -> float:
    """Simulated seconds of the experiment :func:`with_identified` would run for the
    scenario now: 0 when it needs none (not ``design_plant: identified``, the preset's
    plant, ``identify: preset``, or the plant's models in the cache), else per record
    (three, or one with ``identify.excitation: all_legs``) the settling time and the
    excitation."""
    sc = as_scenario(scenario)
    inner = sc.controller.inner
    if inner.design_plant != "identified" or inner.identify != "auto":
        return 0.0
    if _is_presets_plant(sc):
        return 0.0
    tree = plant_tree(sc)
    h = plant_hash(tree)
    if h in _memo or (cache_dir() / f"{h}.json").is_file():
        return 0.0
    ip = Settings.of(tree)
    records = 1.0 if ip.excitation == "all_legs" else 3.0  # one run, or one a leg
    return records * (float(ip.settle_s) + float(ip.duration_s))


def with_identified(scenario: Scenario | Mapping, progress=None) -> tuple[Scenario | Mapping, str]:
    """The scenario with ``controller.inner.identified`` its own plant's models when
    ``design_plant: identified`` (:func:`identified_models`); ``(scenario, source)``.
    Other scenarios come back as they are, ``source`` ``"preset"``: with the
    paper's design plants the identified models only linearise the plant for the
    preflight's analysis, which keeps the preset's (no experiment per variant of a
    Monte-Carlo sweep). A typed scenario comes back typed."""
    sc = as_scenario(scenario)
    if sc.controller.inner.design_plant != "identified":
        notices.phase("simulating")
        return scenario, "preset"
    models, source = identified_models(sc, progress)
    notices.phase("simulating")  # the design plants are known: the run proper follows
    if source == "preset":
        return scenario, source
    typed = sc.model_copy(deep=True)
    typed.controller.inner.identified = Identified.model_validate(models)
    return (typed if isinstance(scenario, Scenario) else typed.model_dump()), source
