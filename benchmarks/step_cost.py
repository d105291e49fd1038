"""``simpro-sim bench [SCENARIO]``: the cost of one co-simulation step.

Measured in one process and one invocation, on the shipped model and a
scenario (default ``step_pitch.yaml``), ``--repeats`` times; every figure is
the median over the repeats:

* ``full_step_us``: wall time of :meth:`simpro_mj.sim.loop.CoSimulation.run`
  (sensors, joint loops, task loop amortised, pneumatics, logging, physics)
  per 1 ms step, as a run runs it (``SIMPRO_KERNEL``: with numba the step
  compiled into MuJoCo's control callback); ``realtime_factor`` = simulated
  seconds per wall second of that loop = ``timestep / full_step_us``.
* ``interpreted_step_us``: the same run with ``SIMPRO_KERNEL=python``, the
  same functions interpreted (the reference path), and its ratio to the
  bare step.
* ``bare_step_us``: ``mj_step`` alone on the same model along the *same*
  state trajectory: the run's initial state and its recorded actuator
  forces are replayed by :func:`mujoco.rollout.rollout`, a loop in C that
  sets the recorded ``ctrl`` and calls ``mj_step`` with no Python between
  steps (the physical floor). ``bare_python_loop_us`` is the same replay
  from a Python loop (``d.ctrl[:] = u_k; mj_step(m, d)``): the floor of any
  Python-driven loop. ``bare_same_trajectory`` says whether both replays end
  in exactly the run's final state (MuJoCo is deterministic, so they should).
* ``bare_frozen_clock_us``: the same C replay with MuJoCo's profiler clock
  frozen as a compiled run freezes it (:mod:`simpro_mj.sim.callback`:
  ``mjcb_time`` returns 0, so ``mj_step`` reads no clock for ``mjData.timer``);
  ``ratio_frozen_clock`` = ``full_step_us`` over it, the like-for-like
  ratio. ``null`` with ``SIMPRO_KERNEL=python``, which leaves the clock alone.
* ``ratio`` = ``full_step_us / bare_step_us``.
* ``stages_us``: per-stage wall time per step from an instrumented run
  (``CoSimulation.run(profile=...)``: the compiled stages called one by one
  from Python, ``time.perf_counter_ns`` around each, ``mj_step1``/``mj_step2``
  as ``physics``). The calls from Python and the clocks cost more than the
  stages inside ``mj_step`` do (``instrumented_step_us`` is that run's own time
  per step): the split shows where the work is, ``full_step_us`` what it costs.
* ``run_command_us``: what the ``run`` command costs per simulated step, as
  measured from outside (``run SCENARIO --no-plots --set logging.decimation=10``
  for 41 s and for 1 s, the difference over the 40 000 steps between them):
  the set-point check, the run and its result folder written, at 41 s and at
  1 s of the scenario, here in one process so that start-up (imports, the
  model's compilation) cancels instead of scattering the difference by
  tenths of a second; ``run_command_ratio`` = that over ``bare_step_us``.
  ``null`` when the scenario refuses to last 41 s (its set-points leave the
  workspace by then).
* ``separate_commands`` (``--commands N``, else ``null``): the same
  figure as a user measures it, from N pairs of whole ``run SCENARIO
  --no-plots --set logging.decimation=10`` commands at 41 s and 1 s,
  each a fresh process timed from outside, the order alternating pair by
  pair: the per-step difference in wall time and in CPU time (user +
  system) of each pair as median, quartiles and range, with ``ratio`` = the
  median wall figure over ``bare_step_us``; and ``min_us``, the difference
  of the fastest command of each duration (``timeit``'s estimator: other
  work on the machine only ever adds time), with ``ratio_min`` = that over
  the fastest bare sample. Start-up (imports, loading the compiled step,
  the caches: about 1.2 s) is in both commands, and on a shared virtual
  machine it varies by tenths of a second from one command to the next,
  which is microseconds on each of the 40 000 steps: hence many pairs.
* ``timeseries_write_s``: wall time to write the plain run's columns as
  ``timeseries.csv`` (:func:`simpro_mj.report.results.write_timeseries`, one
  ``numpy.savetxt`` call); a speed figure, so here and not in a timed test.
* ``throughput``: ``--batch-runs`` copies of the scenario stepped by 1 and
  by 2 threads of one process (:class:`concurrent.futures.ThreadPoolExecutor`;
  ``mj_step`` releases the GIL and the compiled step runs inside it), in
  simulated seconds per wall second; the runs are built before the clock
  starts. ``identical`` says whether every threaded run's log and ``qpos``
  equal a serial run's bit for bit. ``bare_workers_1``/``bare_workers_2``/
  ``bare_speedup``: the same for bare ``mj_step`` (the run's replay,
  :func:`mujoco.rollout.rollout`, on 1 and 2 threads), the ceiling of the
  scaling on this machine; ``others_share``: per repeat, the share of the
  cores other processes kept busy meanwhile (Linux ``/proc/stat``; ``null``
  elsewhere), which a shared machine's threads compete with.

``docs/performance.md`` holds the figures of this machine and how they scale.
"""

