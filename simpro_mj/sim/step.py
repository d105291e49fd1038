"""The 1 ms step, written once: sensors, controllers, actuators and the log row.

One physics step of the co-simulation is, at the state of ``t_k``::

    sense      the slides, the platform pose and the loop closures from MuJoCo;
               potentiometers, height encoder, IMU (own rates, zero-order hold)
    control    the outer loop every ``outer`` steps (or IK(y_d + c) every step,
               feed-forward), Fig. 13's set-point filter, the joint loops -> volts
    actuate    valves and chambers -> the three slide forces (MuJoCo's ctrl)
    record     one log row every ``decimation`` steps

then MuJoCo integrates to ``t_k+1`` with those forces held. The stages are
plain functions on two flat float64 arrays, the state ``S`` (every discrete
state, counter and the set-point filter's ring: saving ``S`` with MuJoCo's
state resumes a run exactly) and the constants ``C``, calling the
controllers' (:mod:`controllers.step_functions`) and the plant's
(:mod:`simpro_mj.plant.step_functions`) per-step functions. Two ways to run
them, the same source:

* interpreted (``SIMPRO_KERNEL=python``, the readable reference):
  :class:`~simpro_mj.sim.loop.CoSimulation` calls ``mj_step1``, the stages,
  ``mj_step2`` from Python every step;
* compiled (numba, the default when it is installed): :func:`compiled` turns
  every function into machine code and :func:`callback_step` runs inside
  ``mj_step`` as MuJoCo's control callback (:mod:`simpro_mj.sim.callback`,
  acting only on the runs registered in :data:`REGISTRY`), exactly where the
  split step runs the stages (after the position and velocity stages, before
  actuation); Python steps chunks of steps.
"""

from __future__ import annotations

import math
import threading
import types as pytypes

import numpy as np

from controllers import step_functions as cs
from controllers.dead_band import dead_band
from simpro_mj.plant import step_functions as ps
from simpro_mj.plant.friction import seal_friction
from simpro_mj.plant.sensor_errors import accel_tilt, pot_nonlinearity

__all__ = ["sense", "control", "actuate", "record", "callback_step", "build", "compiled"]

# ---------------------------------------------------------------- state S
K, STATUS, ERR, ERR_K, ROWS, WORST, FLAGS, NOISE_K0 = range(8)
# the bias walk: its draws used so far, the stream index of its block's first row
WALK_M, WALK_M0 = 8, 9
Q, QD, POSE, QM, PM, LOOP = 10, 13, 16, 19, 22, 25
YQ, YP = 26, 29  # what the controllers see (faults act here)
QDES, QR, U, UA, F, PCMD = 32, 35, 38, 41, 44, 47  # q_d, q_ref, volts (own, applied), N, x_c
SAT = 50  # feed-forward: a valve at its rail since the last outer step
SS = 51  # the sensors' own state (plant.step_functions.SS_*)
TS = SS + ps.SS_LEN  # the outer loop's state (controllers.step_functions.TS)
JX = TS + cs.TS.LEN  # the joint controllers' 9 states
FS = JX + 9  # the set-point filter's state (controllers.step_functions.FS)
AST = FS + cs.FS.LEN  # the actuators' state (plant.step_functions.A_*)
RING = AST + ps.A_LEN  # the ramp filter's ring (3 x n_max)

#: STATUS values: registered but not stepping, stepping, stopped on an error
IDLE, RUNNING, STOPPED = 0.0, 1.0, 2.0
#: errors of the plant and the run, after the controllers' (cs.ERR_*)
ERR_FORCE, ERR_LOOP, ERR_WARNING = 5, 6, 7

# ------------------------------------------------------------ constants C
DT, NSTEPS, DEC, OUTER, HOLD_SAT, HAS_UFF, HEAD, LOOP_BOUND = range(8)
FC = 8  # the set-point filter's constants (controllers.step_functions.FC)
JC = FC + cs.FC.LEN  # the joint controllers' (controllers.step_functions.JC)
# the state read: the slides' qpos and dof, the platform site's xmat and xpos (z), the
# closed loops' site pairs (8 at most), the head sensors, the slides' motors
IQ = JC + cs.JC.LEN
IV, IMAT, IH, NPAIR, PAIRS = IQ + 3, IQ + 6, IQ + 7, IQ + 8, IQ + 9
IHA, IHG, ICTRL = PAIRS + 16, PAIRS + 17, PAIRS + 18
SC = ICTRL + 3
TC = SC + ps.SC_LEN
GEOM = TC + cs.TC.LEN
AC = GEOM + cs.GEOM.LEN  # the actuators' constants (plant.step_functions.AC_*)
MAX_PAIRS = 8

