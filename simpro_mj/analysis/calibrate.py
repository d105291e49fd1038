"""``simpro-sim calibrate``: fit the plant's uncertain parameters to identified models.

The workflow of a rig owner: identify the rig (Fig. 12's experiment) ->
calibrate the simulated plant so that ``simpro-sim identify`` on it gives the
same models -> simulate. The targets are eq. (19)'s natural frequency
``wn = sqrt(a0)``, damping ratio ``zeta = a1 / (2 wn)`` and velocity gain
``b / a0`` per actuator: by default eqs. (34)-(35) in SI under the
``paper_units`` reading (``b / 20`` for potentiometer volts), or a rig
owner's YAML file (:func:`simpro_mj.analysis.targets.load_targets`).

What is fitted, and why these (everything else is a catalogue value or the
geometry of section 5.2.1):

* ``model.payload.mass_kg``: the moving mass sets the natural frequencies
  (``a0 = K / m``, stiffness K fixed by the cylinder and the pressures);
  Table 1 is lost, so the mass is the least known number of the plant;
* ``pneumatics.cylinder.viscous_friction_n_s_per_m`` (leg 1; legs 2-3 one
  value): the damping ratios (``a1 = beta / m`` plus the valve's small
  flow-pressure coefficient);
* ``pneumatics.valve.sonic_conductance_dm3_per_s_bar``: the velocity gains
  scale with the flow the valve and its hoses pass (the catalogue's
  2000 l/min is for the bare valve);
* ``pneumatics.valve.underlap_fraction`` (leg 1; legs 2-3 one value): the
  flow gain around the centre (both edges meter inside the underlap), which
  moves leg 1's gain against legs 2-3's.

Amplitudes (``amplitudes_v``, default ±0.3 V and ±1 V of PRBS): the paper's
models come from a PRBS whose magnitude "was selected to obtain the adequate
excitation" (section 5.2.2), not printed. A plant calibrated at ±0.3 V alone
reproduces eqs. (34)-(35) there and nowhere else: its velocity gains fall by
13 % (leg 1) and 25 % (legs 2-3) at ±1 V, the range the closed-loop steps of
Figs. 14-16 drive the valves through (valve 1 reaches 3.6 V on a 3° pitch
step), because the underlap that gives the small-signal gain is a fraction of
the valve's stroke. Fitting both amplitudes asks for the reading that eqs.
(34)-(35) describe the rig over its working range: more conductance, less
underlap (docs/paper-notes.md section 3).

Legs 2 and 3 are mirror images in the nominal model (same identified model),
so actuator 3 is not excited during the fit; the final identification runs
all three. The cost per evaluation is two short identification experiments
(``calibrate.duration_s`` of PRBS each).
"""

from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from simpro_mj.core.errors import PhysicsError, UserInputError
from simpro_mj.identification.identify import Fit, identify, paper_models
from simpro_mj.identification.settings import Experiment, check_tree
from simpro_mj.plant.model_params import DEFAULT_MODEL_PARAMS
from simpro_mj.plant.pneumatics.params import DEFAULT_PNEUMATIC_PARAMS, Pneumatics

#: Acceptance band of the fit: relative on wn and b/a0, absolute on zeta.
TOLERANCES = {"wn_rad_s": 0.15, "zeta": 0.1, "velocity_gain_m_s_per_v": 0.15}

#: Fitted parameters: name, tree path (``[i]`` selects legs), start, bounds.
_FRICTION = "pneumatics.cylinder.viscous_friction_n_s_per_m"
_VALVE = "pneumatics.valve."
PARAMETERS = (
    ("payload_kg", "model.payload.mass_kg", None, 30.0, (0.0, 600.0)),
    ("friction1_n_s_per_m", _FRICTION, (0,), 6800.0, (0.0, 4e4)),
    ("friction23_n_s_per_m", _FRICTION, (1, 2), 150.0, (50.0, 5e3)),
    ("coulomb_n", "pneumatics.cylinder.coulomb_friction_n", (0, 1, 2), 20.0, (1.0, 300.0)),
    ("conductance_dm3_per_s_bar", _VALVE + "sonic_conductance_dm3_per_s_bar", None, 2.8,
     (0.3, 7.87)),
    ("underlap1", _VALVE + "underlap_fraction", (0,), 0.015, (0.003, 0.15)),
    ("underlap23", _VALVE + "underlap_fraction", (1, 2), 0.03, (0.003, 0.15)),
)  # fmt: skip


def paper_targets(reading: str = "volts") -> dict:
    """Eqs. (34)-(35) as targets: ``{actuator: {wn_rad_s, zeta, velocity_gain_m_s_per_v}}``."""
    return {a: _targets(m) for a, m in paper_models(reading).items()}


def _targets(model: Fit) -> dict:
    """The numbers of ``model`` the fit compares (:data:`TOLERANCES`)."""
    return {k: v for k, v in model.as_dict().items() if k in TOLERANCES}


