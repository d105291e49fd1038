"""A live session: the co-simulation paced to the wall clock, driven over UDP.

What a motion-rig driver (FlyPT Mover, SimTools) does, with the simulated
platform in place of the rig: a game's telemetry comes in as UDP datagrams
(:mod:`simpro_mj.config.datagrams`), the cueing law turns it into set-points
as the samples arrive, the loop steps the plant in chunks at the pace of the
wall clock, and the platform's pose goes out as UDP text lines.

The session talks to the co-simulation through its live interface only
(:mod:`simpro_mj.sim.loop`, "Set-points from outside"): a
``Build(scenario, setpoints="external").simulation()``, whose set-point rows
:class:`Pacer` writes with ``write_setpoints`` and whose ``run(pace=...)``
calls :class:`Pacer` between chunks.

One chunk
---------
Every ``chunk`` steps (the greatest common divisor of the washout period and
the send period: 10 ms by default) the pacer, called before step ``k``:

1. waits until the chunk's deadline ``D(k) = wall0 + k dt`` (absolute, from
   one anchor: no drift accumulates from sleeping), and records how late it
   woke: ``lateness(k) = max(0, woke - D(k))``. A chunk that finished after
   ``D(k)`` (the state at ``t_k`` was not ready at wall time ``t_k``) is a
   missed deadline, and the next chunk starts at once;
2. every send period, sends the newest logged pose (:class:`PoseSender`): the
   state at ``t_k``, stepped before the wake, goes out first;
3. reads every datagram waiting (at most :data:`~simpro_mj.sim.udp.MAX_DRAIN` a chunk, the rest
   stays for the next one), skipping and counting the bad and the late ones;
4. every washout period, steps the washout once with the newest sample
   (held; faded to rest when stale, :class:`Receiver`) and writes the
   set-point for the next period;
5. every output period, the rig's string; every second, one console line.

The loop then runs the chunk's steps without looking outside: the
simulation is ahead of the wall clock by up to one chunk, and an input
reaches the set-points within one washout period of its arrival.

The clock is anchored after the first chunk (which loads the compiled
kernels), when the readiness file is written. A session that falls more
than :data:`MAX_BEHIND_S` behind (the machine stalled it) moves its anchor
instead of running the backlog at full speed: the time lost is counted
(``resyncs``, and in ``drift_ms``), the session goes on in real time.
"""

from __future__ import annotations

import gc
import math
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from controllers.cue_mpc_params import MpcParams
from controllers.mpc_cueing import MpcStream  # the module loads osqp on use
from controllers.washout import ClassicalWashout, WashoutParams
from simpro_mj.config.models import Scenario, as_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.plant.faults import NEVER
from simpro_mj.sim.cue_worker import CueWorker
from simpro_mj.sim.readiness import signal_ready
from simpro_mj.sim.scheduling import (
    cpu_split,
    frozen_gc,
    pinned,
    realtime_scheduling,
    thread_switches,
)
from simpro_mj.sim.udp import DEFAULT_POSE_FORMAT, PoseSender, Receiver, pose_columns, spread

if TYPE_CHECKING:
    from simpro_mj.sim.result import SimResult
    from simpro_mj.sim.rig_output import RigTemplate

#: Behind the wall clock by more than this (s), the session re-anchors its clock.
MAX_BEHIND_S = 0.1
#: Once the input is stale, the set-point is blended to home over this (s), and back to
#: the law's when samples come again (:class:`Pacer`). 1.5 s keeps the blend of a set-point
#: held at the MPC box's largest tilt (roll 11.3 deg) within its 15 deg/s and 30 deg/s^2.
HOME_S = 1.5


