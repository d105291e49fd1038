"""Closed-loop frequency response of the platform in the co-simulation (stepped sines).

For each task axis (roll, pitch, heave) and each frequency, one run of the
scenario with its set-point replaced by a small sine on that axis alone
(the other axes held at home): ``settle_s`` to let the start transient die,
then ``periods`` whole periods over which the set-point, the true pose and
the measured pose are fitted by least squares
(:func:`controllers.frequency.fit_sine`: offset, trend, cosine, sine). The
ratio of the fitted complex amplitudes is the response: on the excited axis
the closed-loop response, on the others the cross-axis coupling (a pitch
command moves heave through the mechanism and the unequal legs).

Frequencies
-----------
By default the twelve OMCT frequencies (ICAO 9625: 0.1 to 15.85 rad/s,
five per decade), each moved to the nearest period on the 1 ms physics grid
(at most 0.4 % away; the table gives the frequency used), plus 0.5 Hz and
1 Hz, where the summary's phases are read. Frequencies given by the user
must have periods on the grid (whole milliseconds): the fit is over whole
periods of whole samples. Every run is independent: they run in parallel
with the batch executors (:func:`simpro_mj.sim.executors.run_tasks`).

Prediction
----------
:func:`loop_model` reads the scenario's linearised loop (the joint
controllers as built, the plant the analysis uses: the linear actuator's
eq. 19 coefficients, or the identified plants ``controller.inner.identified``
for the nonlinear cylinders; the IK Jacobian at home; the IMU filter; the
outer law, gains and period) for :func:`controllers.frequency.predict`.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from controllers.frequency import CHAIN_CHANNELS, OMCT_RAD_S, fit_sine
from controllers.geometry import nominal_geometry
from controllers.kinematics import reachable
from simpro_mj.config.rules import MAX_DURATION_S
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.messages import one_line
from simpro_mj.sim.executors import Progress, run_tasks

AXES = ("roll", "pitch", "heave")
_SETPOINT_KEYS = ("roll_deg", "pitch_deg", "heave_mm")
#: Edge unit and its factor to SI per task axis and per vehicle channel (``response --chain``).
UNITS = {"roll": ("deg", math.pi / 180.0), "pitch": ("deg", math.pi / 180.0), "heave": ("mm", 1e-3)}
UNITS |= {c: ("m/s^2", 1.0) if c[0] == "f" else ("deg/s", math.pi / 180.0) for c in CHAIN_CHANNELS}
#: Small-signal amplitudes (edge units): well inside the valves' linear range.
DEFAULT_AMPLITUDES = {"roll": 0.5, "pitch": 0.5, "heave": 5.0}
#: Frequencies where the summary reads the phase (Hz); measured by default.
PHASE_POINTS_HZ = (0.5, 1.0)
MIN_PERIOD_MS = 20  # 50 Hz: above every loop of the platform
MAX_PERIOD_MS = 600_000
MAX_PERIODS = 100
MAX_SETTLE_S = 600.0


def default_periods_ms(extra_hz: Sequence[float] = PHASE_POINTS_HZ) -> list[int]:
    """OMCT frequencies on the 1 ms period grid, plus ``extra_hz`` (longest period first)."""
    periods = {int(round(2000.0 * math.pi / w)) for w in OMCT_RAD_S}
    return sorted(periods | {int(round(1000.0 / f)) for f in extra_hz}, reverse=True)


def in_edge(cin: str, cout: str, h):
    """An SI ratio from ``cin`` to ``cout`` in their edge units (:data:`UNITS`)."""
    return h * UNITS[cin][1] / UNITS[cout][1]


def db(gain: float) -> float:
    """``gain`` in dB (a zero gain as -6000 dB, finite for JSON)."""
    return 20 * math.log10(max(gain, 1e-300))


def dense_grid(omega: np.ndarray, n: int):
    """``n`` frequencies from ``omega.min() / 20`` (a prediction's phase unwraps from the
    low-frequency asymptote) to ``omega.max()`` with ``omega`` among them: the grid, the
    indices of ``omega`` in it, and the mask of the span between the measured ones."""
    dense = np.unique(np.r_[np.geomspace(omega.min() / 20, omega.max(), n), omega])
    span = (dense >= omega.min() * (1 - 1e-9)) & (dense <= omega.max() * (1 + 1e-9))
    return dense, np.searchsorted(dense, omega), span


def check_periods(freq_hz: Sequence[float], where: str = "--freq-hz") -> list[int]:
    """Periods (ms) of user frequencies; one-line :class:`UserInputError` otherwise."""
    out = []
    for f in freq_hz:
        allowed = (
            f"allowed: frequencies from {1000.0 / MAX_PERIOD_MS:g} to {1000.0 / MIN_PERIOD_MS:g} "
            "Hz whose period is a whole number of milliseconds (the 1 ms physics grid)"
        )
        if not (isinstance(f, (int, float)) and math.isfinite(f) and f > 0):
            raise UserInputError(f"invalid value at {where}: {f!r}; {allowed}")
        period = 1000.0 / f  # inf for a subnormal f: refused here, before round()
        if not MIN_PERIOD_MS <= period <= MAX_PERIOD_MS:
            raise UserInputError(f"invalid value at {where}: {f:g} Hz; {allowed}")
        k = round(period)
        if abs(period - k) > 1e-6 * period:
            raise UserInputError(
                f"invalid value at {where}: {f:g} Hz (period {period:.4f} ms is not on the 1 ms "
                f"grid); {allowed}, e.g. {1000.0 / k:.6g} Hz ({k} ms)"
            )
        out.append(int(k))
    if len(set(out)) != len(out):
        raise UserInputError(
            f"invalid value at {where}: a frequency given twice; allowed: distinct"
        )
    return sorted(out, reverse=True)


def _max_amplitude(axis: int, geometry) -> float:
    """Largest symmetric excursion (SI) from home on one axis inside the workspace."""
    home = np.asarray(geometry.home, float)
    lo, hi = 0.0, 1.0 if axis < 2 else 0.5  # rad, m: beyond the platform's reach
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        poses = np.array([home, home])
        poses[0, axis] += mid
        poses[1, axis] -= mid
        if reachable(poses, geometry).all():
            lo = mid
        else:
            hi = mid
    return lo


#: Smallest sine amplitude measured (edge units): a few steps of the 14-bit
#: potentiometers (500 mm / 2^14 = 0.03 mm) on the legs.
MIN_AMPLITUDES = {"roll": 0.01, "pitch": 0.01, "heave": 0.1}


def check_amplitudes(amplitudes: Mapping[str, float]) -> dict:
    """Amplitudes (edge units) -> SI per axis; beyond the workspace is a one-line error."""
    geometry = nominal_geometry()
    out = {}
    for j, axis in enumerate(AXES):
        unit, scale = UNITS[axis]
        where = "--amplitude-mm" if axis == "heave" else "--amplitude-deg"
        a = amplitudes[axis]
        limit = _max_amplitude(j, geometry) / scale
        low = MIN_AMPLITUDES[axis]
        if not (isinstance(a, (int, float)) and math.isfinite(a) and low <= a <= limit):
            raise UserInputError(
                f"invalid value at {where}: {a!r}; allowed: {low:g} <= amplitude <= {limit:.3g} "
                f"{unit} on {axis} (a sine about home inside the workspace, see simpro-sim "
                "workspace; a smaller one is lost in the potentiometers' 14-bit steps of 0.03 mm)"
            )
        out[axis] = a * scale
    return out


def check_settle_periods(settle_s, periods) -> None:
    """``--settle-s`` (0..600 s on the 1 ms grid) and ``--periods`` (1..100), one-line errors."""
    ok = isinstance(settle_s, (int, float)) and not isinstance(settle_s, bool)
    if not (ok and math.isfinite(settle_s) and 0 <= settle_s <= MAX_SETTLE_S) or (
        abs(settle_s * 1e3 - round(settle_s * 1e3)) > 1e-6
    ):
        raise UserInputError(
            f"invalid value at --settle-s: {settle_s!r}; allowed: 0..{MAX_SETTLE_S:g} s on the "
            "1 ms grid"
        )
    if isinstance(periods, bool) or not isinstance(periods, int) or not 1 <= periods <= MAX_PERIODS:
        raise UserInputError(
            f"invalid value at --periods: {periods!r}; allowed: an integer 1..{MAX_PERIODS}"
        )


def check_run_length(settle_s: float, periods: int, periods_ms: Sequence[int]) -> None:
    """The longest run (settle plus whole periods) within a scenario's longest duration."""
    longest = settle_s + periods * max(periods_ms) / 1000.0
    if longest > MAX_DURATION_S:
        raise UserInputError(
            f"invalid value at --periods: {periods} periods of {max(periods_ms)} ms after "
            f"{settle_s:g} s is a {longest:g} s run; allowed: runs up to {MAX_DURATION_S:g} s"
        )


