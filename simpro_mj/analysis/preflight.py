"""Checks run before a co-simulation steps: can the cylinders lift the payload,
are the outer gains inside the analysed stability limit.

* :func:`check_payload` is an error (:class:`~simpro_mj.core.errors.UserInputError`,
  exit 2): the static holding force of the loaded, as-built plant at the
  start pose and along the set-point profile must be within what each
  cylinder can make at the supply pressure (``force_range`` of
  :class:`simpro_mj.plant.pneumatics.params.PneumaticParams`: ``(p_s - p_a) A_cap`` pushing,
  ``(p_s - p_a) A_annulus`` pulling). Holding forces are affine in the
  payload mass at a fixed pose (gravity is linear in the masses, the
  constraint geometry does not depend on them), so two static solves per pose
  also give the largest payload the cylinders can hold there.
* :func:`gain_warnings` is a warning (users study instability): a task-space
  outer gain above the analysed limit of :func:`simpro_mj.analysis.stability.outer_loop`
  (the outer loop around the scenario's discretised joint loops, lifted to the
  outer period, with the IK Jacobian at home) on the plant the actuator model
  stands for: ``linear`` is eq. (19) with the ``actuator.pneumatics.linear``
  coefficients (eqs. 34-35 in SI under ``paper_units`` by default, and the
  analysis is then exact up to saturation), ``nonlinear`` is linearised by
  ``controller.inner.identified`` (the plant preset's identified models), each
  joint loop behind the scenario's set-point filter (Fig. 13). For the shipped I loop at T = 60 ms
  (backward Euler, ramps of 60 / 30 / 30 ms) that is 14.08 (linear) and 11.84
  (nonlinear, preset ``paper``); with Fig. 7's forward integrator 7.52 (linear).

:func:`preflight` runs both and returns the warnings and the figures that
``metrics.json`` records under ``preflight``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from controllers.kinematics import inverse_kinematics
from simpro_mj.analysis.sanity import unit_warnings
from simpro_mj.analysis.stability import outer_loop
from simpro_mj.config.models import Scenario, as_scenario, as_tree
from simpro_mj.config.reference import late_setpoints, reference
from simpro_mj.core.errors import PhysicsError, UserInputError
from simpro_mj.plant.payload import holding_force_model, max_payload

__all__ = [
    "GAIN_REFUSE_FACTOR",
    "MIN_GAIN_DURATION",
    "check_gains_move",
    "check_payload",
    "cueing_mode_warnings",
    "gain_warnings",
    "stability_limit",
    "preflight",
    "UTILISATION_WARN",
]

#: Warn above this fraction of a cylinder's force spent on holding the payload.
UTILISATION_WARN = 0.9
#: Outer gains above this many times the analysed stability limit are refused: the
#: loop then saturates every step (a gain of 1e6 ran to the end 'ok' with the platform
#: at rest and a 3.4 deg error); up to it a user may study instability (the shipped
#: gain sweep reaches 2.5 times).
GAIN_REFUSE_FACTOR = 10.0
_MAX_POSES = 60  # static solves per check (0.5 ms each)


def _poses(scenario: Scenario, setpoints=None) -> tuple[np.ndarray, np.ndarray]:
    """Set-point poses to check: the start, each axis' extremes, and a spread.

    ``setpoints``: ``(t, pose)`` on the run's 1 ms grid, read at the checked
    times (nearest sample) instead of evaluating the profile again.
    """
    duration = scenario.duration_s
    t = np.linspace(0.0, duration, int(min(2001, duration / 0.05 + 1)))
    if setpoints is None:
        pose = reference(scenario, t)
    else:
        grid, ref = setpoints
        dt = float(grid[1] - grid[0]) if grid.size > 1 else 1.0
        pose = ref[np.clip(np.rint(t / dt).astype(int), 0, ref.shape[0] - 1)]
    _, first = np.unique(np.round(pose, 7), axis=0, return_index=True)
    first = np.sort(first)
    if first.size > _MAX_POSES:
        extremes = np.concatenate([np.argmin(pose, axis=0), np.argmax(pose, axis=0)])
        spread = first[np.linspace(0, first.size - 1, _MAX_POSES - 7).astype(int)]
        first = np.unique(np.concatenate([[0], extremes, spread]))
    return t[first], pose[first]


def check_payload(scenario: Scenario | Mapping, model=None, setpoints=None) -> dict:
    """Refuse a payload the cylinders cannot hold at the supply pressure.

    Parameters
    ----------
    scenario : Scenario or mapping
        A resolved scenario.
    model : mujoco.MjModel, optional
        The compiled plant (built from the scenario's ``plant`` when omitted; its
        payload mass is changed and restored).
    setpoints : (ndarray, ndarray), optional
        ``(t, pose)``: the set-points on the run's 1 ms grid (evaluated here
        when omitted).

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
    # MuJoCo is loaded by the first check that needs the plant, not by importing the
    # preflight (the compare command imports it and refuses bad input within a second)
    import mujoco

    from simpro_mj.plant.model import PlantIndex, assemble, load_model

    sc = as_scenario(scenario)
    params = sc.actuator.pneumatics.params()
    f_min, f_max = params.force_range
    supply_bar = (params.p_supply - params.p_atm) * 1e-5
    info: dict = {
        "supply_bar_gauge": supply_bar,
        "force_range_n": [f_min, f_max],
    }
    if sc.actuator.model == "linear" and not params.lin_saturate:
        info["skipped"] = "linear actuator without force saturation"
        return info

    mass = sc.plant.payload.mass_kg
    if model is None:
        # the payload mass is set per static solve (holding_force_model): build the
        # plant without it, so that 1e6 kg gets this check's message and limit,
        # not the model builder's
        model = load_model(sc.plant.tree(empty=True))
    m = model
    d = mujoco.MjData(m)
    idx = PlantIndex.of(m)
    probe = mass if mass > 0 else 1.0
    times, poses = _poses(sc, setpoints)
    q_all = inverse_kinematics(poses, sc.plant.geometry(), check=False)

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


