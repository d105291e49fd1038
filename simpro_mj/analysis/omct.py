"""The Objective Motion Cueing Test of each cueing law: vehicle -> driver's head.

The OMCT (ICAO 9625, 4th ed., Attachment 2; Hosman & Advani) drives the cueing chain
with a sine on one vehicle channel at twelve frequencies (0.1 to 15.85 rad/s, five per
decade: :data:`controllers.frequency.OMCT_RAD_S`) and reports the gain and phase from the
vehicle's specific force or rotation to the simulator's at the pilot's (here the
driver's) head. ``simpro-sim response --chain`` measures it through the whole plant in
MuJoCo, one run per frequency. This module runs it for every law side by side, fast:
the law itself (:class:`~controllers.washout.ClassicalWashout` or
:class:`~controllers.mpc_cueing.ModelPredictiveCueing`, with its own constraints and
preview), then the platform loop from set-point to pose as the MPC's fitted model
``G(s) = (T_z s + 1) w^2 / (s^2 + 2 zeta w s + w^2) e^(-s T_d)`` (docs/cueing.md: 5.0
rad/s, 0.72, 0.31 s, 0.03 s), then a rigid cabin with the head ``h`` above the tilt
axes (0.75 m in roll, 1.21 m in pitch)::

    f_x = h_p theta'' - g sin(theta),  f_y = g sin(phi) - h_r phi'',
    f_z = g cos(theta) cos(phi) + z'',  w_x = phi',  w_y = theta'

A constrained law (the washout's rate limit, the MPC's box and jolt limits) is not
linear: the response holds at the amplitude tested (``amplitudes``), which the result
names.

Fidelity at 1 rad/s (Sinacori 1977, revised by Schroeder 1999, NASA/TP-1999-208766):
the gain and the phase distortion of each direct response at 1 rad/s place the law in a
high, medium or low fidelity region (:data:`FIDELITY_REGIONS`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from controllers.cue_mpc_params import MpcParams
from controllers.frames import GRAVITY
from controllers.frequency import CHAIN_CHANNELS, OMCT_RAD_S, fit_sine
from controllers.geometry import HEAD_HEIGHT_PITCH, HEAD_HEIGHT_ROLL
from controllers.washout import WashoutParams

#: OMCT tests a roll-pitch-heave platform has: name -> (input, output) channel.
OMCT_TESTS = {
    "surge": ("fx", "fx"),
    "sway": ("fy", "fy"),
    "heave": ("fz", "fz"),
    "pitch": ("wy", "wy"),
    "roll": ("wx", "wx"),
    "pitch-to-surge": ("wy", "fx"),
    "roll-to-sway": ("wx", "fy"),
    "surge-to-pitch": ("fx", "wy"),
    "sway-to-roll": ("fy", "wx"),
}

#: Fidelity regions at 1 rad/s on the plane (gain, phase distortion), as
#: ``(name, gain_min, gain_max, phase_max_deg)``, first match wins: Sinacori's criterion
#: (1977, "The determination of some requirements for a helicopter flight research
#: simulation facility", NASA CR-152066) as reproduced by Schroeder
#: (1999, NASA/TP-1999-208766, "Helicopter flight simulation motion platform
#: requirements"), the same for rotation and translation. The reading: the high region
#: from gain 0.8 with at most 10 deg of phase distortion, the medium one from gain 0.4
#: within 30 deg, drawn as rectangles. The published boundaries are curves through about
#: these corners and Schroeder's revision widens them; the report's figures were not in
#: this project's reach to check the corners against, so this table is a reading, and a law
#: near a boundary is not judged by it alone. Gains above 1 are the mirror of those below
#: (a cue stronger than the car's by a factor is no better than one weaker by it): 1.25
#: and 2.5.
FIDELITY_REGIONS = (
    ("high", 0.8, 1.25, 10.0),
    ("medium", 0.4, 2.5, 30.0),
)

#: Where :data:`FIDELITY_REGIONS` comes from, for the figure's legend and ``omct.json``.
FIDELITY_SOURCE = (
    "Sinacori (1977) as reproduced by Schroeder (1999, NASA/TP-1999-208766); "
    "corners read as gain 0.8 / 10 deg (high) and 0.4 / 30 deg (medium), drawn as rectangles"
)

#: Small-signal amplitudes (SI): 0.3 m/s^2 (specific force) and 1 deg/s (rotation), those
#: of ``response --chain``.
AMPLITUDES = {"f": 0.3, "w": math.radians(1.0)}

#: The laws tested by default, each from a shipped scenario's cueing block:
#: name -> (scenario, parameter changes).
LAWS = {
    "classical_washout": ("cue_slalom", {}),
    "mpc_causal": ("cue_braking", {"preview_s": 0.0, "lead_s": 0.0}),
    "mpc_shipped": ("cue_braking", {}),
}

_SETTLE_S = 10.0
_PERIODS = 2
_DT = 0.01  # divides both laws' periods (10 and 60 ms)


def law_blocks(names: Sequence[str] | None = None) -> dict:
    """The cueing blocks ``{algorithm, parameters}`` of the named laws (:data:`LAWS`)."""
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.core.errors import UserInputError

    names = list(LAWS) if names is None else list(names)
    out = {}
    for name in names:
        if name not in LAWS:
            raise UserInputError(f"invalid value at --laws: {name!r}; allowed: {list(LAWS)}")
        scen, changes = LAWS[name]
        cue = load_scenario(scen).setpoint.cueing
        assert cue is not None  # LAWS name cue scenarios
        out[name] = {
            "algorithm": cue.algorithm,
            "parameters": {**cue.parameters.model_dump(), **changes},
            "scenario": scen,
        }
    return out


def _law(block: Mapping):
    from simpro_mj.config.cue_params import washout_params

    params = washout_params(block)
    if block["algorithm"] == "mpc":
        from controllers.mpc_cueing import ModelPredictiveCueing

        assert isinstance(params, MpcParams)
        return ModelPredictiveCueing(params), params
    from controllers.washout import ClassicalWashout

    assert isinstance(params, WashoutParams)
    return ClassicalWashout(params), params


def _poses(block: Mapping, f: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The law's set-points (n, 3), base frame, on the ``_DT`` grid, and its home."""
    law, params = _law(block)
    home = np.asarray(law.geometry.home, float)
    if block["algorithm"] == "mpc":
        return law.run(f, w, _DT).pose, home
    every = int(round(params.period / _DT))
    res = law.run(f[::every], w[::every])
    return np.repeat(res.pose, every, axis=0)[: f.shape[0]], home


