"""Checks run before a co-simulation steps: can the cylinders lift the payload,
are the outer gains inside the analysed stability limit.

* :func:`check_payload` is an error (:class:`~simpro_mj.core.errors.UserInputError`,
  exit 2): the static holding force of the loaded, as-built plant at the
  start pose and along the set-point profile must be within what each
  cylinder can make at the supply pressure (``force_range`` of
  :class:`simpro_mj.plant.pneumatics.PneumaticParams`: ``(p_s - p_a) A_cap`` pushing,
  ``(p_s - p_a) A_annulus`` pulling). Holding forces are affine in the
  payload mass at a fixed pose (gravity is linear in the masses, the
  constraint geometry does not depend on them), so two static solves per pose
  also give the largest payload the cylinders can hold there.
* :func:`gain_warnings` is a warning (users study instability): a task-space
  outer gain above the limit of :func:`controllers.analysis.real_inner_limit`,
  the outer loop around the discretised joint loops, lifted to the outer
  period, with the IK Jacobian at home, where the joint loops are the
  scenario's controllers (variant, discretisation, design plant) on the plant
  the actuator model stands for: ``linear`` is eq. (19) with the
  ``actuator.pneumatics.linear`` coefficients (eqs. 34-35 in SI under
  ``paper_units`` by default, and the analysis is then exact up to
  saturation), ``nonlinear`` is linearised by ``controller.inner.identified``
  (the plant preset's identified models), each joint loop behind the
  scenario's set-point filter (Fig. 13). For the shipped I loop at T = 60 ms
  (backward Euler, ramps of 60 / 30 / 30 ms) that is 14.08 (linear) and 11.84
  (nonlinear, preset ``paper``); with Fig. 7's forward integrator 7.52 (linear).

:func:`preflight` runs both and returns the warnings and the figures that
``metrics.json`` records under ``preflight``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from simpro_mj.core.errors import PhysicsError, UserInputError
from simpro_mj.plant.payload import holding_force_model, max_payload

__all__ = ["check_payload", "gain_warnings", "stability_limit", "preflight", "UTILISATION_WARN"]

#: Warn above this fraction of a cylinder's force spent on holding the payload.
UTILISATION_WARN = 0.9
_MAX_POSES = 60  # static solves per check (0.5 ms each)


def _poses(scenario: Mapping) -> tuple[np.ndarray, np.ndarray]:
    """Set-point poses to check: the start, each axis' extremes, and a spread."""
    from simpro_mj.config.scenario import reference

    duration = float(scenario["duration_s"])
    t = np.linspace(0.0, duration, int(min(2001, duration / 0.05 + 1)))
    pose = reference(scenario, t)
    _, first = np.unique(np.round(pose, 7), axis=0, return_index=True)
    first = np.sort(first)
    if first.size > _MAX_POSES:
        extremes = np.concatenate([np.argmin(pose, axis=0), np.argmax(pose, axis=0)])
        spread = first[np.linspace(0, first.size - 1, _MAX_POSES - 7).astype(int)]
        first = np.unique(np.concatenate([[0], extremes, spread]))
    return t[first], pose[first]