#: the log's columns (simpro_mj.sim.result.COLUMNS), in order
N_COLS = 1 + 3 * 9 + 6 + 1 + 2


# ---------------------------------------------------------------- the stages
def sense(k, S, C, qpos, qvel, xpos, xmat, noise, walk):
    """The state and the sensors' readings at step ``k`` into ``S``.

    ``noise``: the block of the sensors' draws (row ``k - S[NOISE_K0]``);
    ``walk``: the block of the IMU bias walk's draws (row ``S[WALK_M] - S[WALK_M0]``).
    """
    q, pose, qm, pm = S[Q : Q + 3], S[POSE : POSE + 3], S[QM : QM + 3], S[PM : PM + 3]
    ps.slide_states(qpos, qvel, C[IQ : IQ + 3], C[IV : IV + 3], q, S[QD : QD + 3])
    ps.platform_pose(xmat, xpos, C[IMAT], C[IH], pose)
    S[LOOP] = ps.loop_closure(xpos, C[PAIRS : PAIRS + 2 * MAX_PAIRS], C[NPAIR])
    site = int(C[IH]) - 2  # the platform frame's origin: the IMU site
    draws, steps = noise[k - int(S[NOISE_K0])], walk[int(S[WALK_M]) - int(S[WALK_M0])]
    sc, ss = C[SC : SC + ps.SC_LEN], S[SS : SS + ps.SS_LEN]
    imu = xpos[site : site + 3]
    S[WALK_M] += ps.sample_sensors(k, False, q, pose, imu, draws, steps, sc, ss, qm, pm)
    S[YQ : YQ + 3], S[YP : YP + 3] = qm, pm


def control(k, S, C, ref, qj, uff):
    """The controllers at step ``k``: q_d, the filter, the joint loops; returns an error code.

    Writes q_d (``S[QDES]``), q_ref, the volts (the controllers' own ``U``
    and the applied ``UA``, equal unless a fault overrides them) and the
    commanded pose.
    """
    ts, tc, g = S[TS : TS + cs.TS.LEN], C[TC : TC + cs.TC.LEN], C[GEOM : GEOM + cs.GEOM.LEN]
    mode = tc[cs.TC.mode]
    y0, y1, y2 = S[YP], S[YP + 1], S[YP + 2]
    m0, m1, m2 = S[YQ], S[YQ + 1], S[YQ + 2]
    err = 0
    if mode == cs.MODE_JOINT:  # q_d = IK(y_d), precomputed
        S[QDES : QDES + 3], S[PCMD : PCMD + 3] = qj[k], ref[k]
    else:
        if k % int(C[OUTER]) == 0:
            hold = S[SAT] != 0.0
            err = cs.outer_update(
                ref[k, 0], ref[k, 1], ref[k, 2], y0, y1, y2, m0, m1, m2, hold, ts, tc, g
            )
            S[SAT] = 0.0
        elif mode == cs.MODE_FF:
            err = cs.ff_inner(ref[k, 0], ref[k, 1], ref[k, 2], y0, y1, y2, m0, m1, m2, 2, ts, tc, g)
        S[QDES : QDES + 3] = ts[cs.TS.qd : cs.TS.qd + 3]
        S[PCMD : PCMD + 3] = ts[cs.TS.xc : cs.TS.xc + 3]
    if err:
        return err
    qr, ring = S[QR : QR + 3], S[RING:].reshape(3, -1)
    cs.filter_step(
        C[FC : FC + cs.FC.LEN], S[QDES], S[QDES + 1], S[QDES + 2], S[FS : FS + cs.FS.LEN], ring, qr
    )
    f0 = f1 = f2 = 0.0
    if C[HAS_UFF] != 0.0:
        f0, f1, f2 = uff[k, 0], uff[k, 1], uff[k, 2]
    jc = C[JC : JC + cs.JC.LEN]
    cs.joint_step(S[JX : JX + 9], jc, qr[0] - m0, qr[1] - m1, qr[2] - m2, f0, f1, f2, S[U : U + 3])
    lo, hi = jc[cs.JC.lo], jc[cs.JC.hi]
    S[UA : UA + 3] = S[U : U + 3]
    if C[HOLD_SAT] != 0.0 and S[SAT] == 0.0:
        for i in range(3):
            if not (lo < S[U + i] < hi):
                S[SAT] = 1.0
    return 0