from __future__ import annotations

import copy
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

from simpro_mj.config.reference import check_setpoints
from simpro_mj.core.errors import PhysicsError, UserInputError
from simpro_mj.core.rates import PHYSICS_DT_S
from simpro_mj.plant.kernels import kernel_choice
from simpro_mj.plant.model import load_model
from simpro_mj.report.machine import describe_machine
from simpro_mj.report.render import render_video, require_video
from simpro_mj.report.results import write_timeseries
from simpro_mj.report.runner import execute
from simpro_mj.sim.build import Build
from simpro_mj.sim.readiness import signal_ready

STAGES = ("sensors", "controllers", "pneumatics", "physics", "logging")


# ------------------------------------------------------------------ measurements


def _record(scenario: dict, model):
    """One run at full logging: its initial physics state, controls and final state.

    Logging does not touch the dynamics, so the trajectory is the timed runs'
    whatever their decimation.
    """
    sc = copy.deepcopy(scenario)
    sc["logging"]["decimation"] = 1
    cs = Build(sc, model=model).simulation()
    cs._initial_state()
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, cs.data, state0, spec)
    warm0 = cs.data.qacc_warmstart.copy()
    res = cs.run()
    if res.status != "ok":
        raise PhysicsError(f"the benchmark scenario did not run to the end: {res.reason}")
    n = res.sim["steps"]
    ctrl = np.zeros((n, model.nu))
    for i, a in enumerate(cs.idx.actuators):
        ctrl[:, a] = res.columns[f"f{i + 1}_n"][:n]  # the force applied over step k
    return state0, warm0, ctrl, cs.data.qpos.copy()


def _bare_rollout(model, state0, warm0, ctrl, final_qpos) -> tuple[float, bool]:
    """us per mj_step replaying ``ctrl`` in C (mujoco.rollout); and trajectory match."""
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    n = len(ctrl)
    data = mujoco.MjData(model)
    out = np.empty((1, n, mujoco.mj_stateSize(model, spec)))
    t0 = time.perf_counter()
    rollout.rollout(model, data, state0[None], ctrl[None], initial_warmstart=warm0[None], state=out)
    wall = time.perf_counter() - t0
    mujoco.mj_setState(model, data, out[0, -1], spec)
    return wall / n * 1e6, bool(np.array_equal(data.qpos, final_qpos))


def _bare_frozen_clock(model, state0, warm0, ctrl, final_qpos) -> tuple[float, bool]:
    """:func:`_bare_rollout` with ``mjcb_time`` the compiled run's frozen clock."""
    from simpro_mj.sim.callback import frozen_clock

    previous = mujoco.get_mjcb_time()
    mujoco.set_mjcb_time(frozen_clock.ctypes)
    try:
        return _bare_rollout(model, state0, warm0, ctrl, final_qpos)
    finally:
        mujoco.set_mjcb_time(previous)


