"""Whole-chain frequency response of the motion cueing: vehicle -> driver's head.

``simpro-sim response --chain``. For each vehicle channel (specific force
``fx, fy, fz`` and roll and pitch rates ``wx, wy``, vehicle frame V, ISO
8855) and each frequency, one run of the scenario with its vehicle input
replaced by a sine on that channel alone (``setpoint.cueing.sine``: the car
at rest plus the sine), through the washout, the controllers, the
pneumatics and the multibody, to MuJoCo's ``head_accel`` and ``head_gyro``
at the driver's head. After ``settle_s`` (default 10 s: five time constants
of the washout's slowest poles, ``heave_omega_b`` and ``rot_omega`` at
0.5 rad/s), ``periods`` whole periods of the input and of the five head
channels are fitted by least squares (:func:`controllers.frequency.fit_sine`)
and their ratio is the response.

Rows are the pairs of the Objective Motion Cueing Test (ICAO 9625, 4th ed.,
Attachment 2) that a roll-pitch-heave platform has: the direct responses
pitch, roll, surge, sway and heave, and the cross-couplings pitch-to-surge
(``wy -> fx``: the rotational channel tilts the cabin, gravity leaks into
``f_x``), roll-to-sway, surge-to-pitch (``fx -> wy``: the rotation of tilt
coordination, which the rate limit keeps near the canals' threshold) and
sway-to-roll. Frequencies: the twelve OMCT frequencies (0.1 to 15.85 rad/s)
on the 1 ms period grid. Gains are in the edge units (``m/s^2`` per
``m/s^2``, ``deg/s`` per ``deg/s``, and mixed for the cross-couplings).

Beside the measurement, two linear predictions
(:func:`controllers.frequency.chain_response`):

``washout``
    The washout alone: its discrete filters (Tustin, at its period, held on
    the 1 ms grid) on an ideal platform (pose = set-point) with the head at
    the pose's reference point P: what the algorithm asks for.
``predicted``
    The washout, then the scenario's linearised platform loop
    (:func:`simpro_mj.analysis.response.loop_model`, the pose-response prediction of
    ``simpro-sim response``), then the rigid cabin with the head where the
    MJCF puts it (0.75 m above P: the tangential acceleration of a pitch or
    roll adds to the tilt's gravity cue and grows as w^2).

The difference measured - washout is what the platform adds; measured -
predicted is what the linear model misses (valves, friction, the
nonlinear pneumatics). The washout's rate and angle limits and the
workspace soft limit are not in the predictions: ``rate_limited_pct`` and
``softened_pct`` give the share of the fitted cueing samples where they
acted (not a small-signal point: lower the amplitude).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field

import mujoco
import numpy as np

from controllers.frames import T_VB
from controllers.frequency import CHAIN_CHANNELS, chain_response, fit_sine, predict
from controllers.kinematics import inverse_kinematics
from controllers.washout import ClassicalWashout, WashoutParams
from simpro_mj.analysis.omct import OMCT_TESTS
from simpro_mj.analysis.response import (
    UNITS,
    Failed,
    SinePlan,
    SineTask,
    check_settle_periods,
    db,
    default_periods_ms,
    dense_grid,
    failures,
    fits,
    in_edge,
    run_point,
    saturated_pct,
    sine_plan,
    sine_run,
)
from simpro_mj.analysis.response_summary import Bode, loop_model
from simpro_mj.config.cue_models import Cueing
from simpro_mj.config.cue_params import washout_params
from simpro_mj.config.cueing import vehicle_input
from simpro_mj.config.models import Scenario, as_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.plant.model import assemble
from simpro_mj.sim.build import Build

CHANNELS = CHAIN_CHANNELS
#: The cueing block's ``sine.channel`` of each channel (telemetry column names).
_SINE_CHANNEL = {c: f"{c}_{'mps2' if c[0] == 'f' else 'rad_s'}" for c in CHANNELS}
#: The OMCT tests (:data:`simpro_mj.analysis.omct.OMCT_TESTS`) as (input, output) -> name,
#: the rotations first.
PAIRS = {OMCT_TESTS[name]: name for name in ("pitch", "roll", *OMCT_TESTS)}
#: Small-signal amplitudes (edge units). 0.3 m/s^2 keeps the tilt rate of the default
#: washout below its 3 deg/s limit at every frequency (peak w |LP(jw)| k_x a / g =
#: 2.5 * 0.5 * 0.3 / 9.81 = 2.2 deg/s at w_t = 5 rad/s) and the heave within
#: 19 mm; 1 deg/s tilts the cabin by at most 2 deg through the rotational channel.
DEFAULT_AMPLITUDES = {"f": 0.3, "w": 1.0}
MAX_AMPLITUDES = {"f": 9.80665, "w": 90.0}
DEFAULT_SETTLE_S = 10.0


def omct_periods_ms() -> list[int]:
    """The twelve OMCT frequencies on the 1 ms period grid, longest period first."""
    return default_periods_ms(extra_hz=())


def _check_amplitude(value, kind: str) -> float:
    """``value`` (None: the default) of a ``kind`` of amplitude (``f``, ``w``), checked."""
    value = DEFAULT_AMPLITUDES[kind] if value is None else value
    where = "--amplitude-mps2" if kind == "f" else "--amplitude-deg-s"
    unit = "m/s^2" if kind == "f" else "deg/s"
    top = MAX_AMPLITUDES[kind]
    low = 1e-3 if kind == "f" else 1e-2  # below the head's perception thresholds a hundredfold
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not (ok and math.isfinite(value) and low <= value <= top):
        raise UserInputError(
            f"invalid value at {where}: {value!r}; allowed: {low:g} <= amplitude <= {top:g} "
            f"{unit} (the smallest: a hundredth of the vestibular thresholds)"
        )
    return float(value)


def plan_chain(
    scenario: Mapping,
    *,
    periods_ms: Sequence[int] | None = None,
    amplitude_mps2: float | None = None,
    amplitude_deg_s: float | None = None,
    channels: Sequence[str] = CHANNELS,
    settle_s: float = DEFAULT_SETTLE_S,
    periods: int = 2,
) -> SinePlan:
    """Check the test's parameters and build its tasks (plain data for the workers)."""
    af, aw = _check_amplitude(amplitude_mps2, "f"), _check_amplitude(amplitude_deg_s, "w")
    if not channels:
        raise UserInputError(f"invalid value at --channels: empty; allowed: {list(CHANNELS)}")
    for c in channels:
        if c not in CHANNELS:
            raise UserInputError(f"invalid value at --channels: {c!r}; allowed: {list(CHANNELS)}")
    if len(set(channels)) != len(channels):
        raise UserInputError(
            "invalid value at --channels: a channel given twice; allowed: distinct"
        )
    check_settle_periods(settle_s, periods)
    periods_ms = omct_periods_ms() if periods_ms is None else sorted(periods_ms, reverse=True)
    amps = {c: (af if c[0] == "f" else aw * math.pi / 180.0) for c in CHANNELS}

    def run_of(c: str, p: int) -> dict:
        return chain_scenario(scenario, c, p, amps[c], settle_s, periods)

    return sine_plan(scenario, channels, periods_ms, amps, settle_s, periods, run_of)


