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
(:mod:`simpro_mj.plant.step_functions`) per-step functions. Each array is
read by name through its declared layout (:func:`controllers.layout.layout`):
:data:`ST` and :data:`CT`, whose fields include the controllers' and the
plant's blocks at their own layouts' lengths, so a stage reads
``S[ST.q + i]`` and the plant ``ac[AC.fric + ...]``. Two ways to run them,
the same source:

* interpreted (``SIMPRO_KERNEL=python``, the readable reference):
  :class:`~simpro_mj.sim.loop.CoSimulation` calls ``mj_step1``, the stages,
  ``mj_step2`` from Python every step;
* compiled (numba, the default when it is installed): :func:`compiled` turns
  every function the stages reach (:data:`_PLAIN`, read from the code) into
  machine code and :func:`callback_step` runs inside
  ``mj_step`` as MuJoCo's control callback (:mod:`simpro_mj.sim.callback`,
  acting only on the runs registered in :data:`REGISTRY`), exactly where the
  split step runs the stages (after the position and velocity stages, before
  actuation); Python steps chunks of steps.
"""

from __future__ import annotations

import math
import sys
import threading
import types as pytypes

import numpy as np

from controllers import experiment_law as xl
from controllers import step_functions as cs
from controllers.layout import layout
from simpro_mj.plant import step_functions as ps

__all__ = [
    "sense",
    "control",
    "actuate",
    "record",
    "callback_step",
    "plant_reads",
    "build",
    "compiled",
]

#: the closed loops' site pairs the step reads (at most)
MAX_PAIRS = 8

# ---------------------------------------------------------------- state S
#: The state ``S``: the step counter, the run's status (IDLE ...), its error and the
#: step of it, the log rows written, the worst loop closure, the faults' flags, the
#: noise block's first step; the bias walk's draws used so far and the stream index of
#: its block's first row; the slides, their speeds, the pose, the sensors' readings, the
#: loop closure; what the controllers see (faults act here); q_d, q_ref, the volts (the
#: controllers' own and the applied), the slide forces (N), the commanded pose x_c;
#: feed-forward: a valve at its rail since the last outer step; then the blocks of the
#: sensors (plant.step_functions.SS), the outer loop (controllers.step_functions.TS),
#: the joint controllers (a JX per leg), the set-point filter (FS), the actuators
#: (plant.step_functions.ACT) and the ramp filter's ring (3 x n_max, open)
ST = layout(
    "StepState", k=1, status=1, err=1, err_k=1, rows=1, worst=1, flags=1, noise_k0=1,
    walk_m=1, walk_m0=1, q=3, qd=3, pose=3, qm=3, pm=3, loop=1, yq=3, yp=3, qdes=3, qr=3,
    u=3, ua=3, f=3, pcmd=3, sat=1, ss=ps.SS.LEN, ts=cs.TS.LEN, jx=cs.JS.LEN, fs=cs.FS.LEN,
    ast=ps.ACT.LEN, ring=None,
)  # fmt: skip

#: STATUS values: registered but not stepping, stepping, stopped on an error
IDLE, RUNNING, STOPPED = 0.0, 1.0, 2.0
#: errors of the plant and the run, after the controllers' (cs.ERR_*)
ERR_FORCE, ERR_LOOP, ERR_WARNING = 5, 6, 7

# ------------------------------------------------------------ constants C
#: The constants ``C``: dt, the run's steps, the log's decimation, the outer period
#: (steps), hold on saturation (feed-forward), a feed-forward force given, the head
#: sensors logged (two sensordata triples: in a cueing run the head's), the loop-closure
#: bound (m); the blocks of the set-point filter (controllers.step_functions.FC) and the
#: joint loops (JC); the state read: the slides' qpos and dof, the platform site's xmat,
#: its z and its position (the IMU's) in xpos, the closed loops' site pairs, the head
#: sensors, the slides' motors; the blocks of the sensors (plant.step_functions.SC), the
#: outer loop (TC), the geometry (GEOM), the identification experiment's law
#: (controllers.experiment_law.XC) and the actuators (plant.step_functions.AC or ACL by
#: their kind, open)
CT = layout(
    "StepConstants", dt=1, nsteps=1, dec=1, outer=1, hold_sat=1, has_uff=1, head=1,
    loop_bound=1, fc=cs.FC.LEN, jc=cs.JC.LEN, iq=3, iv=3, imat=1, ih=1, isite=1, npair=1,
    pairs=2 * MAX_PAIRS, iha=1, ihg=1, ictrl=3, sc=ps.SC.LEN, tc=cs.TC.LEN, geom=cs.GEOM.LEN,
    xp=xl.XC.LEN, ac=None,
)  # fmt: skip

#: One log row (simpro_mj.sim.result.COLUMNS, in order): the time, the set-point, the
#: pose, its measurement, the command, q_ref, the slides, their measurement, the applied
#: volts, the forces, per leg the two chamber pressures, the loop closure, the faults'
#: flags, the supply at the valves
ROW = layout(
    "LogRow", t=1, ref=3, pose=3, meas=3, cmd=3, qref=3, q=3, qm=3, u=3, f=3, p=6, loop=1,
    flags=1, ps=1,
)  # fmt: skip
#: the log's columns
N_COLS = ROW.LEN


# ---------------------------------------------------------------- the stages
def sense(k, S, C, qpos, qvel, xpos, xmat, noise, walk):
    """The state and the sensors' readings at step ``k`` into ``S``.

    ``noise``: the block of the sensors' draws (row ``k - S[ST.noise_k0]``);
    ``walk``: the block of the IMU bias walk's draws (row ``S[ST.walk_m] - S[ST.walk_m0]``).
    """
    q, pose = S[ST.q : ST.q + 3], S[ST.pose : ST.pose + 3]
    qm, pm = S[ST.qm : ST.qm + 3], S[ST.pm : ST.pm + 3]
    iq, iv = C[CT.iq : CT.iq + 3], C[CT.iv : CT.iv + 3]
    ps.slide_states(qpos, qvel, iq, iv, q, S[ST.qd : ST.qd + 3])
    ps.platform_pose(xmat, xpos, C[CT.imat], C[CT.ih], pose)
    S[ST.loop] = ps.loop_closure(xpos, C[CT.pairs : CT.pairs + 2 * MAX_PAIRS], C[CT.npair])
    site = int(C[CT.isite])  # the platform frame's origin: the IMU site
    draws = noise[k - int(S[ST.noise_k0])]
    steps = walk[int(S[ST.walk_m]) - int(S[ST.walk_m0])]
    sc, ss = C[CT.sc : CT.sc + ps.SC.LEN], S[ST.ss : ST.ss + ps.SS.LEN]
    imu = xpos[site : site + 3]
    S[ST.walk_m] += ps.sample_sensors(k, False, q, pose, imu, draws, steps, sc, ss, qm, pm)
    for i in range(3):  # element by element: a slice copy costs more than the stage
        S[ST.yq + i], S[ST.yp + i] = S[ST.qm + i], S[ST.pm + i]


def control(k, S, C, ref, qj, uff):
    """The controllers at step ``k``: q_d, the filter, the joint loops; returns an error code.

    Writes q_d (``S[ST.qdes]``), q_ref, the volts (the controllers' own ``u``
    and the applied ``ua``, equal unless a fault overrides them) and the
    commanded pose. With the identification experiment's law on (``C[CT.xp]``), that
    law alone (:func:`controllers.experiment_law.experiment_volts`).
    """
    xc = C[CT.xp : CT.xp + xl.XC.LEN]
    if xc[xl.XC.on] != 0.0:  # the P law holding the legs, the excitation by step
        xl.experiment_volts(k, S[ST.q : ST.q + 3], xc, uff, S[ST.u : ST.u + 3])
        for i in range(3):
            S[ST.ua + i] = S[ST.u + i]
        return 0
    ts = S[ST.ts : ST.ts + cs.TS.LEN]
    tc, g = C[CT.tc : CT.tc + cs.TC.LEN], C[CT.geom : CT.geom + cs.GEOM.LEN]
    mode = tc[cs.TC.mode]
    y0, y1, y2 = S[ST.yp], S[ST.yp + 1], S[ST.yp + 2]
    m0, m1, m2 = S[ST.yq], S[ST.yq + 1], S[ST.yq + 2]
    err = 0
    if mode == cs.MODE_JOINT:  # q_d = IK(y_d), precomputed
        for i in range(3):
            S[ST.qdes + i], S[ST.pcmd + i] = qj[k, i], ref[k, i]
    else:
        if k % int(C[CT.outer]) == 0:
            hold = S[ST.sat] != 0.0
            err = cs.outer_update(
                ref[k, 0], ref[k, 1], ref[k, 2], y0, y1, y2, m0, m1, m2, hold, ts, tc, g
            )
            S[ST.sat] = 0.0
        elif mode == cs.MODE_FF:
            err = cs.ff_inner(ref[k, 0], ref[k, 1], ref[k, 2], y0, y1, y2, m0, m1, m2, 2, ts, tc, g)
        for i in range(3):
            S[ST.qdes + i], S[ST.pcmd + i] = ts[cs.TS.qd + i], ts[cs.TS.xc + i]
    if err:
        return err
    qr, ring = S[ST.qr : ST.qr + 3], S[ST.ring :]  # 3 rows, flat
    qd0, qd1, qd2 = S[ST.qdes], S[ST.qdes + 1], S[ST.qdes + 2]
    fc, fs = C[CT.fc : CT.fc + cs.FC.LEN], S[ST.fs : ST.fs + cs.FS.LEN]
    cs.filter_step(fc, qd0, qd1, qd2, fs, ring, qr)
    f0 = f1 = f2 = 0.0
    if C[CT.has_uff] != 0.0:
        f0, f1, f2 = uff[k, 0], uff[k, 1], uff[k, 2]
    jc, u = C[CT.jc : CT.jc + cs.JC.LEN], S[ST.u : ST.u + 3]
    cs.joint_step(
        S[ST.jx : ST.jx + cs.JS.LEN], jc, qr[0] - m0, qr[1] - m1, qr[2] - m2, f0, f1, f2, u
    )
    lo, hi = jc[cs.JC.lo], jc[cs.JC.hi]
    for i in range(3):
        S[ST.ua + i] = S[ST.u + i]
    if C[CT.hold_sat] != 0.0 and S[ST.sat] == 0.0:
        for i in range(3):
            if not (lo < S[ST.u + i] < hi):
                S[ST.sat] = 1.0
    return 0


def actuate(S, C):
    """The actuators over the step for the applied volts: forces into ``S[ST.f]``; error code."""
    ast, ac = S[ST.ast : ST.ast + ps.ACT.LEN], C[CT.ac :]
    u, q, qd, f = S[ST.ua : ST.ua + 3], S[ST.q : ST.q + 3], S[ST.qd : ST.qd + 3], S[ST.f : ST.f + 3]
    if ac[ps.AC.kind] == 0.0:
        ps.nonlinear_step(u, q, qd, ast, ac, f)
    else:
        ps.linear_step(u, q, qd, ast, ac, f)
    if not math.isfinite(f[0] + f[1] + f[2]):
        return ERR_FORCE
    return 0


def record(k, S, C, ref, qpos, sd, log, qlog, hlog):
    """The log row of step ``k`` (every ``decimation`` steps); error code (loop opened)."""
    if k % int(C[CT.dec]) != 0:
        return 0
    row = int(S[ST.rows])
    out = log[row]
    out[ROW.t] = k * C[CT.dt]
    for i in range(3):
        out[ROW.ref + i] = ref[k, i]
        out[ROW.pose + i] = S[ST.pose + i]
        out[ROW.meas + i] = S[ST.yp + i]
        out[ROW.cmd + i] = S[ST.pcmd + i]
        out[ROW.qref + i] = S[ST.qr + i]
        out[ROW.q + i] = S[ST.q + i]
        out[ROW.qm + i] = S[ST.yq + i]
        out[ROW.u + i] = S[ST.ua + i]
        out[ROW.f + i] = S[ST.f + i]
        out[ROW.p + 2 * i] = S[ST.ast + ps.ACT.p + i]  # cap side
        out[ROW.p + 2 * i + 1] = S[ST.ast + ps.ACT.p + 3 + i]  # rod side
    loop = S[ST.loop]
    out[ROW.loop], out[ROW.flags] = loop, S[ST.flags]
    out[ROW.ps] = S[ST.ast + ps.ACT.ps]  # the supply at the valves
    for j in range(qpos.shape[0]):  # element by element: cheaper than a row's copy
        qlog[row, j] = qpos[j]
    if C[CT.head] != 0.0:
        a, g = int(C[CT.iha]), int(C[CT.ihg])
        for i in range(3):
            hlog[row, i], hlog[row, 3 + i] = sd[a + i], sd[g + i]
    S[ST.rows] = row + 1
    if loop > S[ST.worst]:
        S[ST.worst] = loop
    if loop > C[CT.loop_bound]:
        return ERR_LOOP
    return 0


def apply_forces(S, C, ctrl):
    """The slide forces into MuJoCo's ``ctrl`` (the slides' motors)."""
    for i in range(3):
        ctrl[int(C[CT.ictrl + i])] = S[ST.f + i]


def callback_step(
    S, C, qpos, qvel, xpos, xmat, sd, ctrl, warn, ref, qj, uff, noise, walk, log, qlog, hlog
):
    """Step ``S[ST.k]`` whole (sense, control, actuate, apply, record), then ``k + 1``.

    The body of MuJoCo's control callback for one registered run. Does
    nothing unless the run is stepping; stops it (before the step) when a
    MuJoCo warning counter is set (``warn``: the ``lastinfo, number`` pairs
    of ``mjWarningStat``) or the step is past the run's end or the noise
    rows Python drew. On an error ``S`` records it and the step.
    """
    if S[ST.status] != RUNNING:
        return
    k = int(S[ST.k])
    for i in range(warn.shape[0] // 2):
        if warn[2 * i + 1] != 0:
            S[ST.err], S[ST.err_k], S[ST.status] = ERR_WARNING, k - 1, STOPPED
            return
    if (
        k > int(C[CT.nsteps])
        or k - int(S[ST.noise_k0]) >= noise.shape[0]
        or int(S[ST.walk_m]) - int(S[ST.walk_m0]) >= walk.shape[0]
    ):
        S[ST.status] = IDLE
        return
    sense(k, S, C, qpos, qvel, xpos, xmat, noise, walk)
    err = control(k, S, C, ref, qj, uff)
    if err == 0:
        err = actuate(S, C)
    if err == 0:
        apply_forces(S, C, ctrl)
        err = record(k, S, C, ref, qpos, sd, log, qlog, hlog)
    if err:
        S[ST.err], S[ST.err_k], S[ST.status] = err, k, STOPPED
    S[ST.k] = k + 1


# ------------------------------------------------------------ the run's arrays
def plant_reads(idx) -> dict:
    """The ``C`` fields of where the step reads the plant (:data:`CT`: ``iq`` .. ``pairs``,
    ``ictrl``) for a model's :class:`~simpro_mj.plant.model.PlantIndex`."""
    pairs = [(3 * int(a), 3 * int(b)) for a, b in idx.connect_sites]
    if len(pairs) > MAX_PAIRS:
        raise ValueError(f"the model has {len(pairs)} closed loops; the step reads {MAX_PAIRS}")
    flat_pairs = np.zeros(2 * MAX_PAIRS)
    flat_pairs[: 2 * len(pairs)] = [i for p in pairs for i in p]
    return dict(
        iq=idx.slide_qpos, iv=idx.slide_dof, imat=9 * int(idx.site_p),
        ih=3 * int(idx.site_p) + 2, isite=3 * int(idx.site_p), npair=len(pairs),
        pairs=flat_pairs, ictrl=idx.actuators,
    )  # fmt: skip


