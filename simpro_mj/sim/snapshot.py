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

__all__ = ["Snapshot", "model_digest", "scenario_digest", "NoiseState"]


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