def _loop(y: np.ndarray, dt: float) -> np.ndarray:
    """The platform loop's model (module docstring) on each column of set-points."""
    from scipy import signal

    from controllers.cue_mpc_params import MpcParams

    p = MpcParams()
    w2 = p.loop_omega**2
    sys = signal.cont2discrete(
        ([p.loop_zero * w2, w2], [1.0, 2 * p.loop_zeta * p.loop_omega, w2]), dt, method="bilinear"
    )
    b, a = np.ravel(sys[0]), np.ravel(sys[1])
    out = np.empty_like(y)
    for k in range(y.shape[1]):
        zi = signal.lfilter_zi(b, a) * y[0, k]
        out[:, k] = signal.lfilter(b, a, y[:, k], zi=zi)[0]
    delay = int(round(p.loop_delay / dt))
    if delay:
        out = np.vstack([np.repeat(out[:1], delay, axis=0), out[:-delay]])
    return out


def _head(pose_b: np.ndarray, home: np.ndarray, dt: float) -> dict:
    """Head specific force and rates (ISO, SI) of a rigid cabin following ``pose_b``."""
    phi, theta, z = -pose_b[:, 0], -pose_b[:, 1], pose_b[:, 2] - home[2]

    def d(x, order):
        for _ in range(order):
            x = np.gradient(x, dt)
        return x

    return {
        "fx": HEAD_HEIGHT_PITCH * d(theta, 2) - GRAVITY * np.sin(theta),
        "fy": GRAVITY * np.sin(phi) - HEAD_HEIGHT_ROLL * d(phi, 2),
        "fz": GRAVITY * np.cos(theta) * np.cos(phi) + d(z, 2),
        "wx": d(phi, 1),
        "wy": d(theta, 1),
    }