def build(sim, loop_bound: float, noise_row, walk_row) -> tuple[np.ndarray, np.ndarray]:
    """``(S, C)`` of a :class:`~simpro_mj.sim.loop.CoSimulation` from its objects.

    The controllers, the sensors' configuration and the actuators are built,
    validated and reset as objects; their numbers go into ``C`` (packed by
    name, :data:`CT`) and their states (run through the same per-step
    functions) into ``S``. The sensors take a first reading at the true state,
    the IMU's filter starting there.
    """
    filt, joint, task, idx, act = sim.setpoint_filter, sim.joint, sim.task, sim.idx, sim.actuators
    act.set_timestep(sim.dt)
    head = {"head": 0.0, "iha": 0.0, "ihg": 0.0}
    if sim.cueing:  # the first sensordata index of each (a slice)
        a, g = idx.sensor["head_accel"].start, idx.sensor["head_gyro"].start
        head = {"head": 1.0, "iha": a, "ihg": g}
    C = CT.pack(
        dt=sim.dt, nsteps=sim.n_steps, dec=sim.decimation, outer=sim.outer_every,
        hold_sat=1.0 if sim.mode == "feedforward" and sim.hold_on_saturation else 0.0,
        has_uff=1.0 if sim.u_ff is not None else 0.0, loop_bound=loop_bound,
        fc=filt.step_constants, jc=joint.step_constants, sc=sim.sensor_cfg.step_constants,
        tc=task.step_constants, geom=task.step_geometry, xp=np.zeros(xl.XC.LEN),
        ac=act.step_constants, **head, **plant_reads(idx),
    )  # fmt: skip
    S = np.zeros(ST.LEN + 3 * max(filt.n))
    v = ST.views(S)
    v.status[:] = IDLE
    v.ast[:] = act.step_state
    d = sim.data
    ps.slide_states(d.qpos, d.qvel, C[CT.iq : CT.iq + 3], C[CT.iv : CT.iv + 3], v.q, v.qd)
    xmat, xpos = d.site_xmat.reshape(-1), d.site_xpos.reshape(-1)
    ps.platform_pose(xmat, xpos, C[CT.imat], C[CT.ih], v.pose)
    ss, sc = v.ss, C[CT.sc : CT.sc + ps.SC.LEN]
    ss[ps.SS.imu : ps.SS.imu + 2] = v.pose[:2]
    # no acceleration at the first reading (no IMU site positions)
    v.walk_m[:] += ps.sample_sensors(
        0, True, v.q, v.pose, None, noise_row, walk_row, sc, ss, v.qm, v.pm
    )
    v.ts[:] = task.step_state
    v.pcmd[:] = task.step_state[cs.TS.xc : cs.TS.xc + 3]
    v.jx[:] = joint._x
    v.fs[:] = filt.step_state
    v.ring.reshape(3, -1)[:] = filt.ring
    return S, C


