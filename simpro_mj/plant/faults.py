"""Faults scheduled by a scenario: supply drop, stuck valve, sensor faults.

A scenario's ``faults`` list (validated by :mod:`simpro_mj.config.scenario`, which
also documents the keys) becomes a :class:`FaultSchedule`: the fault times on
the physics-step grid and the little state the faults need. The schedule is
event driven so that a run without faults pays nothing, and a run with faults
pays a comparison per step plus small array operations only while a fault
acts.

What each fault does
--------------------
``supply_drop``
    The supply pressure p_s of all three valves falls from the nominal
    ``actuator.pneumatics.supply_pressure_bar_gauge`` to
    ``pressure_bar_gauge`` (gauge; absolute inside), linearly over ``ramp_s``
    (0: at once), and stays there. Several drops: the lowest value wins.
    Chambers above the new p_s are bounded to it by the pneumatic model (the
    MPYE lets the excess flow back into the supply line), so the platform
    sinks under its weight onto the lower end stops when p_s A_cap cannot hold
    it any more.
``valve_stuck``
    Valve ``leg`` stays at ``voltage_v`` whatever the controller commands,
    from ``time_s`` to ``end_s`` (null: to the end). The controller is not
    told: its own state (integrator, anti-windup) sees its own command.
``sensor_frozen``
    The reading delivered at ``time_s`` is repeated until ``end_s``.
``sensor_dropout``
    Each sample of the sensor (at its own rate) is lost with ``probability``;
    a lost sample is not delivered, so the controller keeps the last
    delivered value (zero-order hold, as the rig's real-time loop does when a
    serial IMU or encoder frame is missing). The draws come from a generator
    seeded by the scenario's ``seed`` (its own stream: the sensor noise is the
    same with and without faults).
``sensor_bias``
    ``bias_mm`` (potentiometer: on the slide reading; height encoder: on h) or
    ``bias_deg`` (IMU roll and/or pitch) is added to the delivered reading.
``potentiometer_failure``
    The potentiometer of ``leg`` reads a rail: ``open`` (wiper lifted, input
    pulled to 0 V) reads 0 V = 0 mm, the fully retracted end; ``short``
    (wiper on the feed) reads the 10 V feed = 500 mm, clipped to the ADC's
    top code. The controller converts it with the nominal scale as any reading.

On one channel the faults act in this order: potentiometer failure (the
electrical reading), frozen, dropout, bias.

How the co-simulation loop uses it (``simpro_mj.sim.loop``)
------------------------------------------------------
:meth:`CoSimulation.run <simpro_mj.sim.loop.CoSimulation.run>` builds the schedule
only if the scenario's ``faults`` is not empty; such a run steps from Python (the
compiled stages when numba is there) and :class:`simpro_mj.sim.stages.FaultHooks`
acts between the stages: at an event step :meth:`FaultSchedule.at_event` (a
changed ``supply_pa`` to the actuators' state, ``flags`` and ``supply_pa`` to the
log); while ``sensor_active`` :meth:`FaultSchedule.apply_sensors` on what the
controllers see (the sensors' own state untouched); while ``valve_active``
:meth:`FaultSchedule.apply_valves` on the joint loops' command (the controllers
keep their own).

A fault at ``time_s`` thus acts from the step ``round(time_s / dt)`` on
(t >= time_s). The log holds the applied voltages (``u*_v``), what the
controllers saw (``q*_meas_m``, ``*_meas_*``) and the two columns of
:data:`FAULT_COLUMNS`: ``fault_flags`` and ``supply_pa``.

*Supply pressure at run time.* The step's actuator state holds p_s
(``ps`` of :data:`simpro_mj.plant.step_functions.ACT`, set at an event by
:class:`simpro_mj.sim.stages.FaultHooks`), which the nonlinear chamber update
reads every step (supply term of the implicit pressure update, the supply
edge's pressure ratio); ``params.p_supply`` (a frozen dataclass) is not read
after construction. The linear model (eq. 19) has no supply in its law; its
force bounds follow p_s. (The MJCF motors are not ``ctrllimited``: the
pneumatic model alone bounds the forces.)

Flags
-----
``flags`` is a bit mask of the fault types acting at the step
(:data:`FLAG_BITS`: supply_drop 1, valve_stuck 2, sensor_frozen 4,
sensor_dropout 8, sensor_bias 16, potentiometer_failure 32); logged as the
column ``fault_flags`` (a float in the CSV, exact for these integers).
:func:`flag_series` gives the same mask from the scenario alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # the typed scenario, read by attribute; the plant does not import it
    from simpro_mj.config.models import Scenario

#: Bit of each fault type in ``fault_flags``: supply_drop 1, valve_stuck 2, ..., 32.
_KINDS = "supply_drop valve_stuck sensor_frozen sensor_dropout sensor_bias potentiometer_failure"
FLAG_BITS = {k: 1 << i for i, k in enumerate(_KINDS.split())}
#: Time-series columns a run with faults adds (flags; supply pressure, Pa absolute).
FAULT_COLUMNS = ("fault_flags", "supply_pa")
#: ``next_event`` when nothing is left to happen (never equal to a step number).
NEVER = -1

# measurement channels: q1, q2, q3 (slides, m), roll, pitch (rad), h (m)
_POT = (0, 1, 2)
_IMU = {"roll": (3,), "pitch": (4,), None: (3, 4)}
_ENC = (5,)
_SEED_TAG = 0x46A017  # a fault stream of its own, independent of the sensor noise


@dataclass(frozen=True)
class FaultChanges:
    """What changed at an event step.

    Attributes
    ----------
    supply_pa : float or None
        The supply pressure to apply from this step on (Pa absolute), or None
        if it did not change.
    valves : bool
        The stuck-valve state changed (``FaultSchedule.valve_active``,
        ``valve_mask``, ``valve_values``).
    sensors : bool
        The set of acting sensor faults changed.
    flags : int
        The fault bit mask from this step on.
    """

    supply_pa: float | None
    valves: bool
    sensors: bool
    flags: int


def _steps(t: float, dt: float) -> int:
    return int(round(t / dt))


def _channels(f: Any) -> tuple[int, ...]:
    if f.type == "potentiometer_failure":
        return (f.leg - 1,)
    if f.sensor == "potentiometer":
        return _POT if f.leg is None else (f.leg - 1,)
    if f.sensor == "imu":
        return _IMU[f.axis]
    return _ENC


@dataclass(eq=False, slots=True)
class _SensorFault:
    """One sensor fault: channels, window and its state."""

    kind: str
    chans: np.ndarray
    k0: int
    k1: int
    every: int  # the sensor's sample period, steps (dropout draws)
    value: Any = None  # bias (SI) or rail reading; frozen: captured at k0
    drops: Any = None  # dropout: bool per step of the window
    dropping: bool = False
    last: Any = None  # dropout: last delivered values


class FaultSchedule:
    """Fault events on the physics-step grid, and what they do to the loop.

    Parameters
    ----------
    scenario : Scenario
        The resolved, typed scenario: its ``faults`` (:mod:`simpro_mj.config.entries`),
        duration, supply pressure, sensors (rates for dropout, potentiometer scale for
        the rails) and seed (dropout draws, on a stream of their own).
    dt : float
        Physics step (s); events after the run's last step are dropped.

    Attributes
    ----------
    events : ndarray of int
        Sorted step numbers at which something starts, ends or ramps.
    next_event : int
        The next of ``events`` not yet processed, :data:`NEVER` when none is left.
    flags : int
        Bit mask (:data:`FLAG_BITS`) of the faults acting now.
    supply_pa : float
        The supply pressure now (Pa absolute).
    valve_active, sensor_active : bool
        Whether :meth:`apply_valves` / :meth:`apply_sensors` must be called.
    valve_mask : ndarray of bool (3,)
    valve_values : ndarray (3,)
        Stuck legs and their voltages (V).
    """

    def __init__(self, scenario: Scenario, dt: float):
        params = scenario.actuator.pneumatics.params()
        self.dt = float(dt)
        self.n_steps = int(round(scenario.duration_s / dt))
        self.nominal_supply_pa, self.p_atm = params.p_supply, params.p_atm
        sensors = scenario.sensors
        rng = np.random.default_rng(np.random.SeedSequence([int(scenario.seed), _SEED_TAG]))
        end = self.n_steps + 1
        events: set[int] = set()

        # supply drops: (k0, ramp steps, target Pa)
        self._drops: list[tuple[int, int, float]] = []
        # stuck valves: (k0, k1, leg index, volts)
        self._valves: list[tuple[int, int, int, float]] = []
        self._sensor_faults: list[_SensorFault] = []
        self._windows: list[tuple[int, int, int]] = []  # (k0, k1, flag) of every fault

        pot = sensors.potentiometer
        lsb_v = 2.0 * pot.range_v / 2**pot.bits
        # rails as slide readings (m) through the nominal scale; the feed is the
        # potentiometer's full-stroke voltage (500 mm), clipped to the ADC's top code
        short = min(pot.volts_per_mm * 500.0, pot.range_v - lsb_v) / pot.volts_per_mm * 1e-3
        rails = {"open": 0.0, "short": short}

        faults: list[Any] = scenario.faults  # each read by the keys of its type
        for f in faults:
            kind = f.type
            k0 = _steps(f.time_s, dt)
            k1 = end if getattr(f, "end_s", None) is None else _steps(f.end_s, dt)
            if k0 > self.n_steps:
                continue
            self._windows.append((k0, k1, FLAG_BITS[kind]))
            events.add(k0)
            if k1 <= self.n_steps:
                events.add(k1)
            if kind == "supply_drop":
                ramp = max(0, _steps(f.ramp_s, dt))
                target = self.p_atm + f.pressure_bar_gauge * 1e5
                self._drops.append((k0, ramp, target))
                events.update(range(k0 + 1, min(k0 + ramp, self.n_steps) + 1))
            elif kind == "valve_stuck":
                self._valves.append((k0, k1, f.leg - 1, float(f.voltage_v)))
            else:
                sensor = "potentiometer" if kind == "potentiometer_failure" else f.sensor
                every = max(1, _steps(getattr(sensors, sensor).rate_ms * 1e-3, dt))
                fault = _SensorFault(kind, np.array(_channels(f)), k0, k1, every)
                if kind == "sensor_bias":
                    fault.value = (
                        f.bias_mm * 1e-3 if f.bias_deg is None else math.radians(f.bias_deg)
                    )
                elif kind == "potentiometer_failure":
                    fault.value = rails[f.mode]
                elif kind == "sensor_dropout":
                    fault.drops = rng.random(max(min(k1, end) - k0, 0)) < float(f.probability)
                self._sensor_faults.append(fault)
        # the order on a channel: failure, frozen, dropout, bias
        order = {"potentiometer_failure": 0, "sensor_frozen": 1, "sensor_dropout": 2}
        self._sensor_faults.sort(key=lambda s: order.get(s.kind, 3))

        self.events = np.array(sorted(events), dtype=np.int64)
        self._i = 0
        self.next_event = int(self.events[0]) if self.events.size else NEVER
        self.flags = 0
        self.supply_pa = self.nominal_supply_pa
        self.valve_active = False
        self.sensor_active = False
        self.valve_mask = np.zeros(3, dtype=bool)
        self.valve_values = np.zeros(3)
        self._acting: list[_SensorFault] = []

    # ------------------------------------------------------------------ events
    def _supply_at(self, k: int) -> float:
        p = self.nominal_supply_pa
        for k0, ramp, target in self._drops:
            if k < k0:
                continue
            frac = 1.0 if ramp == 0 else min(1.0, (k - k0) / ramp)
            p = min(p, self.nominal_supply_pa + (target - self.nominal_supply_pa) * frac)
        return p

    def at_event(self, k: int) -> FaultChanges:
        """Bring the state to step ``k`` (an event step) and say what changed."""
        while self._i < self.events.size and self.events[self._i] <= k:
            self._i += 1
        self.next_event = int(self.events[self._i]) if self._i < self.events.size else NEVER

        flags = 0
        for k0, k1, bit in self._windows:
            if k0 <= k < k1:
                flags |= bit
        supply = self._supply_at(k)
        supply_changed = supply != self.supply_pa
        self.supply_pa = supply

        mask = np.zeros(3, dtype=bool)
        values = np.zeros(3)
        for k0, k1, leg, volts in self._valves:  # a later entry wins on the same leg
            if k0 <= k < k1:
                mask[leg] = True
                values[leg] = volts
        valves_changed = bool(
            np.any(mask != self.valve_mask) or np.any(values != self.valve_values)
        )
        self.valve_mask, self.valve_values = mask, values
        self.valve_active = bool(mask.any())

        acting = [s for s in self._sensor_faults if s.k0 <= k < s.k1]
        sensors_changed = [id(s) for s in acting] != [id(s) for s in self._acting]
        for s in acting:
            if s not in self._acting and s.kind == "sensor_frozen":
                s.value = None  # captured at its first step (apply_sensors)
        self._acting = acting
        self.sensor_active = bool(acting)
        self.flags = flags
        return FaultChanges(
            supply_pa=supply if supply_changed else None,
            valves=valves_changed,
            sensors=sensors_changed,
            flags=flags,
        )

    # ------------------------------------------------------------------ hooks
    def apply_valves(self, u):
        """Valve voltages with the stuck legs replaced.

        Returns a new array; ``u`` itself is left alone.
        """
        out = np.array(u, dtype=float)
        np.copyto(out, self.valve_values, where=self.valve_mask)
        return out

    def apply_sensors(self, k: int, q_meas, pose_meas):
        """The readings the controller receives at step ``k``.

        Returns new arrays; the inputs are left alone.

        Parameters
        ----------
        k : int
            Physics step.
        q_meas : array (3,)
            Slide readings of the potentiometers (m).
        pose_meas : array (3,)
            (roll rad, pitch rad, h m) as measured.
        """
        y = np.concatenate((q_meas, pose_meas))
        for s in self._acting:
            c = s.chans
            if s.kind == "potentiometer_failure":
                y[c] = s.value
            elif s.kind == "sensor_frozen":
                if s.value is None:
                    s.value = y[c].copy()
                y[c] = s.value
            elif s.kind == "sensor_dropout":
                if s.last is None or k == s.k0:
                    s.last = y[c].copy()  # the sample at the start is delivered
                    s.dropping = False
                elif k % s.every == 0:  # the sensor's own sample instants
                    i = k - s.k0
                    s.dropping = bool(s.drops[i]) if i < s.drops.size else False
                if s.dropping:
                    y[c] = s.last
                else:
                    s.last = y[c].copy()
            else:  # sensor_bias
                y[c] += s.value
        return y[:3], y[3:]


def fault_intervals(scenario: Scenario) -> list[tuple[str, float, float]]:
    """``(type, start_s, end_s)`` of each fault of a typed scenario (end: its ``end_s``
    or the run's end)."""
    out: list[tuple[str, float, float]] = []
    for f in scenario.faults:
        end = getattr(f, "end_s", None)
        out.append((f.type, f.time_s, scenario.duration_s if end is None else end))
    return out


def flag_series(scenario: Scenario, t) -> np.ndarray:
    """The ``fault_flags`` mask at times ``t`` (s) from the typed scenario alone (int array)."""
    t = np.asarray(t, dtype=float)
    out = np.zeros(t.shape, dtype=np.int64)
    for kind, start, end in fault_intervals(scenario):
        on = t >= start - 1e-12
        if end < scenario.duration_s:
            on &= t < end - 1e-12
        out[on] |= FLAG_BITS[kind]
    return out