def _set_path(tree: dict, path: str, legs, value: float) -> None:
    parts = path.split(".")
    node = tree
    for part in parts[:-1]:
        node = node[part]
    if legs is None:
        node[parts[-1]] = float(value)
    else:
        arr = list(np.broadcast_to(np.asarray(node[parts[-1]], float), (3,)))
        for i in legs:
            arr[i] = float(value)
        node[parts[-1]] = [float(x) for x in arr]


def apply_values(tree: dict, values: dict) -> dict:
    """A copy of the identify tree with the fitted parameters set."""
    out = copy.deepcopy(tree)
    for name, path, legs, _, _ in PARAMETERS:
        if name in values:
            _set_path(out, path, legs, values[name])
    return out


def residuals(identified: dict[str, Fit], targets: dict) -> dict:
    """Per actuator and quantity: the error in units of its tolerance (|r| <= 1 passes);
    relative on wn and b/a0, absolute on zeta."""
    out = {}
    for a, fit in identified.items():
        got, t = fit.as_dict(), targets[a]
        out[a] = {
            k: ((got[k] - t[k]) if k == "zeta" else (got[k] / t[k] - 1.0)) / tol
            for k, tol in TOLERANCES.items()
        }
    return out


@dataclass
class Calibration:
    """The best fit :func:`calibrate` found: the fitted ``values``, the models
    ``identified`` there (actuators 1-2, the first amplitude's) and their
    ``residuals`` per tolerance (None if no evaluation ran), the ``evaluations``
    spent and the ``cost`` (sum of squared residuals)."""

    cost: float = math.inf
    values: dict[str, float] = field(default_factory=dict)
    identified: dict[str, Fit] | None = None
    residuals: dict | None = None
    evaluations: int = 0


def calibrate(
    tree: dict,
    targets: dict,
    *,
    duration_s: float = 4.0,
    max_evaluations: int = 40,
    progress=None,
    amplitudes_v=(0.3, 1.0),
) -> Calibration:
    """Fit :data:`PARAMETERS` with ``scipy.optimize.least_squares``.

    Parameters
    ----------
    tree : dict
        The identify tree (:func:`simpro_mj.identification.identify.default_tree`), the start.
    targets : dict
        ``{actuator: {wn_rad_s, zeta, velocity_gain_m_s_per_v}}``.
    duration_s : float
        PRBS per actuator and evaluation (s).
    max_evaluations : int
        Budget of identification runs (each excites actuators 1 and 2).
    progress : callable(int, float), optional
        Called after each evaluation with its number and the cost.
    amplitudes_v : sequence of float
        PRBS amplitudes (V) at which the targets are fitted (module docstring);
        each evaluation runs one identification per amplitude.

    Returns
    -------
    Calibration
    """
    names = [p[0] for p in PARAMETERS]
    start = {}
    for name, path, legs, default, _ in PARAMETERS:
        node: Any = tree
        for part in path.split("."):
            node = node[part]
        v = float(np.broadcast_to(np.asarray(node, float), (3,))[legs[0]]) if legs else float(node)
        start[name] = v if v > 0 else default
    lo = np.array([max(b[0], 1e-3) for *_, b in PARAMETERS])
    hi = np.array([b[1] for *_, b in PARAMETERS])
    x0 = np.log(np.clip([start[n] for n in names], lo * 1.0001, hi * 0.9999))
    settings = replace(check_tree(tree).settings, duration_s=float(duration_s))
    amplitudes = [float(a) for a in amplitudes_v]
    if not amplitudes or not all(0.0 < a <= 5.0 for a in amplitudes):
        raise UserInputError(
            f"invalid value at amplitudes_v: {amplitudes_v!r}; allowed: 1+ amplitudes in (0, 5] V"
        )
    acts = ("actuator1", "actuator2")
    count = [0]
    best = Calibration()

    class _Budget(Exception):
        pass

    def fun(x):
        if count[0] >= max_evaluations:
            raise _Budget  # least_squares' max_nfev does not count its Jacobian's runs
        values = dict(zip(names, np.exp(x).tolist(), strict=True))
        count[0] += 1
        trial = apply_values(tree, values)
        parts: list[float] = []
        ident, res = None, None
        try:
            for amp in amplitudes:
                run = replace(settings, prbs_amplitude_v=[amp] * 3)
                got = identify(replace(check_tree(trial), settings=run), legs=(1, 2))
                rs = residuals(got, {a: targets[a] for a in acts})
                parts.extend(rs[a][k] for a in acts for k in TOLERANCES)
                if ident is None:  # the first amplitude's models are reported
                    ident, res = got, rs
            r = np.array(parts)
        except (PhysicsError, UserInputError):
            ident, res, r = None, None, np.full(6 * len(amplitudes), 10.0)
        cost = float(r @ r)
        if cost < best.cost:
            best.cost, best.values, best.identified, best.residuals = cost, values, ident, res
        if progress is not None:
            progress(count[0], cost)
        return r

    try:
        least_squares(
            fun, x0, bounds=(np.log(lo), np.log(hi)), diff_step=0.02, max_nfev=max_evaluations
        )
    except _Budget:
        pass
    best.evaluations = count[0]
    return best