def actuate(S, C):
    """The actuators over the step for the applied volts: forces into ``S[F]``; error code."""
    ast, ac = S[AST : AST + ps.A_LEN], C[AC:]
    u, q, qd, f = S[UA : UA + 3], S[Q : Q + 3], S[QD : QD + 3], S[F : F + 3]
    if ac[ps.AC_KIND] == 0.0:
        ps.nonlinear_step(u, q, qd, ast, ac, f)
    else:
        ps.linear_step(u, q, qd, ast, ac, f)
    if not math.isfinite(f[0] + f[1] + f[2]):
        return ERR_FORCE
    return 0


def record(k, S, C, ref, qpos, sd, log, qlog, hlog):
    """The log row of step ``k`` (every ``decimation`` steps); error code (loop opened)."""
    if k % int(C[DEC]) != 0:
        return 0
    row = int(S[ROWS])
    out = log[row]
    out[0] = k * C[DT]
    for i in range(3):
        out[1 + i] = ref[k, i]
        out[4 + i] = S[POSE + i]
        out[7 + i] = S[YP + i]
        out[10 + i] = S[PCMD + i]
        out[13 + i] = S[QR + i]
        out[16 + i] = S[Q + i]
        out[19 + i] = S[YQ + i]
        out[22 + i] = S[UA + i]
        out[25 + i] = S[F + i]
        out[28 + 2 * i] = S[AST + ps.A_P + i]
        out[29 + 2 * i] = S[AST + ps.A_P + 3 + i]
    loop = S[LOOP]
    out[34], out[35], out[36] = loop, S[FLAGS], S[AST + ps.A_PS]  # the supply at the valves
    qlog[row] = qpos
    if C[HEAD] != 0.0:
        a, g = int(C[IHA]), int(C[IHG])
        hlog[row, :3], hlog[row, 3:] = sd[a : a + 3], sd[g : g + 3]
    S[ROWS] = row + 1
    if loop > S[WORST]:
        S[WORST] = loop
    if loop > C[LOOP_BOUND]:
        return ERR_LOOP
    return 0


def apply_forces(S, C, ctrl):
    """The slide forces into MuJoCo's ``ctrl`` (the slides' motors)."""
    for i in range(3):
        ctrl[int(C[ICTRL + i])] = S[F + i]