@dataclass
class LiveOptions:
    """What a live session is asked (``simpro-sim live``'s options, checked)."""

    listen: tuple[str, int]
    fmt: str = "outsim"
    send: tuple[str, int] | None = None
    send_rate_hz: float = 100.0
    send_format: str = DEFAULT_POSE_FORMAT
    #: input older than this (s) is stale: held until then, then faded to rest while the
    #: set-point is blended home (:data:`HOME_S`)
    stale_after_s: float = 0.3
    #: the fade from the last sample to the vehicle at rest (s): as long as the blend home,
    #: so that the law's own way back (part of the set-point until the blend ends) is no
    #: harsher than its cue (a 0.5 s fade doubles its acceleration on the way)
    fade_s: float = 1.5
    rt: bool = False
    #: with 2+ cores allowed: the pacing thread on the last, the cueing law's process on
    #: the others (:func:`cpu_split`), so that a solve never holds the pacer's core
    pin: bool = True
    #: sleep until this long (s) before a deadline, then spin to it (0: sleep to it)
    spin_s: float = 0.0
    #: a rig's output string (:mod:`simpro_mj.sim.rig_output`): where, what, how often
    output: str | None = None
    output_template: RigTemplate | None = None
    output_rate_hz: float = 100.0
    #: input conditioning (controllers.conditioning): bias time constant (s), vibration
    #: corner (Hz); 0 leaves the stage out
    bias_tau_s: float = 0.0
    vibration_hz: float = 0.0


@dataclass
class _Stats:
    lateness_s: np.ndarray
    compute_s: np.ndarray
    n: int = 0
    missed: int = 0
    resyncs: int = 0
    lost_s: float = 0.0
    stale_s: float = 0.0
    washout_steps: int = 0
    rate_limited: int = 0
    softened: int = 0