def stability_limit(scenario: Scenario | Mapping, dt: float = 1e-3) -> dict:
    """The analysed limit of the scenario's outer loop on the plant its actuator model
    stands for (:func:`simpro_mj.analysis.stability.outer_loop`, plant ``"actuator"``).

    Returns
    -------
    dict
        ``limit`` (largest common K K_I, 1/s), ``basis`` (what was analysed),
        ``spectral_radius`` at the scenario's gains, ``delay_model_limit``
        (eq. 21's one-sample delay, for comparison).
    """
    info = outer_loop(scenario, plant="actuator", dt=dt)
    return {k: info[k] for k in ("limit", "basis", "spectral_radius", "delay_model_limit")}


#: Smallest K K_I * duration_s of the task-space loop: below it an integrating loop
#: moves the platform less than 1 - exp(-0.01) = 1 % of a step within the run.
MIN_GAIN_DURATION = 0.01


def check_gains_move(gains, duration_s: float) -> None:
    """Refuse an outer gain that cannot move the platform within the run.

    The task-space law integrates the pose error, so on an axis with K K_I = 0 the
    joint set-points never leave the start pose (a 3 deg pitch step ended ``ok``
    with a 3.36 deg error); with K K_I duration_s < :data:`MIN_GAIN_DURATION` a step
    is followed by less than 1 % by the end of the run.
    """
    for i, (axis, k) in enumerate(zip(("roll", "pitch", "heave"), gains, strict=False)):
        if not k * duration_s >= MIN_GAIN_DURATION:
            raise UserInputError(
                f"invalid value at controller.outer.gains[{i}]: {k:g} on {axis}: the "
                f"task-space loop integrates the error, so it would move the platform by "
                f"less than 1 % of a step in {duration_s:g} s; allowed: K K_I >= "
                f"{MIN_GAIN_DURATION / duration_s:.3g} 1/s in this run (the paper's 3), or "
                "controller.mode=joint_only to drive the joints without the outer loop"
            )


def refuse_far_gains(scenario: Scenario | Mapping, lim: float, basis: str = "") -> None:
    """Refuse outer gains above :data:`GAIN_REFUSE_FACTOR` times the limit ``lim``;
    ``basis`` says what the limit was analysed on when not the run's design plants."""
    outer = as_scenario(scenario).controller.outer
    top = max(outer.gains)
    if math.isfinite(lim) and lim > 0.0 and top > GAIN_REFUSE_FACTOR * lim:
        raise UserInputError(
            f"invalid value at controller.outer.gains: {top:g} is {top / lim:,.0f} times the "
            f"analysed stability limit {lim:.3g} ({outer.type}, T = {outer.period_ms:g} "
            f"ms{basis}); allowed: <= {GAIN_REFUSE_FACTOR * lim:.3g} ({GAIN_REFUSE_FACTOR:g} "
            "times the limit: far beyond it each outer step asks more than the joints can do, "
            "the anti-windup rejects it and the platform never moves; gains up to that are "
            "allowed to study instability)"
        )


def check_gains_before_identifying(scenario: Scenario | Mapping) -> None:
    """Refuse far-out outer gains before a plant's identification experiment runs.

    The limit is analysed on the models the scenario holds before it (its preset's
    ``controller.inner.identified``), as the preflight analyses a changed plant under
    ``design_plant: paper``; after the experiment :func:`gain_warnings` checks the
    same rule on the plant's own models. A refusal so costs no identification.
    """
    sc = as_scenario(scenario)
    if sc.controller.mode != "task_space":
        return
    lim = stability_limit(sc)["limit"]
    refuse_far_gains(sc, lim, ", on the preset's models: this plant is not identified yet")