def callback_step(
    S, C, qpos, qvel, xpos, xmat, sd, ctrl, warn, ref, qj, uff, noise, walk, log, qlog, hlog
):
    """Step ``S[K]`` whole (sense, control, actuate, apply, record), then ``K + 1``.

    The body of MuJoCo's control callback for one registered run. Does
    nothing unless the run is stepping; stops it (before the step) when a
    MuJoCo warning counter is set (``warn``: the ``lastinfo, number`` pairs
    of ``mjWarningStat``) or the step is past the run's end or the noise
    rows Python drew. On an error ``S`` records it and the step.
    """
    if S[STATUS] != RUNNING:
        return
    k = int(S[K])
    for i in range(warn.shape[0] // 2):
        if warn[2 * i + 1] != 0:
            S[ERR], S[ERR_K], S[STATUS] = ERR_WARNING, k - 1, STOPPED
            return
    if (
        k > int(C[NSTEPS])
        or k - int(S[NOISE_K0]) >= noise.shape[0]
        or int(S[WALK_M]) - int(S[WALK_M0]) >= walk.shape[0]
    ):
        S[STATUS] = IDLE
        return
    sense(k, S, C, qpos, qvel, xpos, xmat, noise, walk)
    err = control(k, S, C, ref, qj, uff)
    if err == 0:
        err = actuate(S, C)
    if err == 0:
        apply_forces(S, C, ctrl)
        err = record(k, S, C, ref, qpos, sd, log, qlog, hlog)
    if err:
        S[ERR], S[ERR_K], S[STATUS] = err, k, STOPPED
    S[K] = k + 1


# ------------------------------------------------------------ the run's arrays
def build(sim, loop_bound: float, noise_row, walk_row) -> tuple[np.ndarray, np.ndarray]:
    """``(S, C)`` of a :class:`~simpro_mj.sim.loop.CoSimulation` from its objects.

    The controllers, the sensors' configuration and the actuators are built,
    validated and reset as objects; their numbers go into ``C`` and their
    states (run through the same per-step functions) into ``S``. The sensors
    take a first reading at the true state, the IMU's filter starting there.
    """
    filt, joint, task, idx, act = sim.setpoint_filter, sim.joint, sim.task, sim.idx, sim.actuators
    act.set_timestep(sim.dt)
    C = np.zeros(AC + act.step_constants.size)
    C[DT : OUTER + 1] = sim.dt, sim.n_steps, sim.decimation, sim.outer_every
    C[HOLD_SAT] = 1.0 if sim.mode == "feedforward" and sim.hold_on_saturation else 0.0
    C[HAS_UFF] = 1.0 if sim.u_ff is not None else 0.0
    C[LOOP_BOUND] = loop_bound
    C[FC : FC + cs.FC.LEN] = filt.step_constants
    C[JC : JC + cs.JC.LEN] = joint.step_constants
    C[IQ : IQ + 3], C[IV : IV + 3] = idx.slide_qpos, idx.slide_dof
    C[IMAT], C[IH] = 9 * int(idx.site_p), 3 * int(idx.site_p) + 2
    pairs = [(3 * int(a), 3 * int(b)) for a, b in idx.connect_sites]
    if len(pairs) > MAX_PAIRS:
        raise ValueError(f"the model has {len(pairs)} closed loops; the step reads {MAX_PAIRS}")
    C[NPAIR] = len(pairs)
    C[PAIRS : PAIRS + 2 * len(pairs)] = [i for p in pairs for i in p]
    if sim.cueing:  # the first sensordata index of each (a slice)
        C[HEAD], C[IHA], C[IHG] = 1.0, idx.sensor["head_accel"].start, idx.sensor["head_gyro"].start
    C[ICTRL : ICTRL + 3] = idx.actuators
    C[SC : SC + ps.SC_LEN] = sim.sensor_cfg.step_constants
    C[TC : TC + cs.TC.LEN] = task.step_constants
    C[GEOM : GEOM + cs.GEOM.LEN] = task.step_geometry
    C[AC:] = act.step_constants
    S = np.zeros(RING + 3 * max(filt.n))
    S[STATUS] = IDLE
    S[AST : AST + ps.A_LEN] = act.step_state
    d = sim.data
    q, pose, qm, pm = S[Q : Q + 3], S[POSE : POSE + 3], S[QM : QM + 3], S[PM : PM + 3]
    ps.slide_states(d.qpos, d.qvel, C[IQ : IQ + 3], C[IV : IV + 3], q, S[QD : QD + 3])
    ps.platform_pose(d.site_xmat.reshape(-1), d.site_xpos.reshape(-1), C[IMAT], C[IH], pose)
    ss, sc = S[SS : SS + ps.SS_LEN], C[SC : SC + ps.SC_LEN]
    ss[ps.SS_IMU : ps.SS_IMU + 2] = pose[:2]
    # no acceleration at the first reading (no IMU site positions)
    S[WALK_M] += ps.sample_sensors(0, True, q, pose, None, noise_row, walk_row, sc, ss, qm, pm)
    S[TS : TS + cs.TS.LEN] = task.step_state
    S[PCMD : PCMD + 3] = task.step_state[cs.TS.xc : cs.TS.xc + 3]
    S[JX : JX + 9] = joint._x
    S[FS : FS + cs.FS.LEN] = filt.step_state
    S[RING:].reshape(3, -1)[:] = filt.ring
    return S, C


# ------------------------------------------------------------ compiled form
_PLAIN = [
    dead_band,
    cs.ik_pose, cs.ik_lag, cs.segment_limit, cs.filter_step, cs.joint_step, cs.outer_setpoint,
    cs._ik_xc, cs._integrate, cs._accumulate, cs._ff_error, cs._correct, cs.ff_step,
    cs.outer_update, cs.ff_inner,
    ps.slide_states, ps.platform_pose, ps.loop_closure, ps.clip, ps.quantise, accel_tilt,
    pot_nonlinearity, ps.imu_input, ps.sample_sensors,
    seal_friction, ps._psi, ps.valve_spool, ps._chamber, ps.chamber_pressures, ps.chamber_energy,
    ps.supply_step, ps.slide_forces,
    ps.nonlinear_step, ps.linear_step,
    sense, control, actuate, record, apply_forces, callback_step,
]  # fmt: skip

_compiled = None
_compile_lock = threading.Lock()


def compiled():
    """The stages compiled by numba (``njit(cache=True)``), as a namespace of functions.

    Each plain function is compiled with the names it calls bound to their
    compiled forms (callees first), so the source above is the only copy.
    Loaded from numba's on-disk cache after the first run (:func:`_cache_dir`).
    """
    global _compiled
    with _compile_lock:
        if _compiled is None:
            import numba  # the optional extra: imported on first use

            numba.config.CACHE_DIR = _cache_dir()  # type: ignore[attr-defined]
            env: dict = {}
            for f in _PLAIN:
                glob = dict(f.__globals__)
                glob.update(
                    {k: _module_view(v, env) for k, v in glob.items() if v is cs or v is ps}
                )
                glob.update(env)
                clone = pytypes.FunctionType(f.__code__, glob, f.__name__, f.__defaults__)
                clone.__qualname__, clone.__module__ = f.__qualname__, f.__module__
                env[f.__name__] = numba.njit(cache=True)(clone)
            _compiled = pytypes.SimpleNamespace(**env)
        return _compiled


def _cache_dir() -> str:
    """numba's cache directory for the compiled step, named by a hash of its sources.

    numba invalidates a cached function when its own file changes, not when
    a function it calls does (the callee's code is linked into the caller's
    cache entry): a cache keyed by all the step's source files is never
    stale. Under ``NUMBA_CACHE_DIR`` if it is a writable folder (else said),
    else next to this package, else the user's cache directory
    (:mod:`simpro_mj.sim.numba_cache`); damaged files are deleted first.
    """
    import os
    import sys

    from simpro_mj.core.cache import source_digest
    from simpro_mj.sim.numba_cache import cache_base, heal

    # the modules of every compiled function, and the callback's
    files = {sys.modules[f.__module__].__file__ for f in _PLAIN}
    files.add(os.path.join(os.path.dirname(__file__), "callback.py"))
    digest = source_digest(files)
    base = cache_base(os.path.join(os.path.dirname(__file__), "__pycache__"))
    folder = os.path.join(base, "simpro-step-" + digest[:16])
    heal(folder)  # a truncated file is deleted (said) and its function compiled again
    return folder


def _module_view(module, env):
    """``module`` as the compiled functions see it: its functions compiled so far swapped in."""
    view = pytypes.ModuleType(module.__name__)
    view.__dict__.update(module.__dict__)
    view.__dict__.update({k: v for k, v in env.items() if k in module.__dict__})
    return view


# ------------------------------------------------------------ the registry
#: The arrays of a registered run, in the order of its slot and of :func:`callback_step`'s
#: arguments; MuJoCo's are views of its ``mjData`` (``site_xpos``, ``site_xmat``,
#: ``sensordata``, the warnings' ``lastinfo, number`` pairs).
SLOT_ARRAYS = "S C qpos qvel xpos xmat sd ctrl warn ref qj uff noise walk log qlog hlog".split()
#: one slot per registered run: the ``mjData``'s address (the key; 0: free),
#: then (address, rows, columns) of each array
SLOT = 1 + 3 * len(SLOT_ARRAYS)
N_SLOTS = 64
REGISTRY = np.zeros(N_SLOTS * SLOT, dtype=np.int64)