# ------------------------------------------------------------ compiled form
#: the packages whose functions make up the step
_OWN = ("controllers.", "simpro_mj.")


def _own_module(v) -> bool:
    """Whether ``v`` is one of the project's modules (``ps``, ``cs``)."""
    return isinstance(v, pytypes.ModuleType) and v.__name__.startswith(_OWN)


def _reached(root) -> list:
    """Every function of the project that ``root`` calls, directly or not, then ``root``:
    callees first (the order :func:`compiled` compiles them in).

    Read from the code: each name a function's code uses, looked up in its module
    and in the project's modules it refers to (``ps.slide_states``), that is a plain
    function of the project. So the compiled list follows the source: a stage
    calling a new function compiles it without a list to edit.
    """
    order: list = []

    def visit(f):
        if f in order:
            return
        glob = f.__globals__
        spaces = [glob] + [vars(m) for m in glob.values() if _own_module(m)]
        codes = [f.__code__]
        while codes:  # the function's code and any nested code in it
            code = codes.pop()
            codes.extend(c for c in code.co_consts if isinstance(c, pytypes.CodeType))
            for name in code.co_names:
                for space in spaces:
                    g = space.get(name)
                    if isinstance(g, pytypes.FunctionType) and g.__module__.startswith(_OWN):
                        visit(g)
        order.append(f)

    visit(root)
    return order


