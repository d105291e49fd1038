"""The cost of one co-simulation step in instructions, counted by valgrind's callgrind.

``simpro-sim bench`` times the step with the wall clock; on a shared or busy
machine its ``ratio`` (full step over bare ``mj_step``) moves by a tenth from
one invocation to the next. Instructions do not: callgrind counts the same
total for the same binary and inputs whatever else the machine is doing. This
script gives the bench's ratio in instructions::

    python benchmarks/step_instructions.py                  # step_pitch.yaml
    python benchmarks/step_instructions.py heavy_cabin_step.yaml --set K=V --json

Each figure is counted in its own process under ``valgrind --tool=callgrind
--toggle-collect=mj_step``: only what runs inside ``mj_step`` counts, which
for the co-simulation is the physics and the whole compiled step (MuJoCo's
control callback), and for the bare replay the physics alone:

* ``full``: the scenario's run (:meth:`simpro_mj.sim.loop.CoSimulation.run`,
  the compiled step inside ``mj_step``, the profiler clock frozen as a run
  freezes it);
* ``bare``: the run's initial state and its slide forces replayed by
  :func:`mujoco.rollout.rollout` (the bench's ``bare_step_us``, MuJoCo's
  defaults);
* ``bare_frozen_clock``: the same replay with ``mjcb_time`` the run's frozen
  clock (the bench's ``bare_frozen_clock_us``, like for like).

Each is counted at two durations (default 1 s and 3 s) and the figure per
step is the difference over the steps between them, so that what does not
grow with the run (the settling of the initial state, the first call's
loads) cancels. The forces are recorded once, natively, at the longer
duration; both replays end in exactly that run's state or the script says so.

numba compiles the step for the CPU it runs on, and valgrind's virtual CPU
lacks AVX-512: every process here, the native one that fills numba's cache
first included, compiles for ``NUMBA_CPU_NAME`` / ``NUMBA_CPU_FEATURES``
(default ``haswell`` with x86-64-v3's features), so the counted code is the
cached code. The instructions of the Python between the chunks of 50 steps
(``mj_step(m, d, 50)``) are not counted: they are outside ``mj_step``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

#: the CPU numba compiles for here (valgrind 3.19 runs x86-64-v3, not AVX-512)
CPU_NAME = "haswell"
CPU_FEATURES = (
    "+64bit,+avx,+avx2,+bmi,+bmi2,+cmov,+cx16,+cx8,+f16c,+fma,+fxsr,+lzcnt,+mmx,+movbe,"
    "+popcnt,+sse,+sse2,+sse3,+sse4.1,+sse4.2,+ssse3,+xsave"
)
MODES = ("full", "bare", "bare_frozen_clock")


# ------------------------------------------------------------------ in the counted process
def _scenario(name: str, sets: list[str], duration: float) -> dict:
    from simpro_mj.config.scenario import load_scenario, scenario_with

    return scenario_with(load_scenario(name, sets), {"duration_s": duration}).model_dump()


def _child(args) -> None:
    """One counted (or the native recording) process: ``args.child`` is its mode."""
    import mujoco
    import numpy as np

    if args.child in ("bare", "bare_frozen_clock"):  # MuJoCo alone: a short start-up
        _replay(args, mujoco, np)
        return
    from simpro_mj.commands.bench import harness
    from simpro_mj.plant.model import load_model
    from simpro_mj.sim.build import Build

    sc = _scenario(args.scenario, args.set, args.duration)
    model = load_model(sc["plant"])
    if args.child == "full":
        res = Build(sc, model=model).simulation().run()
        if res.status != "ok":
            raise SystemExit(f"the run did not end ok: {res.reason}")
        print(json.dumps({"steps": int(res.sim["steps"])}))
        return
    # the bench's recording (benchmarks/step_cost.py); its build sets the model's options
    state0, warm0, ctrl, qpos = harness()._record(sc, model)
    mujoco.mj_saveModel(model, args.forces + ".mjb", None)  # the model as the run stepped it
    np.savez(args.forces, state0=state0, warm0=warm0, ctrl=ctrl, qpos=qpos)


def _replay(args, mujoco, np) -> None:
    """The bare replay of the recorded forces' first ``args.duration`` seconds."""
    import ctypes

    from mujoco import rollout

    model = mujoco.MjModel.from_binary_path(args.forces + ".mjb")
    rec = np.load(args.forces)
    n = round(args.duration / float(model.opt.timestep))
    ctrl = rec["ctrl"][:n]
    previous = mujoco.get_mjcb_time()
    if args.child == "bare_frozen_clock":  # mjcb_time returning 0, as a run's (C, no Python)
        clock = ctypes.CDLL(args.forces + ".clock.so").frozen_clock
        mujoco.set_mjcb_time(ctypes.cast(clock, ctypes.CFUNCTYPE(ctypes.c_double)))
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    data = mujoco.MjData(model)
    out = np.empty((1, len(ctrl), mujoco.mj_stateSize(model, spec)))
    rollout.rollout(model, data, rec["state0"][None], ctrl[None],
                    initial_warmstart=rec["warm0"][None], state=out)  # fmt: skip
    mujoco.set_mjcb_time(previous)
    mujoco.mj_setState(model, data, out[0, -1], spec)
    # the recording's final state is known at its full length only
    same = bool(np.array_equal(data.qpos, rec["qpos"])) if len(ctrl) == len(rec["ctrl"]) else None
    print(json.dumps({"steps": len(ctrl), "same_trajectory": same}))