def _bare_python(model, state0, warm0, ctrl, final_qpos) -> tuple[float, bool]:
    """us per mj_step replaying ``ctrl`` from a Python loop; and trajectory match."""
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state0, spec)
    data.qacc_warmstart[:] = warm0
    c, step, rows = data.ctrl, mujoco.mj_step, list(ctrl)
    t0 = time.perf_counter()
    for u in rows:
        c[:] = u
        step(model, data)
    wall = time.perf_counter() - t0
    return wall / len(rows) * 1e6, bool(np.array_equal(data.qpos, final_qpos))


def _threaded(scenario: dict, model, workers: int, runs: int, serial) -> tuple[float, bool]:
    """Simulated seconds per wall second of ``runs`` copies stepped by ``workers`` threads;
    and whether each equals ``serial`` (a :class:`SimResult`) bit for bit."""
    sims = [Build(scenario, model=model).simulation() for _ in range(runs)]
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=workers) as pool:
        results = list(pool.map(lambda s: s.run(), sims))
    wall = time.perf_counter() - t0
    same = all(
        np.array_equal(r.qpos, serial.qpos)
        and all(np.array_equal(v, serial.columns[k], equal_nan=True) for k, v in r.columns.items())
        for r in results
    )
    return sum(r.sim["simulated_s"] for r in results) / wall, same


def _bare_threaded(model, state0, warm0, ctrl, workers: int, runs: int) -> float:
    """Simulated seconds per wall second of ``runs`` replays of the run's forces
    (:func:`mujoco.rollout.rollout`, which releases the GIL) on ``workers`` threads:
    bare ``mj_step``'s own scaling, the ceiling of the co-simulation's."""
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    n = len(ctrl)
    datas = [mujoco.MjData(model) for _ in range(runs)]
    outs = [np.empty((1, n, mujoco.mj_stateSize(model, spec))) for _ in range(runs)]

    def replay(i):
        rollout.rollout(model, datas[i], state0[None], ctrl[None],
                        initial_warmstart=warm0[None], state=outs[i])  # fmt: skip

    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=workers) as pool:
        list(pool.map(replay, range(runs)))
    return runs * n * float(model.opt.timestep) / (time.perf_counter() - t0)


