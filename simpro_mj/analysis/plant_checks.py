"""Physical checks of a plant: does the model do what its physics says?

``simpro-sim check-plant`` runs :func:`check_plant`: short experiments on the
scenario's own plant (its MuJoCo model and its pneumatic actuators, stepped at
the run's 1 ms with the step's own functions, no controller), each compared
with what a law of physics or the plant's own parameters predict:

========================  ==================================================
stiction                  a leg at valve null, loaded by 80 % of its seal's
                          breakaway force, does not move (Coulomb's law of
                          static friction)
breakaway                 a force ramped on a leg at valve null sets it
                          sliding at the seal's breakaway force
sealed chamber energy     a sealed chamber compressed and expanded through
                          one cycle gives back the work put in (adiabatic,
                          no heat flow) or loses what its walls take
null leakage              a valve at null with the piston held bleeds what
                          its underlap's ISO 6358 orifice passes
chamber filling           a chamber filled from the atmosphere through the
                          open valve, at 1 ms, against the same model at
                          1/64 of the step
supply sag                the supply pressure at the valves during a fast
                          move, against the receiver's mass balance
loop closure              the closed chain's largest loop gap during a fast
                          move (the stiff loop constraints hold)
========================  ==================================================

Each check is a :class:`Check` with its measured value, the expected value,
the tolerance and the source of the expectation.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass

import mujoco
import numpy as np

from simpro_mj.config.models import Scenario, as_scenario
from simpro_mj.plant.model import load_model
from simpro_mj.plant.platform import Platform
from simpro_mj.plant.pneumatics.factory import make_actuators
from simpro_mj.plant.pneumatics.flow import RHO_REF, iso6358_mass_flow
from simpro_mj.plant.step_functions import AC, ACT, CH


@dataclass(frozen=True)
class Check:
    """One physical check: ``ok`` when ``|measured - expected| <= tolerance``."""

    name: str
    measured: float
    expected: float
    tolerance: float
    unit: str
    source: str

    @property
    def ok(self) -> bool:
        """Whether the measured value lies within the tolerance of the expected one."""
        return bool(abs(self.measured - self.expected) <= self.tolerance)

    def as_dict(self) -> dict:
        """The check as plain numbers and text, ``ok`` included (for ``--json``)."""
        return {**asdict(self), "ok": self.ok}


def _plant(scenario: Scenario | Mapping, settle: float = 1.0, ideal_supply: bool = False):
    """The scenario's plant at home, its valves at their holding voltages for ``settle`` s
    (the chain's own static deflection under its load, unknown to the static pressures)."""
    sc = as_scenario(scenario)
    model = load_model(sc.plant.tree())
    tree = sc.actuator.pneumatics.model_dump()
    if ideal_supply:  # the seal alone: no droop of the line under the valves' leakage
        tree["supply"] = {**(tree.get("supply") or {}), "model": "ideal"}
    act = make_actuators("nonlinear", tree, model=model)
    act.set_timestep(float(model.opt.timestep))
    plat = Platform(model, act)
    plat.reset(np.full(3, 0.5 * act.params.stroke))
    for _ in range(int(round(settle / model.opt.timestep))):  # the start-up settling
        _step(plat, act.u_hold.copy())
    return plat


def _step(plat: Platform, u, extra=None) -> None:
    """One 1 ms step of the plant alone: valve volts ``u`` held, ``extra`` N on the slides."""
    m, d, idx, act = plat.model, plat.data, plat.index, plat.actuators
    q, qd = d.qpos[idx.slide_qpos].copy(), d.qvel[idx.slide_dof].copy()
    d.ctrl[idx.actuators] = act.step(u, q, qd, float(m.opt.timestep))
    d.qfrc_applied[idx.slide_dof] = 0.0 if extra is None else extra
    mujoco.mj_step(m, d)


def stiction(
    scenario: Scenario | Mapping, leg: int = 1, share: float = 0.8, seconds: float = 2.0
) -> Check:
    """A leg at valve null loaded by ``share`` of its breakaway force stays put (the
    supply ideal: the seal alone)."""
    plat = _plant(scenario, ideal_supply=True)
    fs = float(plat.actuators.params.breakaway[leg])
    idx, d = plat.index, plat.data
    q0 = float(d.qpos[idx.slide_qpos[leg]])
    push = np.eye(3)[leg] * (share * fs)
    for _ in range(int(round(seconds / plat.model.opt.timestep))):
        _step(plat, plat.actuators.u_hold.copy(), push)
    moved = abs(float(d.qpos[idx.slide_qpos[leg]]) - q0)
    return Check(
        f"stiction (leg {leg + 1}, {share:.0%} of {fs:.0f} N breakaway, {seconds:g} s)",
        moved * 1e3,
        0.0,
        0.05,
        "mm",
        "Coulomb: a seal loaded below its breakaway force does not slide",
    )


def _air_spring(act, leg: int, q: float) -> float:
    """The leg's pneumatic stiffness at valve null and position ``q``, N/m:
    :math:`n (p_1 A_1^2 / V_1 + p_2 A_2^2 / V_2)` of sealed chambers."""
    P = act.params
    v1 = P.dead_cap[leg] + P.area_cap * q
    v2 = P.dead_rod[leg] + P.area_rod_side * (P.stroke - q)
    p1, p2 = float(act.p1[leg]), float(act.p2[leg])
    return P.n_poly * (p1 * P.area_cap**2 / v1 + p2 * P.area_rod_side**2 / v2)


def breakaway(
    scenario: Scenario | Mapping, leg: int = 1, seconds: float = 4.0, slip: float = 2e-5
) -> Check:
    """The seal's force when a leg at valve null, pushed by a force ramped from 0
    to twice its breakaway force over ``2 seconds``, has moved ``slip`` m: the
    push less what the air springs then carry (quasi-static; the supply ideal: with
    a line that droops under the valves' leakage the settled leg holds a preload)."""
    plat = _plant(scenario, ideal_supply=True)
    act = plat.actuators
    fs = float(act.params.breakaway[leg])
    idx, d, dt = plat.index, plat.data, float(plat.model.opt.timestep)
    q0 = float(d.qpos[idx.slide_qpos[leg]])
    k_air = _air_spring(act, leg, q0)
    rate, f, k = fs / seconds, 0.0, 0
    while f < 2.0 * fs + 100.0:
        f = rate * k * dt
        _step(plat, act.u_hold.copy(), np.eye(3)[leg] * f)
        k += 1
        if abs(float(d.qpos[idx.slide_qpos[leg]]) - q0) > slip:
            break
    return Check(
        f"breakaway force (leg {leg + 1}, ramp to it over {seconds:g} s)",
        f - k_air * slip,
        fs,
        0.03 * fs + 0.5,
        "N",
        "the seal's breakaway force (pneumatics.cylinder.breakaway_friction_n)",
    )


def _sealed(scenario: Scenario | Mapping):
    """The scenario's actuators with the valve sealed: no underlap, no leakage."""
    tree = as_scenario(scenario).actuator.pneumatics.model_dump()
    valve = dict(tree.get("valve") or {})
    valve.update(underlap_fraction=0.0, leakage_fraction=1e-12)  # > 0: the model needs an edge
    tree["valve"] = valve
    act = make_actuators("nonlinear", tree)
    act.set_timestep(1e-3)
    return act


def sealed_chamber_energy(
    scenario: Scenario | Mapping, amplitude: float = 0.1, hz: float = 1.0
) -> Check:
    """The first law over one compression cycle of a sealed cap-side chamber:
    work done on the gas plus heat from the wall less the change of its internal
    energy ``p V / (γ - 1)``, over the largest work stored in the cycle."""
    act = _sealed(scenario)
    P, dt = act.params, 1e-3
    ac, st = act.step_constants, act.step_state
    q_mid = 0.5 * P.stroke
    act.reset(np.full(3, q_mid), np.zeros(3))
    act.spool[:] = 0.0
    energy = P.thermal_model == "energy"
    gamma = P.gamma if energy else P.n_poly
    aw0, awv = float(ac[AC.ch + CH.a0]), float(ac[AC.ch + CH.av])  # chamber 1
    w = 2.0 * math.pi * hz
    n = int(round(1.0 / (hz * dt)))
    v_start = float(P.dead_cap[0] + P.area_cap * q_mid)
    u_start = float(act.p1[0]) * v_start / (gamma - 1.0)
    work = heat = stored = 0.0
    for k in range(n):  # the state at the step's start, as the co-simulation passes it
        t = k * dt
        q = q_mid + amplitude * math.sin(w * t)
        qd = amplitude * w * math.cos(w * t)
        p1, t1 = float(act.p1[0]), float(st[ACT.t])
        act.step([5.0] * 3, [q] * 3, [qd] * 3, dt)
        dvol = P.area_cap * (amplitude * math.sin(w * (t + dt)) - (q - q_mid))
        work += -0.5 * (p1 + float(act.p1[0])) * dvol  # on the gas
        if energy:  # heat from the wall over the step, at the step's mean temperature
            vol = P.dead_cap[0] + P.area_cap * (q + 0.5 * dvol / P.area_cap)
            t_mean = 0.5 * (t1 + float(st[ACT.t]))
            heat += P.heat_transfer * (aw0 + awv * vol) * (P.temperature - t_mean) * dt
        stored = max(stored, abs(work))
    du = float(act.p1[0]) * v_start / (gamma - 1.0) - u_start
    kind = "energy equation, wall heat" if energy else f"polytropic n = {P.n_poly:g}, no heat"
    return Check(
        f"sealed chamber energy (cap side, +-{amplitude * 1e3:g} mm at {hz:g} Hz, {kind})",
        100.0 * (work + heat - du) / stored,
        0.0,
        3.0,
        "% of the work stored",
        "first law: work in + heat in = the gas's internal energy gained; the 1 ms "
        "step's first-order volume term leaves about 2 % (0.65 % at 1/8 ms)",
    )


def null_leakage(scenario: Scenario | Mapping) -> Check:
    """Supply flow of the three valves at null, pistons held at mid-stroke, l/min ANR:
    the step's own draw (one step from the static equilibrium) against ISO 6358
    through each chamber's underlapped supply edge."""
    act = make_actuators("nonlinear", as_scenario(scenario).actuator.pneumatics.model_dump())
    P = act.params
    q = np.full(3, 0.5 * P.stroke)
    act.set_timestep(1e-3)
    act.reset(q, np.zeros(3))
    edge = P.conductance * np.maximum(P.underlap, P.leakage)  # m^3/(s Pa), per leg
    expected = sum(
        float(np.sum(iso6358_mass_flow(edge, P.p_supply, p, P.temperature, P.b_crit, P.r_laminar)))
        for p in (act.p1.copy(), act.p2.copy())
    )
    act.step(act.u_hold.copy(), q, np.zeros(3), 1e-3)
    measured = float(act.step_state[ACT.draw])
    per_min = 60e3 / RHO_REF  # kg/s -> l/min ANR (ISO 6358's reference density)
    return Check(
        "null leakage (three valves, pistons held at mid-stroke)",
        measured * per_min,
        expected * per_min,
        0.05 * expected * per_min + 0.1,
        "l/min ANR",
        "ISO 6358 flow of the underlap (valve.underlap_fraction of the conductance); "
        "assumption: the MPYE's null leakage is not in the data at hand",
    )


def chamber_filling(scenario: Scenario | Mapping, seconds: float = 0.3, fine: int = 64) -> Check:
    """Largest pressure difference filling a held chamber at 1 ms against 1 ms / ``fine``."""
    traces = []
    for sub in (1, fine):
        tree = as_scenario(scenario).actuator.pneumatics.model_dump()
        base = int((tree.get("integration") or {}).get("substeps", 1))
        tree["integration"] = {"substeps": sub * base}
        act = make_actuators("nonlinear", tree)
        act.set_timestep(1e-3)
        P = act.params
        act.reset(np.full(3, 0.5 * P.stroke), np.zeros(3))
        act.p1[:] = P.p_atm
        act.p2[:] = P.p_atm
        act.spool[:] = 1.0
        tr = []
        for _ in range(int(round(seconds / 1e-3))):
            act.step([10.0] * 3, [0.5 * P.stroke] * 3, [0.0] * 3, 1e-3)
            tr.append(float(act.p1[0]))
        traces.append(np.array(tr))
    gap = float(np.max(np.abs(traces[0] - traces[1])))
    return Check(
        f"chamber filling (cap side from atmosphere, 1 ms vs 1/{fine} ms)",
        100.0 * gap / (P.p_supply - P.p_atm),
        0.0,
        1.0,
        "% of the supply's gauge pressure",
        "the same chamber ODE integrated at a step 64 times finer",
    )


def _supply_pa(plat: Platform) -> float:
    """The supply pressure at the valves now (Pa absolute)."""
    return float(plat.actuators.step_state[ACT.ps])


def supply_sag(scenario: Scenario | Mapping, seconds: float = 0.4) -> Check:
    """The supply during a fast move: the ideal source holds its pressure; the supply
    as built (``supply.model: receiver``) loses from its receiver and line the mass
    the valves draw less what the compressor delivers (the mass balance, in % of
    the mass drawn), the sag in the check's name."""
    plat = _plant(scenario)
    act = plat.actuators
    P, st, dt = act.params, act.step_state, float(plat.model.opt.timestep)
    rt = P.gas_constant * P.temperature

    def stored() -> float:
        return (st[ACT.pr] * P.receiver_volume + st[ACT.ps] * P.line_volume) / rt

    ps0, m0, drawn, delivered, low = _supply_pa(plat), stored(), 0.0, 0.0, _supply_pa(plat)
    for _ in range(int(round(seconds / dt))):
        _step(plat, [8.0, 8.0, 8.0])
        drawn += float(st[ACT.draw]) * dt
        delivered += float(st[ACT.comp]) * P.compressor_flow * dt
        low = min(low, _supply_pa(plat))
    sag = (ps0 - low) / 1e5
    if P.supply_model == "ideal":
        return Check(
            f"supply sag (every valve at 8 V for {seconds:g} s, ideal source)",
            sag,
            0.0,
            1e-9,
            "bar",
            "the ideal supply holds its pressure whatever the valves draw",
        )
    return Check(
        f"supply mass balance (every valve at 8 V for {seconds:g} s: sags {sag:.2f} bar)",
        100.0 * ((m0 - stored()) - (drawn - delivered)) / drawn,
        0.0,
        1.0,
        "% of the mass drawn",
        "conservation of mass: receiver and line lose what the valves take less what "
        "the compressor gives",
    )


def loop_closure(scenario: Scenario | Mapping) -> Check:
    """The largest loop-closure gap (m) during a fast move: every valve at 8 V for 0.4 s,
    the legs extend about as fast as they can."""
    plat = _plant(scenario)
    d, pairs, gap = plat.data, plat.index.connect_sites, 0.0
    for _ in range(int(round(0.4 / plat.model.opt.timestep))):
        _step(plat, [8.0, 8.0, 8.0])
        gap = max(gap, *(float(np.linalg.norm(d.site_xpos[a] - d.site_xpos[b])) for a, b in pairs))
    return Check(
        "loop closure (every valve at 8 V for 0.4 s)",
        gap * 1e3,
        0.0,
        0.1,
        "mm",
        "the MJCF's loop constraints (solref 2 ms, solimp 0.9999): gaps of microns at rest",
    )


#: the checks in the order of the table
CHECKS = (
    stiction,
    breakaway,
    sealed_chamber_energy,
    null_leakage,
    chamber_filling,
    supply_sag,
    loop_closure,
)


def check_plant(scenario: Scenario | Mapping) -> list[Check]:
    """Every check of :data:`CHECKS` on the resolved ``scenario``'s plant."""
    return [fn(scenario) for fn in CHECKS]


def table(checks: list[Check]) -> str:
    """The checks as a fixed-width text table, one row each, and a last line."""
    rows = [("check", "measured", "expected", "tolerance", "unit", "ok")]
    for c in checks:
        rows.append(
            (
                c.name,
                f"{c.measured:.4g}",
                f"{c.expected:.4g}",
                f"{c.tolerance:.3g}",
                c.unit,
                "yes" if c.ok else "NO",
            )  # fmt: skip
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    lines.insert(1, "-" * len(lines[0]))
    n_ok = sum(c.ok for c in checks)
    lines.append(f"{n_ok} of {len(checks)} checks hold")
    return "\n".join(lines)