class Pacer:
    """The ``pace`` callback of ``CoSimulation.run`` for a live session (module docstring).

    Parameters
    ----------
    sim : CoSimulation
        Built with ``setpoints="external"``.
    receiver : Receiver
    washout : ClassicalWashout
    wash_every, send_every : int
        The washout and send periods in steps.
    sender : PoseSender, optional
    say : callable(str), optional
        The console (one line a second); None: silent.
    spin_s : float
        Sleep until this long before a deadline, then spin to it (0: sleep to it).
        A wake-up late by less than this (timer slack, an idle core's exit from its
        sleep state) is absorbed, at the price of that share of a core.
    clock, sleep : callables
        ``time.perf_counter`` and ``time.sleep`` (replaceable in tests).
    """

    def __init__(self, sim, receiver: Receiver, washout: ClassicalWashout | MpcStream | CueWorker,
                 *, wash_every: int, send_every: int, sender: PoseSender | None = None, say=None,
                 rig=None, rig_every: int | None = None, conditioner=None, spin_s: float = 0.0,
                 clock=time.perf_counter, sleep=time.sleep):  # fmt: skip
        self.sim, self.rx, self.washout, self.sender, self.say = sim, receiver, washout, sender, say
        self.dt, self.n = sim.dt, sim.n_steps
        self.wash_every, self.send_every = wash_every, send_every
        self.rig, self.rig_every = rig, rig_every or send_every
        self.conditioner = conditioner
        self.chunk = math.gcd(math.gcd(wash_every, send_every), self.rig_every)
        self.clock, self.sleep, self.spin = clock, sleep, float(spin_s)
        size = self.n // self.chunk + 2
        self.stats = _Stats(lateness_s=np.zeros(size), compute_s=np.zeros(size))
        self.wall0: float | None = None  # the anchor: D(k) = wall0 + k dt
        self.start_wall: float | None = None  # the first anchor (drift is measured from it)
        self.end_wall: float | None = None
        self._left: float | None = None  # when the last chunk was handed to the loop
        self._ones = np.ones((wash_every, 1))
        self.home = np.asarray(washout.geometry.home, float)
        self._home_weight = 1.0  # at home until samples come (a soft start)
        self._last_console = 0
        c = pose_columns()  # the pose in a logged row, for the console
        self._pose = [c[name] for name in ("roll_rad", "pitch_rad", "heave_m")]
        #: the collector's passes per generation from the anchor on (filled by
        #: :func:`frozen_gc` in a session; None: not counted, nothing frozen)
        self.gc_counts: list | None = None
        self._switches: list = [None, None]  # the pacing thread's, at the anchor and the end

    def __call__(self, k: int, log) -> int:
        now = self.clock()
        st = self.stats
        if self.wall0 is None and k > 0:
            # the first chunk has loaded the compiled kernels: out of the collector's way
            # with the rest, then the clock starts here
            if self.gc_counts is not None:
                gc.collect()
                gc.freeze()
                self.gc_counts[:] = [0] * len(self.gc_counts)
                now = self.clock()
            self._switches[0] = thread_switches()
            self.wall0 = self.start_wall = now - k * self.dt
            host, port = self.rx.address
            signal_ready(f"listening@{host}:{port}")
        if self.wall0 is not None:
            if self._left is not None:  # the loop's time on the chunk just stepped
                st.compute_s[st.n] = now - self._left
            deadline = self.wall0 + k * self.dt
            if now < deadline:
                if self.spin <= 0.0:
                    self.sleep(deadline - now)
                    now = self.clock()
                else:  # sleep to the margin, then spin: a late wake-up within it is absorbed
                    if deadline - now > self.spin:
                        self.sleep(deadline - now - self.spin)
                    clock = self.clock
                    now = clock()
                    while now < deadline:
                        now = clock()
            elif now > deadline:
                st.missed += 1
            late = now - deadline
            st.lateness_s[st.n] = max(0.0, late)
            st.n += 1
            if late > MAX_BEHIND_S:  # stalled: go on in real time from here
                self.wall0 += late
                st.resyncs += 1
                st.lost_s += late
        # the pose of t_k (logged before the wake) goes out first, at D(k)
        if self.sender is not None and k % self.send_every == 0 and len(log) and k < self.n:
            self.sender.send(log[-1].tolist())
        rx = self.rx
        rx.poll(now)
        if k % self.wash_every == 0:
            f, w, stale = rx.sample(now)
            if self.conditioner is not None:  # bias and vibration out, before the law
                f, w = self.conditioner.step(f, w)
            if stale and self.wall0 is not None and k < self.n:
                st.stale_s += self.wash_every * self.dt
            pose = self._homed(self.washout.step(f, w), stale)
            st.washout_steps += 1
            st.rate_limited += self.washout.last_rate_limited
            st.softened += self.washout.last_softened
            ones = self._ones
            self.sim.write_setpoints(k, ones * pose, ones * f, ones * w)
        if k >= self.n:  # the last step: its row is written, the session ends with it
            self.end_wall = now
            self._switches[1] = thread_switches()
            return NEVER
        if self.rig is not None and k % self.rig_every == 0 and len(log):
            self.rig.send(log[-1].tolist())
        if self.say is not None and k - self._last_console >= 1000 and len(log):
            self._last_console = k
            self.say(self._console_line(k, log[-1]))
        if self.wall0 is not None:
            self._left = self.clock()
        return k + self.chunk

    def _homed(self, pose, stale: bool) -> np.ndarray:
        """The law's set-point blended with home: weight 1 (home) while the input is
        stale, 0 (the law's) while samples come, moving between them over
        :data:`HOME_S` along a smootherstep ``a = w^3 (10 - 15 w + 6 w^2)``: no jump in
        position, rate or acceleration. The blend's own rate and acceleration are at
        most ``15/8 D / HOME_S`` and ``10/sqrt(3) D / HOME_S^2`` for a set-point ``D``
        from home: 14.1 deg/s and 28.9 deg/s^2 at the MPC box's largest roll (11.3 deg).

        Why: a law's state need not return home by itself when the input rests (a
        felt-force error state left by a biased drive moves it for seconds), and
        waiting for the input's fade to end before going home leaves the platform off
        home ``stale_after + fade + HOME_S`` after the last sample. Blending from the
        moment the input goes stale puts the set-point home ``stale_after + HOME_S``
        after it (1.8 s by default), whatever the law. A short gap in the feed barely
        moves it: 50 ms of staleness is a weight of 4e-4."""
        step = self.wash_every * self.dt / HOME_S
        target = 1.0 if stale else 0.0
        w = self._home_weight
        w = min(target, w + step) if target > w else max(target, w - step)
        self._home_weight = w
        a = w * w * w * (10.0 + w * (6.0 * w - 15.0))
        if a == 0.0:
            return pose
        return (1.0 - a) * np.asarray(pose, float) + a * self.home

    def _console_line(self, k: int, row) -> str:
        st = self.stats
        recent = st.lateness_s[max(0, st.n - 1000 // self.chunk) : st.n]
        p99 = float(np.percentile(recent, 99)) * 1e6 if recent.size else 0.0
        rx = self.rx
        roll, pitch, heave = (row[j] for j in self._pose)
        _, _, stale = rx.sample(self.clock())
        return (
            f"live t {k * self.dt:7.2f} s | roll {math.degrees(roll):+6.2f} "
            f"pitch {math.degrees(pitch):+6.2f} deg heave "
            f"{(heave - self.washout.geometry.home[2]) * 1e3:+6.1f} mm | late p99 "
            f"{p99:6.0f} us missed {st.missed} | rx {rx.received} bad {rx.bad} late {rx.late}"
            + (" | input stale" if stale else "")
        )

    def realtime(self, steps: int) -> dict:
        """The ``realtime`` block of ``metrics.json`` after the run stopped at ``steps``."""
        st = self.stats
        lat = st.lateness_s[: st.n] * 1e6
        busy = st.compute_s[1 : st.n] * 1e6  # from the second deadline on: one chunk each
        end = self.end_wall if self.end_wall is not None else self.clock()
        drift = None
        if self.start_wall is not None:
            drift = (steps * self.dt - (end - self.start_wall)) * 1e3
        out = {
            "lateness_us": spread(lat),
            "deadlines": int(st.n),
            "chunk_compute_us": spread(busy),
            "missed_deadlines": int(st.missed),
            "chunk_steps": self.chunk,
            "drift_ms": drift,
            "resyncs": int(st.resyncs),
            "lost_s": float(st.lost_s),
            "packets": self.rx.counts(),
            "stale_s": float(st.stale_s),
        }
        if self.gc_counts is not None:
            out["gc_collections"] = list(self.gc_counts)
        begin, end = self._switches
        if begin is not None and end is None:  # ended by a signal: the figures are now
            end = thread_switches()
        if begin is not None and end is not None:  # the pacing thread's, anchor to end
            out["pacer_switches"] = {
                "voluntary": end[0] - begin[0],
                "involuntary": end[1] - begin[1],
            }
        if self.sender is not None:
            out["pose_sent"] = {"datagrams": self.sender.sent, "errors": self.sender.errors}
        if self.rig is not None:
            out["rig_out"] = {"strings": self.rig.sent, "errors": self.rig.errors}
        return out

    def lateness(self) -> dict:
        """Each deadline's simulated time and lateness (``realtime.npz`` of the folder)."""
        st = self.stats
        return {
            "time_s": (np.arange(st.n) + 1) * self.chunk * self.dt,
            "lateness_us": st.lateness_s[: st.n] * 1e6,
            "chunk_compute_us": st.compute_s[: st.n] * 1e6,
        }

    def washout_info(self) -> dict:
        """What the cueing figures need of the washout as it ran (box, limit fractions)."""
        st, w = self.stats, self.washout
        m = max(st.washout_steps, 1)
        return {
            "box": {k: list(map(float, v)) if k != "scale" else v for k, v in w.box.items()},
            "rate_limited_fraction": st.rate_limited / m,
            "softened_fraction": st.softened / m,
        }


@dataclass
class Session:
    """What a live session returns (:func:`run_session`)."""

    #: the result (status ``interrupted`` when a signal ended it)
    result: SimResult
    #: the ``realtime`` block of ``metrics.json`` (:meth:`Pacer.realtime`)
    realtime: dict
    #: the law's figures as it ran (:meth:`Pacer.washout_info`, the law's ``algorithm``
    #: and, for the MPC, its ``solve_time``): the cueing metrics' ``info``
    washout: dict
    #: each deadline's lateness (:meth:`Pacer.lateness`)
    lateness: dict
    #: where the telemetry came to
    address: tuple[str, int]


def run_session(scenario: Scenario | Mapping, options: LiveOptions, say=None,
                checks=None) -> Session:  # fmt: skip
    """Run one live session of a resolved cueing scenario (``duration_s`` long).

    The socket is bound before anything heavy is built, so that a busy port is
    refused at once; ``checks()`` (the preflight) runs next.
    """
    sc = as_scenario(scenario)
    cue = sc.setpoint.cueing
    if cue is None:
        raise UserInputError(
            "invalid value at setpoint.cueing: a live session needs a cueing scenario (the "
            "vehicle input drives the washout); allowed: e.g. cue_braking.yaml"
        )

    def chose(name: str) -> None:
        if say is not None:
            say(f"live: --format auto: the datagrams are {name}")

    rx = Receiver(options.listen, options.fmt, options.stale_after_s, options.fade_s, chose)
    if say is not None:
        say(
            f"live: {sc.name}, {options.fmt} datagrams at {rx.address[0]}:"
            f"{rx.address[1]}, {sc.duration_s:g} s (Ctrl-C ends it, the result is kept)"
        )
    sender = rig = law = None
    try:
        # on use, once the port is ours: scipy's filter design and MuJoCo take seconds
        from simpro_mj.config.cue_params import washout_params
        from simpro_mj.core.rates import steps_per_period
        from simpro_mj.sim.build import Build

        if checks is not None:
            checks()
        params = washout_params(cue)
        mpc = cue.algorithm == "mpc"
        if isinstance(params, MpcParams) and params.preview > 0 and say is not None:
            say(
                f"live: setpoint.cueing.parameters.preview_s = {params.preview:g} needs the "
                "vehicle's future, which a live session does not have: played with 0"
            )
        # the MPC's plan is sampled every 10 ms between its solves; the washout runs at
        # its own period
        period = 0.01 if mpc else params.period
        wash_every = steps_per_period(period * 1e3, 1e-3, "setpoint.cueing.parameters.period_ms")
        send_every = steps_per_period(1e3 / options.send_rate_hz, 1e-3, "--send-rate")
        sim = Build(scenario, setpoints="external").simulation()
        split = None
        if options.pin and hasattr(os, "sched_getaffinity"):
            split = cpu_split(os.sched_getaffinity(0))
        if mpc:  # its solves in a child process, one period late (sim/cue_worker.py)
            assert isinstance(params, MpcParams)
            law = CueWorker(params.replace(preview=0.0), sim.geometry, period,
                            cpus=None if split is None else split[1])  # fmt: skip
            washout: CueWorker | ClassicalWashout = law
        else:
            assert isinstance(params, WashoutParams)
            washout = ClassicalWashout(params, geometry=sim.geometry)
        if options.send is not None:
            sender = PoseSender(options.send, options.send_format, sim.geometry.home[2])
        conditioner = None
        if options.bias_tau_s > 0 or options.vibration_hz > 0:
            from controllers.conditioning import InputConditioner

            try:
                conditioner = InputConditioner(period, options.bias_tau_s, options.vibration_hz)
            except ValueError as exc:  # a corner above this law's Nyquist frequency
                raise UserInputError(f"invalid value at --vibration-hz: {exc}") from None
        rig_every = None
        if options.output is not None:
            from simpro_mj.sim.rig_output import RigOutput

            rig_every = steps_per_period(1e3 / options.output_rate_hz, 1e-3, "--output-rate")
            assert options.output_template is not None  # checked with --output
            rig = RigOutput(options.output, options.output_template, sim.geometry.home[2])
        pacer = Pacer(sim, rx, washout, wash_every=wash_every, send_every=send_every,
                      sender=sender, say=say, rig=rig, rig_every=rig_every,
                      conditioner=conditioner, spin_s=options.spin_s)  # fmt: skip
        pacer.gc_counts = [0, 0, 0]  # counted from the anchor, after a freeze there
        with (
            realtime_scheduling(options.rt, say),
            pinned(None if split is None else split[0]),
            frozen_gc(pacer.gc_counts),
        ):
            res = sim.run(pace=pacer)
        realtime = pacer.realtime(int(res.sim["steps"]))
        realtime["spin_us"] = options.spin_s * 1e6
        realtime["cpus"] = None if split is None else {
            "pacer": sorted(split[0]), "cue": sorted(split[1])}  # fmt: skip
        info = dict(pacer.washout_info(), algorithm=cue.algorithm)
        if law is not None:
            law.close()
            realtime["cue"] = {
                "in": "process",
                "latency_periods": 1,
                "period_ms": period * 1e3,
                "late_results": law.late,
                "max_behind_periods": law.max_behind,
                "periods": law.periods,
            }
        if law is not None and law.solve_times:
            from controllers.mpc_cueing import MpcResult

            done = MpcResult(np.empty(0), np.empty((0, 3)), np.asarray(law.solve_times),
                             list(law.status), np.asarray(law.iterations))  # fmt: skip
            info["solve_time"] = done.solve_time_stats()
            realtime["cue_solve_ms"] = info["solve_time"]
        return Session(res, realtime, info, pacer.lateness(), rx.address)
    finally:
        rx.close()
        if sender is not None:
            sender.close()
        if rig is not None:
            rig.close()
        if law is not None:
            law.close()  # a second close does nothing
