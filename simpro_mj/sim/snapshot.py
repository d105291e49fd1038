"""A run stopped between two steps, to resume exactly (:meth:`CoSimulation.snapshot`).

A :class:`Snapshot` holds copies (never views) of everything a run's next
step reads: MuJoCo's integration state (``mj_getState`` with
``mjSTATE_INTEGRATION``: time, ``qpos``, ``qvel``, ``act``, the warm start,
``ctrl``, ``qfrc_applied`` and the other user inputs) and its
``sensordata`` (the head accelerometer is logged from the previous step's
acceleration stage), the step's flat state ``S`` and constants ``C``, the
step number, the log rows written so far, and each noise block with its
generator's state. ``restore`` accepts it only on a run of the same model
and scenario, which the two digests name.
"""

from __future__ import annotations

import copy
import hashlib
import json
from dataclasses import dataclass

import mujoco
import numpy as np

from simpro_mj.sim import step

#: the set-point arrays a live run writes (a snapshot of it keeps them)
SETPOINTS = ("ref", "q_joint_only", "veh_f", "veh_w")


@dataclass(frozen=True)
class NoiseState:
    """A :class:`~simpro_mj.sim.stages.NoiseBlock`: its rows, first draw and generator state."""

    rows: np.ndarray
    i0: int
    rng_state: dict | None

    @classmethod
    def of(cls, block) -> NoiseState:
        state = None if block.rng is None else copy.deepcopy(block.rng.bit_generator.state)
        return cls(block.rows.copy(), int(block.i0), state)

    def into(self, block) -> None:
        block.rows = self.rows.copy()
        block.i0 = self.i0
        if self.rng_state is not None:
            block.rng.bit_generator.state = copy.deepcopy(self.rng_state)


@dataclass(frozen=True)
class Snapshot:
    """A run between steps ``k - 1`` and ``k``: every field a copy.

    Attributes
    ----------
    model, scenario : str
        SHA-256 digests of the compiled model (``mj_saveModel``) and of the
        resolved scenario (sorted JSON).
    k : int
        The next step.
    mj_state : ndarray
        ``mj_getState(..., mjSTATE_INTEGRATION)``.
    sensordata : ndarray
        MuJoCo's sensor values after step ``k - 1``.
    S, C : ndarray
        The step's state and constants (:mod:`simpro_mj.sim.step`).
    log, qlog, hlog : ndarray
        The log rows written so far (``S[ST.rows]`` of them).
    noise, walk : NoiseState
        The sensors' draws and the IMU bias walk's draws.
    setpoints : tuple of ndarray or None
        With set-points from outside (live): the set-point buffer, its IK,
        the vehicle input (``None`` when not used); ``None`` otherwise (the
        scenario computes them again).
    """

    model: str
    scenario: str
    k: int
    mj_state: np.ndarray
    sensordata: np.ndarray
    S: np.ndarray
    C: np.ndarray
    log: np.ndarray
    qlog: np.ndarray
    hlog: np.ndarray
    noise: NoiseState
    walk: NoiseState
    setpoints: tuple | None


def model_digest(model: mujoco.MjModel) -> str:
    """SHA-256 of the compiled model's binary form."""
    buf = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buf)
    return hashlib.sha256(buf.tobytes()).hexdigest()


def scenario_digest(scenario: dict) -> str:
    """SHA-256 of the resolved scenario as sorted JSON."""
    text = json.dumps(scenario, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def take(sim) -> Snapshot:
    """The run as it stands before step ``k``, to resume exactly (:func:`put_back`).

    Taken between two steps: from a ``pace`` callback of ``CoSimulation.run``
    (before step ``k``) or after a run returned. Everything in it is a
    copy (:class:`~simpro_mj.sim.snapshot.Snapshot`): MuJoCo's integration
    state and sensor values, the step's flat state and constants, the step
    number, the log rows written so far, the noise blocks and their
    generators' states.

    Raises
    ------
    ValueError
        No run has started, or the scenario has ``faults`` (their
        schedule lives outside the step's state).
    """
    if sim.scenario.get("faults"):
        raise ValueError("snapshot: invalid value at faults: allowed: none in a snapshot run")
    if getattr(sim, "_log", None) is None:
        raise ValueError("snapshot: no run has started; take it from run(pace=...)")
    m, d, S, log = sim.model, sim.data, sim.S, sim._log
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, state, spec)
    rows = int(S[step.ST.rows])
    setpoints = None
    if sim.external:  # written while the run went
        arrays = [getattr(sim, name) for name in SETPOINTS]
        setpoints = tuple(None if a is None else a.copy() for a in arrays)
    return Snapshot(
        model=sim._model_digest,
        scenario=scenario_digest(sim.scenario),
        k=int(sim._k),
        mj_state=state,
        sensordata=d.sensordata.copy(),
        S=S.copy(),
        C=sim.C.copy(),
        log=log.log[:rows].copy(),
        qlog=log.qlog[:rows].copy(),
        hlog=log.hlog[: rows if log.head else 1].copy(),
        noise=NoiseState.of(sim.noise),
        walk=NoiseState.of(sim.walk),
        setpoints=setpoints,
    )


def put_back(sim, snap: Snapshot) -> None:
    """Put ``sim`` back where :func:`take` took it; its next ``run`` goes on from there.

    Works on the simulation that took it or on a fresh one of the same
    model and scenario; the run resumed gives the same bits as the run
    that was never stopped.

    Raises
    ------
    ValueError
        ``snap`` is not a Snapshot, or comes from another model or
        scenario (the message names the field).
    """
    if not isinstance(snap, Snapshot):
        raise ValueError(f"restore: {type(snap).__name__} given; allowed: a Snapshot")
    if snap.model != sim._model_digest:
        raise ValueError("restore: snapshot field 'model' is from another model")
    if snap.scenario != scenario_digest(sim.scenario):
        raise ValueError("restore: snapshot field 'scenario' is from another scenario")
    sim._initial_state()  # the objects and buffers, then their contents
    if snap.S.shape != sim.S.shape or snap.C.shape != sim.C.shape:
        raise ValueError("restore: snapshot field 'S' has another layout")
    m, d = sim.model, sim.data
    mujoco.mj_setState(m, d, snap.mj_state, mujoco.mjtState.mjSTATE_INTEGRATION)
    d.sensordata[:] = snap.sensordata
    sim.S[:], sim.C[:] = snap.S, snap.C
    snap.noise.into(sim.noise)
    snap.walk.into(sim.walk)
    log, rows = sim._log, snap.log.shape[0]
    log.log[:rows], log.qlog[:rows] = snap.log, snap.qlog
    log.hlog[: snap.hlog.shape[0]] = snap.hlog
    for name, a in zip(SETPOINTS, snap.setpoints or [None] * 4, strict=True):
        if a is not None:
            getattr(sim, name)[:] = a
    sim._k = sim._resume = snap.k