def check_payload(scenario: Mapping, model=None) -> dict:
    """Refuse a payload the cylinders cannot hold at the supply pressure.

    Parameters
    ----------
    scenario : mapping
        A resolved scenario.
    model : mujoco.MjModel, optional
        The compiled plant (built from ``scenario["plant"]`` when omitted; its
        payload mass is changed and restored).

    Returns
    -------
    dict
        ``max_payload_kg`` (largest payload the cylinders hold at every checked
        pose), ``holding_force_n`` (worst per leg), ``force_range_n``,
        ``utilisation`` (worst holding force / available force, per leg),
        ``poses_checked``, ``supply_bar_gauge``.

    Raises
    ------
    UserInputError
        ``payload too heavy at plant.payload.mass_kg: ...`` or, when the empty
        platform already needs more, ``supply too low at
        actuator.pneumatics.supply_pressure_bar_gauge: ...``.
    """
    import mujoco

    from controllers.geometry import nominal_geometry
    from controllers.kinematics import inverse_kinematics
    from simpro_mj.plant.model import PlantIndex, assemble, load_model
    from simpro_mj.plant.pneumatics import PneumaticParams

    params = PneumaticParams.from_tree(scenario["actuator"].get("pneumatics") or {})
    f_min, f_max = params.force_range
    supply_bar = (params.p_supply - params.p_atm) * 1e-5
    info: dict = {
        "supply_bar_gauge": supply_bar,
        "force_range_n": [f_min, f_max],
    }
    if scenario["actuator"]["model"] == "linear" and not params.lin_saturate:
        info["skipped"] = "linear actuator without force saturation"
        return info

    mass = float(scenario["plant"]["payload"]["mass_kg"])
    if model is None:
        # the payload mass is set per static solve (holding_force_model): build the
        # plant without it, so that 1e6 kg gets this check's message and limit,
        # not the model builder's
        plant = dict(scenario["plant"], payload=dict(scenario["plant"]["payload"], mass_kg=0.0))
        model = load_model(plant)
    m = model
    d = mujoco.MjData(m)
    idx = PlantIndex.of(m)
    probe = mass if mass > 0 else 1.0
    times, poses = _poses(scenario)
    q_all = inverse_kinematics(poses, nominal_geometry(), check=False)

    worst = None  # (utilisation, leg, t, force)
    hold_max = np.zeros(3)
    util = np.zeros(3)
    m_max = math.inf
    empty_short = None  # (deficit, leg, t, force at no payload)
    checked = 0
    for t, q in zip(times, q_all, strict=True):
        d.qpos[:] = m.qpos0
        try:
            assemble(m, d, q, index=idx)
        except PhysicsError:
            continue  # not assemblable on the as-built plant: the run reports it
        f_empty, slope = holding_force_model(m, d, idx, probe)
        f = f_empty + slope * mass
        checked += 1
        m_max = min(m_max, max_payload(f_empty, slope, (f_min, f_max)))
        for i in range(3):
            u = f[i] / (f_max if f[i] >= 0 else f_min)
            util[i] = max(util[i], u)
            if abs(f[i]) > abs(hold_max[i]):
                hold_max[i] = f[i]
            if worst is None or u > worst[0]:
                worst = (u, i, float(t), float(f[i]))
            ratio = f_empty[i] / (f_max if f_empty[i] >= 0 else f_min)
            if ratio > 1 and (empty_short is None or ratio > empty_short[0]):
                empty_short = (ratio, i, float(t), float(f_empty[i]))
    info.update(
        max_payload_kg=max(m_max, 0.0) if math.isfinite(m_max) else None,
        holding_force_n=hold_max.tolist(),
        utilisation=util.tolist(),
        poses_checked=checked,
    )
    if worst is None or worst[0] <= 1.0:
        return info
    where = "at the start pose" if worst[2] == 0.0 else f"at the set-point of t = {worst[2]:.2f} s"
    if empty_short is not None:
        _, i, t, f = empty_short
        area = params.area_cap if f >= 0 else params.area_rod_side
        need_bar = abs(f) / area * 1e-5
        raise UserInputError(
            f"supply too low at actuator.pneumatics.supply_pressure_bar_gauge: {supply_bar:g} bar; "
            f"the platform without payload needs {abs(f) / 1e3:.2f} kN on cylinder {i + 1} "
            f"{where}, which makes at most {abs(f_max if f >= 0 else f_min) / 1e3:.2f} kN; "
            f"allowed: > {need_bar:.2f} bar gauge"
        )
    _, i, t, f = worst
    cap = f_max if f >= 0 else f_min
    raise UserInputError(
        f"payload too heavy at plant.payload.mass_kg: {mass:g} kg needs {abs(f) / 1e3:.2f} kN "
        f"on cylinder {i + 1} {where}, which makes at most {abs(cap) / 1e3:.2f} kN at "
        f"{supply_bar:g} bar gauge supply; allowed: <= {max(m_max, 0.0):.0f} kg at this supply "
        "pressure (actuator.pneumatics.supply_pressure_bar_gauge)"
    )


def _inner_legs(scenario: Mapping, dt: float):
    """The joint loops as the analysis sees them: the scenario's controllers on the
    plant its actuator model stands for. Returns (legs, plant description)."""
    from controllers.analysis import inner_discrete_loop, with_setpoint_filter
    from controllers.design import (
        ACTUATORS,
        Plant,
        corrected_design,
        paper_coefficients,
        paper_plant,
        printed_design,
        redesigned_design,
    )
    from controllers.setpoint_filter import filter_state_space, leg_times

    inner = scenario["controller"]["inner"]
    reading = scenario["paper_units"]
    identified = {a: Plant(**inner["identified"][a]) for a in ACTUATORS}
    if inner["design_plant"] == "identified":
        design_plants = identified
    else:
        design_plants = {a: paper_plant(a, reading) for a in ACTUATORS}
    if scenario["actuator"]["model"] == "linear":
        from simpro_mj.plant.pneumatics import PneumaticParams, fill_linear

        p = PneumaticParams.from_tree(scenario["actuator"].get("pneumatics") or {})
        p = fill_linear(p, paper_coefficients(reading))
        plants = {
            a: Plant(b=float(p.lin_b[i]), a1=float(p.lin_a1[i]), a0=float(p.lin_a0[i]))
            for i, a in enumerate(ACTUATORS)
        }
        what = "the linear actuators' eq. (19) plants"
    else:
        plants = identified
        what = "the identified plant controller.inner.identified"
    legs = []
    for a in ACTUATORS:
        if inner["variant"] == "printed":
            design = printed_design(a, reading)
        elif inner["variant"] == "corrected":
            design = corrected_design(a, design_plants[a])
        else:
            design = redesigned_design(
                a, zeta=inner["zeta"], wn=inner["wn_rad_s"], plant=design_plants[a]
            )
        legs.append(inner_discrete_loop(design, plants[a], dt, inner["discretisation"]))
    sf = scenario["controller"]["setpoint_filter"]
    times = leg_times(np.asarray(sf["time_ms"], float) * 1e-3)
    legs = [
        with_setpoint_filter(leg, filter_state_space(sf["type"], dt, t))
        for leg, t in zip(legs, times, strict=True)
    ]
    return legs, (
        f"real inner loops: {sf['type']} set-point filter, {inner['variant']} joint "
        f"controllers on {what}"
    )