def _others_busy():
    """CPU seconds the whole machine has spent busy so far, and this process's (Linux)."""
    try:
        with open("/proc/stat") as fh:
            v = [int(x) for x in fh.readline().split()[1:]]
    except OSError:
        return None
    return (sum(v) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK"), time.process_time()


def _others_share(before, wall: float):
    """Share of the cores other processes kept busy since ``before`` (:func:`_others_busy`)."""
    after = _others_busy()
    if before is None or after is None or wall <= 0:
        return None
    others = (after[0] - before[0]) - (after[1] - before[1])
    return min(1.0, max(0.0, others) / ((os.cpu_count() or 1) * wall))  # /proc/stat: 10 ms ticks


def _interpreted(scenario: dict, model) -> float:
    """us per step of the run with ``SIMPRO_KERNEL=python`` (the reference path)."""
    before = os.environ.get("SIMPRO_KERNEL")
    os.environ["SIMPRO_KERNEL"] = "python"
    try:
        res = Build(scenario, model=model).simulation().run()
    finally:
        if before is None:
            del os.environ["SIMPRO_KERNEL"]
        else:
            os.environ["SIMPRO_KERNEL"] = before
    return res.sim["wall_s"] / res.sim["steps"] * 1e6


def _run_command(scenario: dict, model, durations: tuple[float, float]) -> float | None:
    """us per step between the run command's work at two durations (logging every 10).

    The work timed is what ``run`` does that grows with the run: the set-point
    check, the run, and its result folder (no plots), ``timeseries.csv``
    formatted beside the run as ``run`` formats it. ``None`` if the longer
    duration is refused (a set-point unreachable by then).
    """
    long_s, short_s = durations
    dt = float(model.opt.timestep)
    times = []
    with tempfile.TemporaryDirectory(prefix="simpro-bench-") as tmp:
        for d in (short_s, long_s):
            sc = copy.deepcopy(scenario)
            sc["duration_s"], sc["logging"]["decimation"] = float(d), 10
            t0 = time.perf_counter()
            try:
                check_setpoints(sc)
                execute(sc, Path(tmp) / f"run_{d:g}", plots=False, quiet=True, model=model)
            except UserInputError:
                return None
            times.append(time.perf_counter() - t0)
    return (times[1] - times[0]) / round((long_s - short_s) / dt) * 1e6


def _spread(values: list[float]) -> dict:
    q1, _, q3 = statistics.quantiles(values, n=4) if len(values) > 1 else values * 3
    return {"median": statistics.median(values), "quartiles": [q1, q3],
            "range": [min(values), max(values)]}  # fmt: skip


def separate_commands(
    scenario: str,
    sets: list[str],
    pairs: int,
    bare_us: list[float],
    durations=(41.0, 1.0),
    log=None,
) -> dict:
    """The ``run`` command's cost per step from ``pairs`` pairs of whole commands
    (``separate_commands`` in the module docstring); ``scenario`` and ``sets`` as
    given on the command line, ``bare_us`` the bare step's samples
    (:func:`measure`'s ``samples["bare_step_us"]``) the ratios divide by.

    Raises
    ------
    UserInputError
        If a command fails (its last line of stderr says why).
    """
    long_s, short_s = durations
    steps = round((long_s - short_s) / PHYSICS_DT_S)
    base = [sys.executable, "-m", "simpro_mj.commands.main", "run", scenario, "--no-plots"]
    for item in [*sets, "logging.decimation=10"]:
        base += ["--set", item]

    def one(d: float, out: Path) -> tuple[float, float]:
        r0, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
        cmd = [*base, "--set", f"duration_s={d:g}", "--out", str(out)]
        done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        wall, r1 = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
        if done.returncode not in (0, 1):  # 1: a finished run whose verdict is not ok
            last = (done.stderr.strip().splitlines() or ["no message"])[-1]
            raise UserInputError(f"bench --commands: the run command failed: {last}")
        cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
        return wall, cpu

    wall, cpu, each = [], [], {long_s: [], short_s: []}
    with tempfile.TemporaryDirectory(prefix="simpro-bench-") as tmp:
        one(short_s, Path(tmp) / "warm")  # untimed: the first loads what the rest reuse
        for i in range(pairs):
            if log is not None:
                log(f"separate commands, pair {i + 1}/{pairs}")
            order = (long_s, short_s) if i % 2 == 0 else (short_s, long_s)
            got = {d: one(d, Path(tmp) / f"run_{i}_{d:g}") for d in order}
            for d in order:
                each[d].append(got[d][0])
            wall.append((got[long_s][0] - got[short_s][0]) / steps * 1e6)
            cpu.append((got[long_s][1] - got[short_s][1]) / steps * 1e6)
    spread = _spread(wall)
    min_us = (min(each[long_s]) - min(each[short_s])) / steps * 1e6
    return {
        "pairs": pairs,
        "durations_s": [long_s, short_s],
        "wall_us": spread,
        "cpu_us": _spread(cpu),
        "ratio": spread["median"] / statistics.median(bare_us),
        "min_us": min_us,
        "ratio_min": min_us / min(bare_us),
        "samples": {"wall_us": wall, "cpu_us": cpu, "wall_s": {f"{d:g}": each[d] for d in each}},
    }


def measure(
    scenario: dict,
    repeats: int = 5,
    *,
    batch: bool = True,
    batch_runs: int = 4,
    run_durations: tuple[float, float] = (41.0, 1.0),
    log=None,
) -> dict:
    """Run the benchmark on a resolved scenario; the figures of ``--json``.

    Each repeat measures, in this order, a plain run, the two bare replays
    and an instrumented run, so that a change of machine load during the
    benchmark touches all of them alike; the medians are reported.
    """

    def say(msg):
        if log is not None:
            log(msg)

    model = load_model(scenario["plant"])
    dt = float(model.opt.timestep)
    say("recording the trajectory")
    state0, warm0, ctrl, final_qpos = _record(scenario, model)
    full, bare, bare_py, instr, write, interp, command = [], [], [], [], [], [], []
    frozen = [] if kernel_choice() == "numba" else None
    # once untimed: the first result folder imports and caches what the later ones reuse
    # (timed, it made the first 1 s run cost more than the 41 s run after it)
    _run_command(scenario, model, run_durations)
    stages = {s: [] for s in STAGES}
    same = True
    for r in range(repeats):
        say(f"repeat {r + 1}/{repeats}")
        res = Build(scenario, model=model).simulation().run()
        full.append(res.sim["wall_s"] / res.sim["steps"] * 1e6)
        with tempfile.TemporaryDirectory(prefix="simpro-bench-") as tmp:
            t0 = time.perf_counter()
            write_timeseries(Path(tmp) / "timeseries.csv", res.columns)
            write.append(time.perf_counter() - t0)
        us, ok1 = _bare_rollout(model, state0, warm0, ctrl, final_qpos)
        bare.append(us)
        if frozen is not None:
            us, ok3 = _bare_frozen_clock(model, state0, warm0, ctrl, final_qpos)
            frozen.append(us)
            ok1 = ok1 and ok3
        us, ok2 = _bare_python(model, state0, warm0, ctrl, final_qpos)
        bare_py.append(us)
        same = same and ok1 and ok2
        interp.append(_interpreted(scenario, model))
        command.append(_run_command(scenario, model, run_durations))
        prof: dict = {}
        res = Build(scenario, model=model).simulation().run(profile=prof)
        instr.append(res.sim["wall_s"] / res.sim["steps"] * 1e6)
        for s in STAGES:
            stages[s].append(prof[s] / prof["steps"] / 1e3)
    full_us, bare_us = statistics.median(full), statistics.median(bare)
    command_us = None if None in command else statistics.median(command)
    out = {
        "scenario": scenario["name"],
        "duration_s": float(scenario["duration_s"]),
        "steps": int(len(ctrl)),
        "logging_decimation": int(scenario["logging"]["decimation"]),
        "bare_step_us": bare_us,
        "bare_python_loop_us": statistics.median(bare_py),
        "bare_same_trajectory": same,
        "full_step_us": full_us,
        "ratio": full_us / bare_us,
        "bare_frozen_clock_us": statistics.median(frozen) if frozen else None,
        "ratio_frozen_clock": full_us / statistics.median(frozen) if frozen else None,
        "interpreted_step_us": statistics.median(interp),
        "interpreted_ratio": statistics.median(interp) / bare_us,
        "run_command_us": command_us,
        "run_command_ratio": None if command_us is None else command_us / bare_us,
        "run_command_durations_s": list(run_durations),
        "separate_commands": None,  # separate_commands(), when asked
        "realtime_factor": dt * 1e6 / full_us,
        "stages_us": {s: statistics.median(v) for s, v in stages.items()},
        "instrumented_step_us": statistics.median(instr),
        "timeseries_write_s": statistics.median(write),
        "timeseries_rows": int(len(res.columns["time_s"])),
        "throughput": None,
        "repeats": repeats,
        "samples": {
            "full_step_us": full,
            "bare_step_us": bare,
            "bare_frozen_clock_us": frozen,
            "bare_python_loop_us": bare_py,
            "interpreted_step_us": interp,
            "run_command_us": command,
        },
        "machine": describe_machine(),
    }
    if batch:
        serial = Build(scenario, model=model).simulation().run()
        signal_ready("throughput")
        tput, bare_t, others, same = {1: [], 2: []}, {1: [], 2: []}, [], True
        for r in range(repeats):
            say(f"throughput, 1 and 2 threads, {r + 1}/{repeats}")
            t0, before = time.perf_counter(), _others_busy()
            for workers in (1, 2):
                rate, ok = _threaded(scenario, model, workers, batch_runs, serial)
                tput[workers].append(rate)
                same = same and ok
                rate = _bare_threaded(model, state0, warm0, ctrl, workers, batch_runs)
                bare_t[workers].append(rate)
            others.append(_others_share(before, time.perf_counter() - t0))
        w1, w2 = statistics.median(tput[1]), statistics.median(tput[2])
        b1, b2 = statistics.median(bare_t[1]), statistics.median(bare_t[2])
        out["throughput"] = {
            "workers_1": w1,
            "workers_2": w2,
            "speedup": w2 / w1,
            "bare_workers_1": b1,
            "bare_workers_2": b2,
            "bare_speedup": b2 / b1,
            "runs": batch_runs,
            "identical": same,
            "others_share": others,
            "samples": {
                "workers_1": tput[1],
                "workers_2": tput[2],
                "bare_workers_1": bare_t[1],
                "bare_workers_2": bare_t[2],
            },
        }
    return out


# ------------------------------------------------------------------ table


def _command_line(r: dict) -> str:
    long_s, short_s = r["run_command_durations_s"]
    what = f"the run command, {long_s:g} s - {short_s:g} s, logging every 10, results written"
    if r["run_command_us"] is None:
        return f"  run command               -     ({what}: the scenario cannot last {long_s:g} s)"
    return (
        f"  run command          {r['run_command_us']:8.2f} us  "
        f"(ratio {r['run_command_ratio']:.2f}: {what})"
    )


def _separate_lines(r: dict) -> list[str]:
    sep = r.get("separate_commands")
    if not sep:
        return []
    w, c = sep["wall_us"], sep["cpu_us"]
    return [
        f"  separate commands    {w['median']:8.2f} us  (ratio {sep['ratio']:.2f}: median of "
        f"{sep['pairs']} pairs of whole run commands, quartiles {w['quartiles'][0]:.2f}"
        f"-{w['quartiles'][1]:.2f}; CPU time {c['median']:.2f} us)",
        f"    fastest of each    {sep['min_us']:8.2f} us  (ratio {sep['ratio_min']:.2f} to the "
        "fastest bare sample)",
    ]


def table(r: dict) -> str:
    """The human table of a :func:`measure` result."""
    m = r["machine"]
    lines = [
        f"simpro-sim bench: {r['scenario']}, {r['duration_s']:g} s simulated "
        f"({r['steps']} steps, logging every {r['logging_decimation']}), "
        f"median of {r['repeats']}",
        f"machine: {m['cpu']}, {m['cores']} cores; Python {m['python']}, "
        f"MuJoCo {m['mujoco']}, numpy {m['numpy']}; kernels {m['kernels']}",
        "",
        f"  full step            {r['full_step_us']:8.2f} us",
        f"  bare mj_step (C)     {r['bare_step_us']:8.2f} us"
        + ("" if r["bare_same_trajectory"] else "   (replay left the trajectory!)"),
        f"  bare (Python loop)   {r['bare_python_loop_us']:8.2f} us",
        f"  ratio full/bare      {r['ratio']:8.2f}",
    ]
    if r["bare_frozen_clock_us"]:
        lines.append(
            f"  bare, clock frozen   {r['bare_frozen_clock_us']:8.2f} us  (ratio "
            f"{r['ratio_frozen_clock']:.2f}: mjcb_time frozen as in a compiled run)"
        )
    lines += [
        f"  interpreted step     {r['interpreted_step_us']:8.2f} us  (ratio "
        f"{r['interpreted_ratio']:.2f}, SIMPRO_KERNEL=python)",
        f"  realtime factor      {r['realtime_factor']:8.1f} x",
        _command_line(r),
        *_separate_lines(r),
        f"  timeseries.csv write {r['timeseries_write_s']:8.3f} s  ({r['timeseries_rows']} rows)",
        "",
        "  stage (instrumented) us/step",
    ]
    for s in STAGES:
        lines.append(f"    {s:<18s} {r['stages_us'][s]:8.2f}")
    lines.append(f"    {'sum':<18s} {sum(r['stages_us'].values()):8.2f}")
    tp = r["throughput"]
    if tp:
        lines += [
            "",
            f"  batch of {tp['runs']} runs      simulated s / wall s",
            f"    1 thread           {tp['workers_1']:8.1f}",
            f"    2 threads          {tp['workers_2']:8.1f}   (x{tp['speedup']:.2f})",
            f"    bare mj_step       {tp['bare_workers_1']:8.1f}   -> {tp['bare_workers_2']:.1f} "
            f"on 2 threads (x{tp['bare_speedup']:.2f})",
            "    results            "
            + ("identical to a serial run" if tp["identical"] else "DIFFER from a serial run"),
        ]
        busy = [x for x in tp["others_share"] if x is not None]
        if busy:
            lines.append(
                f"    other processes    {100 * max(busy):.0f} % of the cores at most (per repeat: "
                + ", ".join(f"{100 * x:.0f} %" for x in busy)
                + "; above a few % the threads share the cores with them)"
            )
    return "\n".join(lines)


# ------------------------------------------------------------------ video

#: The target for the video benchmark (s, on a 2-core machine).
BENCH_TARGET_S = 90.0


def measure_video(scenario: dict, *, fps=25.0, size=(640, 480), jobs=None, progress=True) -> dict:
    """Time a replay video of a run (``simpro-sim bench --video``).

    The scenario is run first (not timed) into a temporary folder, then
    rendered with the plot strip and the ghost; ``render_s`` is the wall time
    of :func:`render_video` from the start of the worker processes to the
    closed MP4 (strip drawing, encoding and worker start-up included).
    """
    require_video()
    tmp = Path(tempfile.mkdtemp(prefix="simpro-video-bench-"))
    try:
        execute(scenario, tmp / "run", plots=False, quiet=True)
        info = render_video([tmp / "run"], tmp / "run" / "replay.mp4", fps=fps, size=size,
                            jobs=jobs, progress=progress)  # fmt: skip
        mb = (tmp / "run" / "replay.mp4").stat().st_size / 1e6
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {
        "scenario": scenario.get("name"),
        "duration_s": scenario["duration_s"],
        "fps": fps,
        "size": f"{size[0]}x{size[1]}",
        "video_size": f"{info.width}x{info.height}",
        "frames": info.frames,
        "workers": info.workers,
        "gl": info.gl,
        "render_s": info.wall_s,
        "s_per_frame": info.s_per_frame,
        "worker_s_per_frame": info.s_per_frame * info.workers,
        # CPU time the workers spent per frame: what the frames cost on an idle machine
        "worker_cpu_s_per_frame": info.worker_cpu_s_per_frame,
        "load_average": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        "mp4_mb": mb,
        "target_s": BENCH_TARGET_S,
        "within_target": info.wall_s <= BENCH_TARGET_S,
        "machine": describe_machine(),
    }


def video_table(r: dict) -> str:
    """The human table of a :func:`measure_video` result."""
    m = r["machine"]
    return "\n".join(
        [
            f"video benchmark: {r['scenario']}, {r['duration_s']:g} s at {r['fps']:g} fps, "
            f"{r['size']} view + plot strip ({r['video_size']}), ghost on",
            f"  frames            {r['frames']}",
            f"  workers           {r['workers']} (MUJOCO_GL={r['gl']})",
            f"  render wall time  {r['render_s']:.1f} s (target <= {r['target_s']:g} s: "
            f"{'met' if r['within_target'] else 'NOT met'})",
            f"  per frame         {r['s_per_frame']:.3f} s wall, "
            f"{r['worker_s_per_frame']:.3f} s per worker, "
            f"{r['worker_cpu_s_per_frame']:.3f} s of worker CPU",
            f"  load average      {r['load_average']} (other jobs slow the wall time)",
            f"  MP4               {r['mp4_mb']:.1f} MB",
            f"  machine           {m['cpu']}, {m['cores']} cores, MuJoCo {m['mujoco']}",
        ]
    )