def cue_block(scenario: Scenario | Mapping) -> dict:
    """The scenario's cueing block (its algorithm and parameters), or the defaults."""
    cue = as_scenario(scenario).setpoint.cueing or Cueing.model_validate(
        {"sine": {"channel": "fx_mps2", "amplitude": 1.0, "period_s": 1.0}}
    )
    return {"algorithm": cue.algorithm, "parameters": cue.parameters.model_dump()}


def chain_scenario(
    scenario: Mapping, channel: str, period_ms: int, amplitude: float, settle_s: float, periods: int
) -> dict:
    """The scenario driven by a vehicle sine of ``amplitude`` (SI) on ``channel`` alone,
    through its washout (or the default one), for ``settle_s`` plus ``periods`` periods,
    logged every step, faults removed."""
    sine = {"channel": _SINE_CHANNEL[channel], "amplitude": float(amplitude),
            "period_s": period_ms / 1000.0}  # fmt: skip
    cueing = {"telemetry": None, "manoeuvre": None, "sine": sine, **cue_block(scenario)}
    return sine_run(scenario, {"cueing": cueing}, period_ms, settle_s, periods)


@dataclass
class SineFit:
    """A chain run's fit over its settled whole periods (:func:`fit_columns`): ``ref``
    the input's complex amplitude (``[re, im]``, SI), ``head`` one ``[re, im]`` per
    :data:`CHANNELS`, the fitted rows ``k0:k1``; from the run (:func:`measure_chain_point`)
    the shares (%) of those rows with a valve at a rail (``saturated_pct``) and of the
    cueing samples where the tilt rate limit or the workspace soft limit acted."""

    ref: list
    head: list
    k0: int
    k1: int
    saturated_pct: float = 0.0
    rate_limited_pct: float = 0.0
    softened_pct: float = 0.0