def gain_warnings(scenario: Scenario | Mapping) -> tuple[list[str], dict]:
    """Warnings for outer gains above the analysed limit, and the analysis figures.

    Returns ``([], {})`` in joint-only mode (no outer loop).
    """
    sc = as_scenario(scenario)
    if sc.controller.mode != "task_space":
        return [], {}
    outer = sc.controller.outer
    gains = outer.gains
    check_gains_move(gains, sc.duration_s)
    info = stability_limit(sc)
    lim = info["limit"]
    label = f"{outer.type}, T = {outer.period_ms:g} ms, {info['basis']}"
    if lim <= 0.0:  # unstable at every gain: the joint loops, not the outer gains
        return [
            f"the task-space loop is unstable at any outer gain in the analysis ({label}): "
            "its joint loops do not hold the plant (controller.inner: variant, design_plant); "
            "the run may diverge"
        ], info
    refuse_far_gains(sc, lim)
    out = []
    over = [i for i, g in enumerate(gains) if g > lim]
    if len(over) == len(gains) and len(set(gains)) == 1:
        # the usual case (one gain on every axis): one line, not three
        out.append(
            f"controller.outer.gains = {gains[0]:g} on every axis exceeds the analysed "
            f"stability limit {lim:.3g} ({label}); the run may diverge"
        )
    else:
        for i in over:
            out.append(
                f"controller.outer.gains[{i}] = {gains[i]:g} exceeds the analysed "
                f"stability limit {lim:.3g} ({label}); the run may diverge"
            )
    if not out and info["spectral_radius"] >= 1.0:
        out.append(
            f"controller.outer.gains = {gains} together are unstable in the analysis "
            f"(spectral radius {info['spectral_radius']:.3f} >= 1; {label}); the run may diverge"
        )
    return out, info


#: Frequency at which a cueing scenario's loop is checked (Hz): a car's manoeuvres.
CUE_CHECK_HZ = 0.5


def cueing_mode_warnings(scenario: Scenario | Mapping) -> list[str]:
    """A cueing scenario on a loop that cannot follow a moving cue (``task_space``:
    the pose loop alone, ~1 s behind at 0.5 Hz): warned, with the loop's predicted
    gain and delay at :data:`CUE_CHECK_HZ` beside the feed-forward scheme's."""
    sc = as_scenario(scenario)
    if sc.setpoint.cueing is None or sc.controller.mode != "task_space":
        return []
    from controllers.frequency import predict
    from simpro_mj.analysis.response_summary import loop_model

    omega = 2.0 * math.pi * CUE_CHECK_HZ
    figures = {}
    for mode in ("task_space", "feedforward"):
        loop = sc.model_copy(update={"controller": sc.controller.model_copy(update={"mode": mode})})
        try:
            h = complex(predict(loop_model(loop), [omega])["true"][0, 1, 1])  # pitch
        except Exception:  # noqa: BLE001 - a warning without its numbers is still a warning
            return [
                "controller.mode = task_space on a cueing scenario: the pose loop alone lags "
                "a moving cue; allowed but defeats the cueing: use feedforward"
            ]
        lag = (-math.atan2(h.imag, h.real)) % (2 * math.pi)
        figures[mode] = (20 * math.log10(max(abs(h), 1e-300)), lag / omega)
    (g_ts, d_ts), (g_ff, d_ff) = figures["task_space"], figures["feedforward"]
    return [
        f"controller.mode = task_space on a cueing scenario: the pose loop follows the cue at "
        f"{CUE_CHECK_HZ:g} Hz with {g_ts:.1f} dB and {d_ts:.2f} s of delay (feedforward: "
        f"{g_ff:.1f} dB, {d_ff:.2f} s), so the driver feels the cue late; use "
        "controller.mode = feedforward"
    ]


def preflight(
    scenario: Scenario | Mapping, model=None, *, setpoints=None, payload: dict | None = None
) -> tuple[list[str], dict]:
    """Payload check (raises), gain warnings and set-point components that start
    after the run ends (warned: they never act); returns ``(warnings, figures)``.

    ``scenario`` carries its design plants (``design_plant: identified``: the
    scenario's own plant's models, :func:`~simpro_mj.identification.auto.with_identified`);
    ``model`` and ``setpoints`` are the run's compiled plant and set-points
    (:class:`simpro_mj.job.run.Run` passes both; built here when omitted);
    ``payload`` is :func:`check_payload`'s result when the caller ran it first.
    """
    sc = as_scenario(scenario)
    if payload is None:
        payload = check_payload(sc, model, setpoints)
    warnings, stability = gain_warnings(sc)
    warnings += late_setpoints(sc)
    warnings += cueing_mode_warnings(sc)
    # radians in a _deg key, telemetry without gravity: read on the scenario's tree
    warnings += unit_warnings(as_tree(scenario))
    for i, u in enumerate(payload.get("utilisation", [])):
        if u > UTILISATION_WARN:
            warnings.append(
                f"plant.payload.mass_kg = {sc.plant.payload.mass_kg:g} kg takes "
                f"{u * 100:.0f} % of cylinder {i + 1}'s force at "
                f"{payload['supply_bar_gauge']:g} bar gauge just to hold it; little is left "
                "to accelerate"
            )
    return warnings, {"payload": payload, "stability": stability}