def law_response(block: Mapping, channel: str, omega: float, amplitude: float) -> dict:
    """Complex responses (SI per SI) from the vehicle ``channel`` to every head channel at
    ``omega`` (rad/s): a sine of ``amplitude`` after the car at rest, fitted over
    ``_PERIODS`` whole periods after ``_SETTLE_S``."""
    period = 2 * math.pi / omega
    n0 = int(round(_SETTLE_S / _DT))
    n1 = n0 + int(round(_PERIODS * period / _DT))
    t = _DT * np.arange(n1 + 1)
    f = np.zeros((t.size, 3))
    w = np.zeros((t.size, 3))
    f[:, 2] = GRAVITY
    k = "xyz".index(channel[1])
    (f if channel[0] == "f" else w)[:, k] += amplitude * np.sin(omega * t)
    pose, home = _poses(block, f, w)
    head = _head(_loop(pose, _DT), home, _DT)
    sl = slice(n0, n1)
    ref = fit_sine(t[sl], (f if channel[0] == "f" else w)[sl, k], omega)
    return {c: complex(fit_sine(t[sl], head[c][sl], omega)) / ref for c in CHAIN_CHANNELS}


def fidelity(gain: float, phase_deg: float) -> str:
    """The region (:data:`FIDELITY_REGIONS`) of a response's gain and phase at 1 rad/s."""
    distortion = abs((phase_deg + 180.0) % 360.0 - 180.0)  # whatever the branch
    for name, lo, hi, ph in FIDELITY_REGIONS:
        if lo <= gain <= hi and distortion <= ph:
            return name
    return "low"


def _edge(channel: str) -> float:
    return 1.0 if channel[0] == "f" else math.pi / 180.0


@dataclass
class OmctRow:
    """One law's response in one OMCT test at one frequency (edge units)."""

    law: str
    test: str
    input: str
    output: str
    omega_rad_s: float
    frequency_hz: float
    gain: float
    gain_db: float
    phase_deg: float


@dataclass
class Fidelity:
    """A direct test's response at 1 rad/s and its region (:func:`fidelity`)."""

    gain: float
    phase_deg: float
    fidelity: str


@dataclass
class Omct:
    """The OMCT of the laws (:func:`omct`); :meth:`to_json` is ``omct.json``'s body."""

    rows: list[OmctRow] = field(default_factory=list)
    #: per law, per direct test
    fidelity_at_1_rad_s: dict[str, dict[str, Fidelity]] = field(default_factory=dict)
    f_mps2: float = 0.0
    w_deg_s: float = 0.0
    #: name -> cueing block
    laws: dict[str, dict] = field(default_factory=dict)

    def to_json(self) -> dict:
        return {
            "rows": [asdict(r) for r in self.rows],
            "fidelity_at_1_rad_s": {
                law: {t: asdict(v) for t, v in tests.items()}
                for law, tests in self.fidelity_at_1_rad_s.items()
            },
            "amplitudes": {"f_mps2": self.f_mps2, "w_deg_s": self.w_deg_s},
            "laws": self.laws,
            "fidelity_regions": {
                "source": FIDELITY_SOURCE,
                "regions": [
                    {"name": n, "gain_min": lo, "gain_max": hi, "phase_max_deg": ph}
                    for n, lo, hi, ph in FIDELITY_REGIONS
                ],
            },
            "chain": CHAIN,
        }


#: The chain every law's OMCT runs through.
CHAIN = "law -> platform loop model (5.0 rad/s, 0.72, 0.31 s, 0.03 s) -> rigid cabin"