def fit_columns(columns: Mapping, task: SineTask, dt: float = 0.001) -> SineFit:
    """Fit a run's vehicle input and head channels over the settled whole periods.

    ``columns``: ``time_s``, ``veh_*`` and ``head_*`` (:data:`simpro_mj.config.cueing.CUE_COLUMNS`).
    """
    k0, k1 = task.window(dt)
    t = np.asarray(columns["time_s"], float)[k0:k1]
    if t.size < k1 - k0 or t.size < 4:
        raise ValueError(f"run too short: {t.size} samples, the fit needs {k1 - k0}")
    w = 2.0 * math.pi / (task.period_ms / 1000.0)

    def col(side: str, ch: str) -> np.ndarray:
        return np.asarray(columns[f"{side}_{_SINE_CHANNEL[ch]}"], float)[k0:k1]

    ref = fit_sine(t, col("veh", task.input), w)
    head = fit_sine(t, np.column_stack([col("head", c) for c in CHANNELS]), w)
    return SineFit([ref.real, ref.imag], [[v.real, v.imag] for v in np.atleast_1d(head)], k0, k1)


def _fit_chain(task: SineTask, res) -> SineFit:
    sine = fit_columns(res.columns, task, res.sim["timestep_s"])
    k0, k1 = sine.k0, sine.k1
    info = vehicle_input(task.scenario)[4]
    e = info["every"]
    lim = np.asarray(info["rate_limited"])[k0 // e : -(-k1 // e)]
    soft = np.asarray(info["softened"])[k0 // e : -(-k1 // e)]
    sine.saturated_pct = saturated_pct(res.columns, k0, k1)
    sine.rate_limited_pct = float(lim.mean() * 100.0) if lim.size else 0.0
    sine.softened_pct = float(soft.mean() * 100.0) if soft.size else 0.0
    return sine


def measure_chain_point(envelope: Mapping) -> dict:
    """Run one vehicle sine through the chain and fit it (worker side; pickles by name):
    a :class:`SineFit` when ``ok`` (:func:`simpro_mj.analysis.response.run_point`)."""
    return run_point(envelope, _fit_chain)


def head_jacobian(scenario: Mapping, step: float = 1e-4) -> np.ndarray:
    """How the head site moves per pose at home, ISO axes (m per rad, m per m), (3, 3).

    Central differences of MuJoCo's assembled closed chain
    (:func:`simpro_mj.plant.model.assemble` at the IK of home +- ``step``). The mechanism
    moves the head by more than a rigid rotation about P: P itself moves back and
    forth on the guide's arc (0.43 m per rad of pitch, 0.50 m per m of heave).
    """
    cs = Build(dict(scenario)).simulation()
    m, d, idx, c = cs.model, cs.data, cs.idx, cs.sensor_cfg
    home = np.asarray(cs.geometry.home, float)

    def head(pose) -> np.ndarray:
        q = inverse_kinematics(np.asarray(pose, float), cs.geometry)
        mujoco.mj_resetData(m, d)
        assemble(m, d, (q - c.pot_offset_m) / c.pot_gain, index=idx)
        mujoco.mj_kinematics(m, d)
        return d.site("head").xpos.copy()

    jac = np.empty((3, 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = step
        jac[:, j] = (head(home + e) - head(home - e)) / (2 * step)
    return T_VB @ jac @ T_VB  # base <-> ISO: T_VB is its own inverse


@dataclass
class ChainPrediction:
    """The washout alone and the linear chain (None when the loop has no linear model)
    at the frequencies asked for: complex (len(omega), 5, 5) per
    :func:`controllers.frequency.chain_response`; ``note`` why one is missing."""

    washout: np.ndarray | None = None
    predicted: np.ndarray | None = None
    note: str | None = None


def predictions(plan: SinePlan, omega) -> ChainPrediction:
    """The :class:`ChainPrediction` of ``plan``'s washout and loop at ``omega``."""

    sc = plan.tasks[0].scenario if plan.tasks else plan.scenario
    if sc["setpoint"]["cueing"].get("algorithm") == "mpc":
        # a constrained optimisation, not a filter: no transfer function to draw beside
        note = "no linear prediction: the mpc law is a constrained QP, not a linear filter"
        return ChainPrediction(note=note)
    params = washout_params(sc["setpoint"]["cueing"])
    assert isinstance(params, WashoutParams)  # mpc returned above
    wash = ClassicalWashout(params)
    out = ChainPrediction(washout=chain_response(wash, omega))
    try:
        loop = predict(loop_model(sc), omega)["true"]
        pose = T_VB @ loop @ T_VB  # base <-> ISO angles
        out.predicted = chain_response(wash, omega, pose=pose, head_jac=head_jacobian(sc))
    except Exception as exc:  # noqa: BLE001 - the measurement stands without it
        out.note = f"no loop prediction: {type(exc).__name__}: {exc}"
    return out


@dataclass
class ChainRow:
    """One OMCT pair at one frequency: the head's measured response (edge units, the
    pair's ``unit``) beside the washout alone and the linear chain."""

    test: str
    input: str
    output: str
    unit: str
    frequency_hz: float
    omega_rad_s: float
    period_ms: int
    amplitude: float
    gain: float
    gain_db: float
    phase_deg: float
    washout_gain_db: float | None = None
    washout_phase_deg: float | None = None
    predicted_gain_db: float | None = None
    predicted_phase_deg: float | None = None
    #: measured less the washout alone: what the platform adds
    platform_db: float | None = None
    platform_deg: float | None = None
    saturated_pct: float = 0.0
    rate_limited_pct: float = 0.0
    softened_pct: float = 0.0


@dataclass
class ChainCurve:
    """An OMCT pair's washout alone and linear chain (None without a loop model) on a
    dense grid between the measured frequencies."""

    omega_rad_s: list[float]
    washout: Bode | None = None
    predicted: Bode | None = None


@dataclass
class ChainSummary:
    """The summary of a chain response (:func:`chain_summary`)."""

    rows: list[ChainRow] = field(default_factory=list)
    #: the frequencies that did not run
    failed: list[Failed] = field(default_factory=list)
    prediction_note: str | None = None
    #: the pairs on which the washout's rate limit or softening acted
    not_small_signal: list[str] = field(default_factory=list)
    curves: dict[str, ChainCurve] = field(default_factory=dict)

    def to_json(self) -> dict:
        return {
            "rows": [asdict(r) for r in self.rows],
            "failed": [f.as_json("channel") for f in self.failed],
            "prediction_note": self.prediction_note,
            "not_small_signal": self.not_small_signal,
            "curves": {k: asdict(c) for k, c in self.curves.items()},
        }


def chain_summary(plan: SinePlan, results: list) -> ChainSummary:
    """Rows (one per OMCT pair and frequency), the failures, and ``curves``: per OMCT
    pair the washout alone and the linear chain (None without a loop model) on a
    dense grid between the lowest and highest measured frequency."""
    periods = sorted(plan.periods_ms, reverse=True)
    omega = 2 * np.pi * 1000.0 / np.array(periods, float)
    dense, at, span = dense_grid(omega, 300)
    pred = predictions(plan, dense)
    by_key = fits(plan.tasks, results)
    out = ChainSummary(failed=failures(plan.tasks, results), prediction_note=pred.note)
    for (cin, cout), name in PAIRS.items():
        if cin not in plan.inputs:
            continue
        i, o = CHANNELS.index(cin), CHANNELS.index(cout)
        curve = out.curves[name] = ChainCurve(dense[span].tolist())
        h_of, ph_of = {}, {}
        for key in ("washout", "predicted"):
            if (h_all := getattr(pred, key)) is not None:
                h_of[key] = h = h_all[:, o, i]
                unwrapped = np.degrees(np.unwrap(np.angle(h)))
                ph_of[key] = unwrapped[at]
                setattr(curve, key, Bode.of(in_edge(cin, cout, np.abs(h[span])), unwrapped[span]))
        hw, ph_w = h_of.get("washout"), ph_of.get("washout")
        hp, ph_p = h_of.get("predicted"), ph_of.get("predicted")
        for n, p in enumerate(periods):
            if (r := by_key.get((cin, p))) is None:
                continue
            hm = complex(*r.head[o]) / complex(*r.ref)
            raw = math.degrees(np.angle(hm))
            near = ph_p[n] if ph_p is not None else ph_w[n] if ph_w is not None else raw
            phase = raw + 360.0 * round((near - raw) / 360.0)  # the branch of the prediction
            g = abs(in_edge(cin, cout, hm))
            gw = abs(in_edge(cin, cout, hw[at[n]])) if hw is not None else None
            row = ChainRow(
                test=name,
                input=cin,
                output=cout,
                unit=f"{UNITS[cout][0]} per {UNITS[cin][0]}",
                frequency_hz=float(omega[n] / (2 * np.pi)),
                omega_rad_s=float(omega[n]),
                period_ms=p,
                amplitude=plan.amplitudes[cin] / UNITS[cin][1],
                gain=g,
                gain_db=db(g),
                phase_deg=float(phase),
                washout_gain_db=None if gw is None else db(gw),
                washout_phase_deg=None if ph_w is None else float(ph_w[n]),
                platform_db=None
                if gw is None
                else 20 * math.log10(max(g, 1e-300) / max(gw, 1e-300)),
                platform_deg=None if hw is None else float(np.degrees(np.angle(hm / hw[at[n]]))),
                saturated_pct=r.saturated_pct,
                rate_limited_pct=r.rate_limited_pct,
                softened_pct=r.softened_pct,
            )
            if hp is not None and ph_p is not None:
                row.predicted_gain_db = db(abs(in_edge(cin, cout, hp[at[n]])))
                row.predicted_phase_deg = float(ph_p[n])
            out.rows.append(row)
    out.not_small_signal = sorted(
        {r.test for r in out.rows if r.rate_limited_pct > 0 or r.softened_pct > 0}
    )
    return out