# ------------------------------------------------------------------ plausibility, preset


def plausibility(ex: Experiment) -> dict:
    """Physical reading of a fitted plant: moving mass, friction against a seal's, valve flow.

    Bands (assumptions, stated): a 125 mm cylinder's seals give 100-2000 N s/m of
    viscous friction (Richer & Hurmuzlu's order of magnitude); more on leg 1 is the
    passive guide's bearings it drives. The MPYE-5-3/8 passes 2000 l/min (ANR,
    C = 7.87 dm^3/(s bar)) bare; hoses and fittings lower the effective value.
    """
    m, p = ex.model, Pneumatics.model_validate(ex.pneumatics)  # checked: check_tree
    payload = float(m["payload"]["mass_kg"])
    platform = float(m["platform_mass_kg"])
    visc = np.broadcast_to(np.asarray(p.cylinder.viscous_friction_n_s_per_m, float), (3,))
    c = float(p.valve.sonic_conductance_dm3_per_s_bar)
    c_ref = float(Pneumatics().valve.sonic_conductance_dm3_per_s_bar)
    under = np.broadcast_to(np.asarray(p.valve.underlap_fraction, float), (3,))
    return {
        "moving_mass_kg": {
            "payload": payload,
            "platform": platform,
            "total": payload + platform,
            "note": "payload + platform on the legs (legs' own rods and the guide come from "
            "the MJCF); Table 1 is lost",
        },
        "viscous_friction_n_s_per_m": {
            "values": visc.tolist(),
            "seal_band": [100.0, 2000.0],
            "within_seal_band": [bool(100.0 <= v <= 2000.0) for v in visc],
            "note": "above the band on leg 1: the guide's bearings lumped on the leg",
        },
        "valve_flow": {
            "sonic_conductance_dm3_per_s_bar": c,
            "fraction_of_catalogue": c / c_ref,
            "nominal_flow_l_per_min": 2000.0 * c / c_ref,
            "note": "effective conductance of valve + hoses + fittings",
        },
        "underlap_fraction": under.tolist(),
    }


def preset_document(name: str, ex: Experiment, result: Calibration, targets: dict, extra=None):
    """The preset YAML document: only the values that differ from the model's own
    defaults (a preset lies over them)."""

    def diff(a, b):
        out = {}
        for k, v in a.items():
            if isinstance(v, dict) and isinstance(b.get(k), dict):
                d = diff(v, b[k])
                if d:
                    out[k] = d
            elif v != b.get(k):
                out[k] = v
        return out

    ident = result.identified or {}
    doc = {
        "name": name,
        "description": f"calibrated by simpro-sim calibrate ({len(targets)} target models)",
        "plant": diff(ex.model, DEFAULT_MODEL_PARAMS),
        "pneumatics": diff(ex.pneumatics, DEFAULT_PNEUMATIC_PARAMS),
        "identified": {a: {k: round(v, 4) for k, v in m.model().items()} for a, m in ident.items()},
        "calibration": {
            "targets": targets,
            "tolerances": TOLERANCES,
            "residuals_per_tolerance": result.residuals,
            "fitted": result.values,
            "evaluations": result.evaluations,
            "plausibility": plausibility(ex),
        }
        | (extra or {}),
    }
    return doc


def calibrate_preset(
    tree: dict,
    targets: dict,
    name: str,
    *,
    duration_s: float,
    max_evaluations: int,
    amplitudes_v,
    progress=None,
) -> tuple[dict, Calibration]:
    """Calibrate ``tree`` to ``targets`` and write nothing: returns the preset document
    (plain data for YAML) and the :class:`Calibration`, its models those identified at
    the fit (all three actuators, the identify command's settings) and their residuals."""
    result = calibrate(
        tree, targets, duration_s=duration_s, max_evaluations=max_evaluations,
        progress=progress, amplitudes_v=amplitudes_v,
    )  # fmt: skip
    fitted = check_tree(apply_values(tree, result.values))
    final = identify(fitted)
    result.identified, result.residuals = final, residuals(final, targets)
    by_amp = {}
    for amp in amplitudes_v[1:]:  # the other amplitudes' models at the fit, for the record
        run = replace(fitted.settings, prbs_amplitude_v=[float(amp)] * 3)
        got = identify(replace(fitted, settings=run), legs=(1, 2))
        by_amp[f"{amp:g}_v"] = {
            a: {k: round(v, 4) for k, v in _targets(m).items()} for a, m in got.items()
        }
    extra = {
        "paper_units": fitted.paper_units,
        "amplitudes_v": [float(a) for a in amplitudes_v],
        "identified_at_other_amplitudes": by_amp,
    }
    doc = preset_document(name, fitted, result, targets, extra)
    doc = json.loads(json.dumps(doc, default=float))  # plain floats for YAML
    return doc, result