def omct(
    laws: Mapping, omegas: Sequence[float] = OMCT_RAD_S, amplitudes=None, progress=None
) -> Omct:
    """The OMCT of each law: rows (law, test, omega, gain, phase) for every test of
    :data:`OMCT_TESTS`, and per law the fidelity of each direct test at 1 rad/s.

    ``laws``: name -> cueing block (:func:`law_blocks`). Gains in edge units (m/s^2 per
    m/s^2, deg/s per deg/s; mixed for the cross-couplings); phases unwrapped along the
    frequencies from the lowest.
    """
    amps = dict(AMPLITUDES, **(amplitudes or {}))
    out = Omct(
        f_mps2=amps["f"],
        w_deg_s=math.degrees(amps["w"]),
        laws={k: {kk: v for kk, v in b.items()} for k, b in laws.items()},
    )
    for name, block in laws.items():
        h = {}
        for cin in sorted({c for c, _ in OMCT_TESTS.values()}):
            for om in omegas:
                h[cin, om] = law_response(block, cin, om, amps[cin[0]])
                if progress:
                    progress()
        verdicts = out.fidelity_at_1_rad_s[name] = {}
        for test, (cin, cout) in OMCT_TESTS.items():
            resp = np.array([h[cin, om][cout] for om in omegas])
            phase = np.degrees(np.unwrap(np.angle(resp)))
            # the branch nearest 0 at the lowest frequency for the direct tests
            if cin == cout:
                phase -= 360.0 * round(phase[0] / 360.0)
            for om, r, ph in zip(omegas, resp, phase, strict=True):
                g = abs(r) * _edge(cin) / _edge(cout)
                row = OmctRow(name, test, cin, cout, float(om), float(om / (2 * math.pi)),
                              float(g), 20 * math.log10(max(g, 1e-300)), float(ph))  # fmt: skip
                out.rows.append(row)
                if cin == cout and abs(om - 1.0) < 1e-9:
                    verdicts[test] = Fidelity(float(g), float(ph), fidelity(g, ph))
    return out


def model_chain_metrics(block: Mapping, t: np.ndarray, f: np.ndarray, w: np.ndarray, *,
                        bound: bool = False) -> dict:  # fmt: skip
    """The cueing metrics (:func:`simpro_mj.analysis.cue_metrics.cue_metrics`) of a vehicle
    input ``t``, ``f``, ``w`` (V frame, SI, a uniform grid whose step divides into
    ``_DT``) through the same chain as the OMCT: the law of ``block`` (with its preview),
    the platform loop's model, a rigid cabin's head; with ``bound``, the bound with the
    block's own parameters too. The loop's valves and strokes are not modelled: the
    block's ``workspace`` is the set-points' and its ``valves`` say nothing (a run
    through the plant has them)."""
    from simpro_mj.analysis.cue_metrics import cue_metrics

    t = np.asarray(t, float)
    step = float(np.median(np.diff(t)))
    every = int(round(_DT / step))
    if every < 1 or abs(every * step - _DT) > 1e-9:
        raise ValueError(f"the input's step {step!r} s must divide {_DT} s")
    t, f, w = t[::every], np.asarray(f, float)[::every], np.asarray(w, float)[::every]
    law, _ = _law(block)
    pose, home = _poses(block, f, w)
    loop = _loop(pose, _DT)
    head = _head(loop, home, _DT)
    n = t.size
    cols: dict[str, np.ndarray] = {"time_s": t - t[0]}
    for k, a in enumerate("xyz"):
        cols[f"veh_f{a}_mps2"], cols[f"veh_w{a}_rad_s"] = f[:, k], w[:, k]
        cols[f"head_f{a}_mps2"] = head[f"f{a}"]
        cols[f"head_w{a}_rad_s"] = head[f"w{a}"] if a != "z" else np.zeros(n)
    cols["roll_rad"], cols["pitch_rad"], cols["heave_m"] = loop[:, 0], loop[:, 1], loop[:, 2]
    for i in (1, 2, 3):
        cols[f"q{i}_m"], cols[f"u{i}_v"] = np.full(n, 0.25), np.full(n, 5.0)
    info = {
        "box": law.box,
        "softened_fraction": 0.0,
        "rate_limited_fraction": 0.0,
        "source": "model chain",
        "algorithm": block["algorithm"],
    }
    return cue_metrics(cols, {"setpoint": {"cueing": dict(block)}}, info=info, bound=bound)