@dataclass(frozen=True)
class SineTask:
    """One stepped sine (worker side): ``scenario`` with the sine on ``input`` (a task
    axis, or a vehicle channel for the chain) of ``period_ms``, run for ``settle_s`` and
    then the ``periods`` whole periods that are fitted."""

    scenario: dict
    input: str
    period_ms: int
    settle_s: float
    periods: int

    def window(self, dt: float) -> tuple[int, int]:
        """The rows ``k0:k1`` of the settled whole periods at step ``dt``."""
        k0 = int(round(self.settle_s / dt))
        return k0, k0 + int(round(self.periods * (self.period_ms / 1000.0) / dt))


class Outcome(NamedTuple):
    """A sine task's result: ``status``, ``reason`` and, when ``ok``, its ``fit``."""

    status: str
    reason: str | None = None
    fit: Any = None


class Failed(NamedTuple):
    """A sine task that did not run ``ok``: its input, period, status and reason."""

    input: str
    period_ms: int
    status: str
    reason: str | None

    def as_json(self, key: str) -> dict:
        """The entry of ``failed`` in the document, its input named ``key`` (axis, channel)."""
        return {key: self.input, "period_ms": self.period_ms, "status": self.status,
                "reason": self.reason}  # fmt: skip


def failures(tasks: Sequence[SineTask], results: Sequence[Outcome]) -> list[Failed]:
    """The tasks that did not run ``ok``."""
    return [
        Failed(t.input, t.period_ms, r.status, r.reason)
        for t, r in zip(tasks, results, strict=True)
        if r.status != "ok"
    ]


