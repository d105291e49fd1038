"""The task-space loop of a scenario, analysed: one function for the preflight and the batch.

The outer loop (eqs. 21-27, Fig. 7: the I or PI law at period T on the
measured pose, the IK Jacobian at home mapping task to joint deviations) is
closed around the discretised joint loops lifted to the outer period
(:func:`controllers.analysis.lifted.lifted_inner`), each joint loop behind the
scenario's set-point filter (Fig. 13). :func:`outer_loop` returns its
stability limit (the largest common ``K K_I`` with the closed loop's spectral
radius below 1, :func:`controllers.analysis.lifted.real_inner_limit`), the spectral
radius at the scenario's gains and the limit of eq. (21)'s one-sample-delay
model beside it.

The joint controllers are always the scenario's (``controller.inner``:
variant, discretisation, ``zeta``/``wn_rad_s`` of the redesign) designed on
``design_plant`` (the paper's eqs. 34-35 in SI under ``paper_units``, or the
identified models). What they control is the *plant assumption*, a parameter:

* ``"actuator"`` (:func:`simpro_mj.analysis.preflight.gain_warnings`): the plant
  the scenario's actuator model stands for: ``linear`` is eq. (19) with the
  ``actuator.pneumatics.linear`` coefficients (the analysis is then exact up
  to saturation), ``nonlinear`` is linearised by ``controller.inner.identified``;
* ``"paper"`` (:func:`simpro_mj.batch.stability.analytic`, the ``analytic_limit``
  column of a gain sweep): eqs. (34)-(35) in SI under ``paper_units``, the plants
  the joint loops were designed for.

For the shipped I loop at T = 60 ms (backward Euler, ramps of 60 / 30 / 30 ms)
the limit is 14.08 on the paper's (and the linear actuators') plants, 11.84 on
the nonlinear plant of preset ``paper``.

The analysis of one loop is cached by every number it reads, so a sweep's
variants that differ only in their gains analyse their loop once: in memory,
and its two limits on disk (:mod:`simpro_mj.core.cache`, kind ``stability``,
named by those numbers and the analysis's source files), which saves every
later ``run`` of the same loop the limit's scan (about 0.3 s).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path

import numpy as np

from controllers.analysis.lifted import (
    inner_discrete_loop,
    lifted_inner,
    outer_closed_loop,
    real_inner_limit,
    reduced,
    spectral_radius,
    with_setpoint_filter,
)
from controllers.analysis.outer_delay import closed_form_limit, outer_polynomials, stability_limit
from controllers.design import ACTUATORS, Plant, design_for, paper_coefficients, paper_plant
from controllers.geometry import geometry_from_rig
from controllers.kinematics import jacobian
from controllers.setpoint_filter import filter_state_space, leg_times
from controllers.task_space import outer_law
from simpro_mj.config.models import Scenario, as_scenario
from simpro_mj.core import cache
from simpro_mj.plant.pneumatics.params import fill_linear

#: The plant assumptions of the analysis (module docstring).
PLANTS = ("actuator", "paper")


def _coefficients(plants: Mapping[str, Plant]) -> tuple:
    return tuple((float(plants[a].b), float(plants[a].a1), float(plants[a].a0)) for a in ACTUATORS)


def _loop_plants(scenario: Scenario, plant: str) -> tuple[tuple, str]:
    """The joint plants under ``plant`` as (b, a1, a0) per actuator, and their description."""
    reading = scenario.paper_units
    if plant == "paper":
        plants = {a: paper_plant(a, reading) for a in ACTUATORS}
        return _coefficients(plants), "the paper's eq. (34)-(35) plants"
    if plant != "actuator":
        raise ValueError(f"plant assumption {plant!r}; allowed: {', '.join(PLANTS)}")
    if scenario.actuator.model == "linear":
        p = fill_linear(scenario.actuator.pneumatics.params(), paper_coefficients(reading))
        assert p.lin_b is not None and p.lin_a1 is not None and p.lin_a0 is not None
        coeffs = tuple(
            (float(p.lin_b[i]), float(p.lin_a1[i]), float(p.lin_a0[i])) for i in range(3)
        )
        return coeffs, "the linear actuators' eq. (19) plants"
    plants = dict(zip(ACTUATORS, scenario.controller.inner.identified.plants(), strict=True))
    return _coefficients(plants), "the identified plant controller.inner.identified"


def _key(scenario: Scenario, plant: str, dt: float) -> tuple:
    """Every number the analysis of the scenario's loop reads, hashable (the cache's key)."""
    c = scenario.controller
    inner, outer, sf = c.inner, c.outer, c.setpoint_filter
    loop, what = _loop_plants(scenario, plant)
    if inner.design_plant == "identified":
        design = _coefficients(dict(zip(ACTUATORS, inner.identified.plants(), strict=True)))
    else:
        design = None  # the paper's plants under the reading
    mode, pi_zero = outer_law(outer.type, outer.integrator, outer.pi_zero)
    return (
        float(dt),
        scenario.paper_units,
        inner.variant,
        inner.discretisation,
        float(inner.zeta),
        float(inner.wn_rad_s),
        design,
        loop,
        what,
        sf.type,
        tuple(float(t) * 1e-3 for t in sf.time_ms),  # validated: 3 per-leg times
        mode,
        float(pi_zero),
        outer.period_ms * 1e-3,
        int(outer.delay_samples),
        _jacobian_home(json.dumps(scenario.plant.rig_tree(), sort_keys=True)),
    )


@lru_cache(maxsize=64)
def _legs_of(key: tuple) -> tuple[list, str]:
    dt, reading, variant, method, zeta, wn, design, loop, what, sf_type, sf_times = key[:11]
    spec = {"zeta": zeta, "wn": wn} if variant == "redesigned" else {}
    legs = []
    for i, a in enumerate(ACTUATORS):
        design_plant = paper_plant(a, reading) if design is None else Plant(*design[i])
        controller = design_for(a, variant, plant=design_plant, reading=reading, **spec)
        leg = inner_discrete_loop(controller, Plant(*loop[i]), dt, method)
        legs.append(leg)
    legs = [
        with_setpoint_filter(leg, filter_state_space(sf_type, dt, t))
        for leg, t in zip(legs, leg_times(sf_times), strict=True)
    ]
    basis = f"real inner loops: {sf_type} set-point filter, {variant} joint controllers on {what}"
    return legs, basis


@lru_cache(maxsize=8)
def _jacobian_home(rig: str) -> tuple:
    """J at home of the rig (its JSON; ``null``: the paper's), as nested tuples (a key)."""
    g = geometry_from_rig(json.loads(rig))
    return tuple(map(tuple, jacobian(g.home, g).tolist()))


@lru_cache(maxsize=1)
def _code() -> str:
    """Digest of the sources that compute a loop's limits (part of the disk cache's key)."""
    import controllers.analysis
    import controllers.design
    import controllers.kinematics
    import controllers.setpoint_filter

    files = [Path(str(m.__file__)) for m in (controllers.design, controllers.kinematics,
                                        controllers.setpoint_filter)]  # fmt: skip
    files += Path(str(controllers.analysis.__file__)).parent.glob(
        "*.py"
    )  # the whole analysis package
    return cache.source_digest([Path(__file__), *files])


def _limits(key: tuple, legs: list) -> tuple[float, float]:
    """(limit, delay-model limit) of one loop, from the disk cache or computed."""
    text = json.dumps([key, _code()], allow_nan=True)
    path = cache.cache_dir("stability") / f"{hashlib.sha256(text.encode()).hexdigest()}.json"

    def entry(doc) -> tuple[float, float] | None:  # NaN refused by read_json
        if doc["key"] != text:  # the file's own key: a hash collision reads as a miss
            return None
        return float(doc["limit"]), float(doc["delay_model_limit"])

    found = cache.read_json(path, entry)  # missing or damaged (said): computed again
    if found is not None:
        return found
    dt = key[0]
    mode, pi_zero, period, delay, jac = key[11:]
    jac = np.asarray(jac)
    limit = real_inner_limit(mode, period, dt=dt, jac=jac, pi_zero=pi_zero, legs=legs)
    try:  # eq. (21)'s model: the closed form where there is one, else the crossing search
        delay_limit = closed_form_limit(mode, period, delay, pi_zero)
    except NotImplementedError:
        delay_limit = stability_limit(*outer_polynomials(mode, period, delay, pi_zero))
    limit, delay_limit = float(limit), float(delay_limit)
    cache.write_json(path, {"key": text, "limit": limit, "delay_model_limit": delay_limit})
    return limit, delay_limit


@lru_cache(maxsize=64)
def _analysed(key: tuple):
    """(limit, delay-model limit, lifted inner loops, basis) of one loop."""
    dt, period = key[0], key[13]
    legs, basis = _legs_of(key)
    limit, delay_limit = _limits(key, legs)
    lifted = reduced(lifted_inner(period, dt=dt, legs=legs))  # same eigenvalues
    return limit, delay_limit, lifted, basis


def outer_loop(scenario: Scenario | Mapping, plant: str = "actuator", dt: float = 1e-3) -> dict:
    """The scenario's outer loop around its joint loops, on the ``plant`` assumption.

    Parameters
    ----------
    scenario : Scenario or mapping
        A resolved scenario (its ``controller``, ``paper_units`` and ``actuator``).
    plant : {"actuator", "paper"}
        What the joint loops control (module docstring).
    dt : float
        The joint loops' period (s).

    Returns
    -------
    dict
        ``limit`` (largest common K K_I, 1/s), ``basis`` (what was analysed),
        ``spectral_radius`` of the closed loop at the scenario's gains,
        ``growth_rate_1_s`` (``ln(spectral_radius) / T``, ``None`` at radius 0)
        and ``delay_model_limit`` (eq. 21's one-sample delay, for comparison).
    """
    sc = as_scenario(scenario)
    key = _key(sc, plant, dt)
    limit, delay_limit, lifted, basis = _analysed(key)
    mode, pi_zero, period = key[11:14]
    gains = np.asarray(sc.controller.outer.gains, float)
    f = outer_closed_loop(mode, gains, period, lifted, np.asarray(key[15]), pi_zero)[0]
    rho = spectral_radius(f)
    return {
        "limit": limit,
        "basis": basis,
        "spectral_radius": rho,
        "growth_rate_1_s": math.log(rho) / period if rho > 0 else None,
        "delay_model_limit": delay_limit,
    }