def stability_limit(scenario: Mapping, dt: float = 1e-3) -> dict:
    """The analysed limit of the scenario's outer loop (see the module docstring).

    Returns
    -------
    dict
        ``limit`` (largest common K K_I, 1/s), ``basis`` (what was analysed),
        ``spectral_radius`` at the scenario's gains, ``delay_model_limit``
        (eq. 21's one-sample delay, for comparison).
    """
    from controllers import analysis as an
    from controllers.geometry import nominal_geometry
    from controllers.kinematics import jacobian

    outer = scenario["controller"]["outer"]
    from controllers.task_space import outer_law

    mode, c = outer_law(outer["type"], outer["integrator"], outer["pi_zero"])
    period = outer["period_ms"] * 1e-3
    legs, basis = _inner_legs(scenario, dt)
    jac = jacobian(nominal_geometry().home)
    limit = an.real_inner_limit(mode, period, dt=dt, jac=jac, pi_zero=c, legs=legs)
    lifted = an.lifted_inner(period, dt=dt, legs=legs)
    f = an.outer_closed_loop(mode, np.asarray(outer["gains"], float), period, lifted, jac, c)[0]
    a, b = an.outer_polynomials(mode, period, int(outer["delay_samples"]), c)
    return {
        "limit": float(limit),
        "basis": basis,
        "spectral_radius": an.spectral_radius(f),
        "delay_model_limit": float(an.stability_limit(a, b)),
    }


def gain_warnings(scenario: Mapping) -> tuple[list[str], dict]:
    """Warnings for outer gains above the analysed limit, and the analysis figures.

    Returns ``([], {})`` in joint-only mode (no outer loop).
    """
    if scenario["controller"]["mode"] != "task_space":
        return [], {}
    outer = scenario["controller"]["outer"]
    info = stability_limit(scenario)
    lim = info["limit"]
    label = f"{outer['type']}, T = {outer['period_ms']:g} ms, {info['basis']}"
    out = []
    over = [i for i, g in enumerate(outer["gains"]) if g > lim]
    if len(over) == len(outer["gains"]) and len(set(outer["gains"])) == 1:
        # the usual case (one gain on every axis): one line, not three
        out.append(
            f"controller.outer.gains = {outer['gains'][0]:g} on every axis exceeds the analysed "
            f"stability limit {lim:.3g} ({label}); the run may diverge"
        )
    else:
        for i in over:
            out.append(
                f"controller.outer.gains[{i}] = {outer['gains'][i]:g} exceeds the analysed "
                f"stability limit {lim:.3g} ({label}); the run may diverge"
            )
    if not out and info["spectral_radius"] >= 1.0:
        out.append(
            f"controller.outer.gains = {outer['gains']} together are unstable in the analysis "
            f"(spectral radius {info['spectral_radius']:.3f} >= 1; {label}); the run may diverge"
        )
    return out, info


def preflight(scenario: Mapping, model=None) -> tuple[list[str], dict]:
    """Payload check (raises), gain warnings and set-point components that start
    after the run ends (warned: they never act); returns ``(warnings, figures)``."""
    from simpro_mj.config.scenario import late_setpoints
    from simpro_mj.identification.auto import with_identified

    scenario = with_identified(scenario)[0]  # design_plant identified: its own plant's
    payload = check_payload(scenario, model)
    warnings, stability = gain_warnings(scenario)
    warnings += late_setpoints(scenario)
    for i, u in enumerate(payload.get("utilisation", [])):
        if u > UTILISATION_WARN:
            warnings.append(
                f"plant.payload.mass_kg = {scenario['plant']['payload']['mass_kg']:g} kg takes "
                f"{u * 100:.0f} % of cylinder {i + 1}'s force at "
                f"{payload['supply_bar_gauge']:g} bar gauge just to hold it; little is left "
                "to accelerate"
            )
    return warnings, {"payload": payload, "stability": stability}