def fits(tasks: Sequence[SineTask], results: Sequence[Outcome]) -> dict:
    """The fits of the tasks that ran ``ok``, by (input, period_ms)."""
    ok = zip(tasks, results, strict=True)
    return {(t.input, t.period_ms): r.fit for t, r in ok if r.status == "ok"}


@dataclass
class SinePlan:
    """What :func:`measure` runs: one task per (input, period); ``inputs`` the task axes
    (:func:`plan_response`) or the vehicle channels (``plan_chain``)."""

    scenario: dict
    inputs: tuple
    periods_ms: list
    amplitudes: dict  # SI per input
    settle_s: float
    periods: int
    tasks: list[SineTask]


def sine_plan(scenario: Mapping, inputs, periods_ms, amplitudes: dict, settle_s: float,
              periods: int, scenario_of) -> SinePlan:  # fmt: skip
    """The plan of one task per input and period, ``scenario_of(input, period_ms)`` run
    for ``settle_s`` and ``periods`` whole periods, once the longest run is checked."""
    check_run_length(settle_s, periods, periods_ms)
    tasks = [
        SineTask(scenario_of(x, p), x, int(p), float(settle_s), int(periods))
        for x in inputs
        for p in periods_ms
    ]
    return SinePlan(copy.deepcopy(dict(scenario)), tuple(inputs), list(periods_ms), amplitudes,
                    float(settle_s), int(periods), tasks)  # fmt: skip


def plan_response(
    scenario: Mapping,
    *,
    periods_ms: Sequence[int] | None = None,
    amplitudes: Mapping[str, float] | None = None,
    axes: Sequence[str] = AXES,
    settle_s: float = 4.0,
    periods: int = 2,
) -> SinePlan:
    """Check the test's parameters and build its tasks (plain data for the workers)."""
    amps = dict(DEFAULT_AMPLITUDES)
    amps.update(amplitudes or {})
    amp_si = check_amplitudes(amps)
    check_settle_periods(settle_s, periods)
    for a in axes:
        if a not in AXES:
            raise UserInputError(f"invalid value at --axes: {a!r}; allowed: {list(AXES)}")
    periods_ms = default_periods_ms() if periods_ms is None else list(periods_ms)

    def run_of(a: str, p: int) -> dict:
        return point_scenario(scenario, a, p, amps[a], settle_s, periods)

    return sine_plan(scenario, axes, periods_ms, amp_si, settle_s, periods, run_of)


def point_scenario(
    scenario: Mapping, axis: str, period_ms: int, amplitude: float, settle_s: float, periods: int
) -> dict:
    """The scenario with a sine of ``amplitude`` (edge units) on ``axis`` alone, run for
    ``settle_s`` plus ``periods`` periods, logged every step, faults removed."""
    sine = {"type": "sine", "amplitude": float(amplitude), "period_s": period_ms / 1000.0,
            "phase_deg": 0.0, "start_s": 0.0, "end_s": None}  # fmt: skip
    excited = _SETPOINT_KEYS[AXES.index(axis)]
    setpoint = {key: [sine] if key == excited else [] for key in _SETPOINT_KEYS}
    return sine_run(scenario, setpoint, period_ms, settle_s, periods)