#: the functions :func:`compiled` compiles, callees first: all that the step calls
_PLAIN = _reached(callback_step)

_compiled = None
_compile_lock = threading.Lock()


def compiled():
    """The stages compiled by numba (``njit(cache=True)``), as a namespace of functions
    (and ``cache_folder``, the folder of their on-disk cache).

    Each plain function is compiled with the names it calls bound to their
    compiled forms (callees first), so the source above is the only copy.
    Loaded from numba's on-disk cache after the first run (:func:`_cache_dir`).
    """
    global _compiled
    with _compile_lock:
        if _compiled is None:
            from simpro_mj.sim.numba_cache import jit  # numba: imported on first use

            folder = _cache_dir()
            env: dict = {}
            for f in _PLAIN:
                glob = dict(f.__globals__)
                views = {k: _module_view(v, env) for k, v in glob.items() if _own_module(v)}
                glob.update(views)
                glob.update(env)
                clone = pytypes.FunctionType(f.__code__, glob, f.__name__, f.__defaults__)
                clone.__qualname__, clone.__module__ = f.__qualname__, f.__module__
                env[f.__name__] = jit(folder)(clone)
            _compiled = pytypes.SimpleNamespace(**env, cache_folder=folder)
        return _compiled


def _sources_digest() -> str:
    """SHA-256 of the step's source files: every compiled function's module, the
    callback's, and the layouts' helper (the offsets compiled in as constants)."""
    import os

    from simpro_mj.core.cache import source_digest

    files = {sys.modules[f.__module__].__file__ for f in _PLAIN}
    files.add(os.path.join(os.path.dirname(__file__), "callback.py"))
    files.add(sys.modules[layout.__module__].__file__)
    return source_digest(files)


#: Taken as the step's modules are imported, not when it is first compiled: a source
#: edited between the two would otherwise name the old code's cache by the new
#: code's digest, and every later run would load offsets that no longer hold.
_SOURCES = _sources_digest()


def _cache_dir() -> str:
    """numba's cache directory for the compiled step, named by a hash of its sources.

    numba invalidates a cached function when its own file changes, not when
    a function it calls does (the callee's code is linked into the caller's
    cache entry): a cache keyed by all the step's source files (:data:`_SOURCES`)
    is never stale. Under ``NUMBA_CACHE_DIR`` if it is a writable folder (else
    said), else next to this package, else the user's cache directory
    (:mod:`simpro_mj.sim.numba_cache`, which deletes a damaged file when it is loaded).
    """
    import os

    from simpro_mj.sim.numba_cache import cache_base

    base = cache_base(os.path.join(os.path.dirname(__file__), "__pycache__"))
    return os.path.join(base, "simpro-step-" + _SOURCES[:16])


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