# ------------------------------------------------------------------ the driver
def _env() -> dict:
    env = dict(os.environ)
    env.setdefault("NUMBA_CPU_NAME", CPU_NAME)
    env.setdefault("NUMBA_CPU_FEATURES", CPU_FEATURES)
    env["OMP_NUM_THREADS"] = env["OPENBLAS_NUM_THREADS"] = "1"
    return env


def _command(mode: str, duration: float, args, forces: Path) -> list[str]:
    cmd = [sys.executable, os.path.abspath(__file__), args.scenario, "--child", mode]
    for s in args.set:
        cmd += ["--set", s]
    return cmd + ["--duration", f"{duration:g}", "--forces", str(forces)]


def _frozen_clock(so: str) -> None:
    """``double frozen_clock(void) { return 0; }`` compiled by the system's C compiler:
    the run's frozen ``mjcb_time`` (:func:`simpro_mj.sim.callback.frozen_clock`)
    without loading numba into the replay."""
    src = so + ".c"
    Path(src).write_text("double frozen_clock(void) { return 0.0; }\n")
    subprocess.run(["cc", "-O2", "-shared", "-fPIC", "-o", so, src], check=True)


def _summary(path: Path) -> int:
    """The instructions (``Ir``) a callgrind output file counts in all."""
    for line in path.read_text().splitlines():
        if line.startswith(("summary:", "totals:")):
            return int(line.split()[1])
    raise RuntimeError(f"{path}: no summary line")


def count(args, log=print) -> dict:
    """Instructions per step of each mode (module docstring) and their ratios."""
    env = _env()
    d1, d2 = args.durations
    with tempfile.TemporaryDirectory(prefix="simpro-instructions-") as tmp:
        forces = Path(tmp) / "forces.npz"
        log(f"recording {d2:g} s natively (numba compiles for {env['NUMBA_CPU_NAME']} once)")
        subprocess.run(_command("record", d2, args, forces), env=env, check=True)
        _frozen_clock(str(forces) + ".clock.so")
        got: dict = {}
        for mode in MODES:
            for d in (d1, d2):
                out = Path(tmp) / f"callgrind.{mode}.{d:g}"
                log(f"counting {mode}, {d:g} s")
                cmd = ["valgrind", "--tool=callgrind", "--collect-atstart=no",
                       "--toggle-collect=mj_step", f"--callgrind-out-file={out}",
                       *_command(mode, d, args, forces)]  # fmt: skip
                done = subprocess.run(cmd, env=env, capture_output=True, text=True)
                if done.returncode != 0:
                    raise SystemExit(f"{mode} {d:g} s failed:\n{done.stderr[-2000:]}")
                info = json.loads(done.stdout.strip().splitlines()[-1])
                got[mode, d] = (_summary(out), info)
    per_step, same = {}, True
    for mode in MODES:
        (i1, a), (i2, b) = got[mode, d1], got[mode, d2]
        per_step[mode] = (i2 - i1) / (b["steps"] - a["steps"])
        same = same and b.get("same_trajectory", True) is not False
    full = per_step["full"]
    return {
        "scenario": args.scenario,
        "sets": args.set,
        "durations_s": [d1, d2],
        "numba_cpu": [env["NUMBA_CPU_NAME"], env["NUMBA_CPU_FEATURES"]],
        "instructions_per_step": per_step,
        "ratio": full / per_step["bare"],
        "ratio_frozen_clock": full / per_step["bare_frozen_clock"],
        "step_instructions": full - per_step["bare_frozen_clock"],
        "bare_same_trajectory": same,
        "totals": {f"{m} {d:g} s": [v[0], v[1]["steps"]] for (m, d), v in got.items()},
    }


def table(r: dict) -> str:
    """The human table of a :func:`count` result."""
    n = r["instructions_per_step"]
    d1, d2 = r["durations_s"]
    return "\n".join(
        [
            f"instructions per step inside mj_step (callgrind), {r['scenario']}, "
            f"{d2:g} s - {d1:g} s; numba for {r['numba_cpu'][0]}",
            f"  full step             {n['full']:10.0f}",
            f"  bare mj_step          {n['bare']:10.0f}"
            + ("" if r["bare_same_trajectory"] else "   (replay left the trajectory!)"),
            f"  bare, clock frozen    {n['bare_frozen_clock']:10.0f}",
            f"  ratio full/bare       {r['ratio']:10.3f}",
            f"  ratio, clock frozen   {r['ratio_frozen_clock']:10.3f}",
            f"  the step's own        {r['step_instructions']:10.0f}  (full - bare, clock frozen)",
        ]
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("scenario", nargs="?", default="step_pitch.yaml")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--durations", nargs=2, type=float, default=[1.0, 3.0], metavar=("S1", "S2"))
    p.add_argument("--json", action="store_true")
    p.add_argument("--child", choices=("record", *MODES), help=argparse.SUPPRESS)
    p.add_argument("--duration", type=float, help=argparse.SUPPRESS)
    p.add_argument("--forces", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        _child(args)
        return 0
    if not args.durations[0] < args.durations[1]:
        p.error(f"--durations: {args.durations}; allowed: two durations, the shorter first")
    r = count(args, log=(lambda m: print(m, file=sys.stderr)))
    print(json.dumps(r, indent=2) if args.json else table(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