def sine_run(scenario: Mapping, setpoint: dict, period_ms: int, settle_s: float, periods: int):
    """``scenario`` with ``setpoint``, run for ``settle_s`` plus ``periods`` periods of
    ``period_ms``, logged every step, faults removed."""
    sc = copy.deepcopy(dict(scenario))
    return sc | {
        "setpoint": setpoint,
        "duration_s": round(settle_s + periods * period_ms / 1000.0, 3),
        "faults": [],
        "logging": dict(sc.get("logging") or {}, decimation=1),
    }


def saturated_pct(columns: Mapping, k0: int, k1: int) -> float:
    """The share (%) of the rows ``k0:k1`` with a valve at a rail (0 or 10 V)."""
    u = np.column_stack([columns[f"u{i}_v"][k0:k1] for i in (1, 2, 3)])
    return float(np.any((u <= 0.0) | (u >= 10.0), axis=1).mean() * 100.0)


def run_point(envelope: Mapping, fit) -> dict:
    """Run one sine task and ``fit(task, result)`` it (worker side): ``status``, ``reason``
    and, when ``ok``, the ``fit``; a failure is this frequency's, not the test's.

    ``envelope``: the executor's task, ``{"task": SineTask}`` and whatever the executor
    adds (the runs' ``stop`` token on threads, :func:`simpro_mj.sim.executors.run_tasks`).
    """
    # MuJoCo with the loop, when a point runs: analysis.analyze imports this room's
    # figures without running anything
    from simpro_mj.sim.build import simulate

    task: SineTask = envelope["task"]
    try:
        res = simulate(task.scenario, stop=envelope.get("stop"))
        if res.status != "ok":
            return {"status": res.status, "reason": res.reason}
        return {"status": "ok", "reason": None, "fit": fit(task, res)}
    except UserInputError as exc:
        return {"status": "invalid", "reason": one_line(exc)}
    except Exception as exc:  # noqa: BLE001
        return {"status": "failed", "reason": f"{type(exc).__name__}: {' '.join(str(exc).split())}"}


@dataclass
class PoseFit:
    """A pose sine's fit over its settled whole periods (:func:`measure_point`), SI, each
    complex amplitude as ``[re, im]``: the set-point's ``ref``, the ``true`` and
    ``measured`` poses' (three outputs each); ``saturated_pct`` the share of the fitted
    steps with a valve at a rail."""

    ref: list
    true: list
    measured: list
    saturated_pct: float


def _fit_pose(task: SineTask, res) -> PoseFit:
    c = res.columns
    k0, k1 = task.window(res.sim["timestep_s"])
    t = c["time_s"][k0:k1]
    w = 2.0 * math.pi / (task.period_ms / 1000.0)
    ref_col = ("roll_ref_rad", "pitch_ref_rad", "heave_ref_m")[AXES.index(task.input)]
    true = np.column_stack([c[k][k0:k1] for k in ("roll_rad", "pitch_rad", "heave_m")])
    meas = np.column_stack(
        [c[k][k0:k1] for k in ("roll_meas_rad", "pitch_meas_rad", "heave_meas_m")]
    )
    r = fit_sine(t, c[ref_col][k0:k1], w)
    yt, ym = fit_sine(t, true, w), fit_sine(t, meas, w)
    return PoseFit(
        [r.real, r.imag],
        [[v.real, v.imag] for v in np.atleast_1d(yt)],
        [[v.real, v.imag] for v in np.atleast_1d(ym)],
        saturated_pct(c, k0, k1),
    )


def measure_point(envelope: Mapping) -> dict:
    """Run one stepped sine and fit it (worker side; top level, pickles by name): a
    :class:`PoseFit` when ``ok`` (:func:`run_point`)."""
    return run_point(envelope, _fit_pose)


def measure(
    plan,
    *,
    jobs: int = 1,
    scheduler=None,
    progress: bool = False,
    fn=None,
    desc: str = "response",
) -> list:
    """Run every task of ``plan``; results in task order (``fn``, default :func:`measure_point`;
    a top-level function, it pickles by name)."""

    fn = measure_point if fn is None else fn
    results = [Outcome("cancelled", "not run")] * len(plan.tasks)
    bar = Progress(len(plan.tasks), progress, desc=desc)

    def done(key: int, result: dict) -> None:
        results[key] = Outcome(result.get("status", "failed"), result.get("reason"),
                               result.get("fit"))  # fmt: skip
        bar.update(results[key].status)

    tasks = [(k, {"task": t}) for k, t in enumerate(plan.tasks)]
    try:
        run_tasks(tasks, done, jobs=jobs, scheduler=scheduler, fn=fn)
    finally:
        bar.close()
    return results
