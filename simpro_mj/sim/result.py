"""What one co-simulation run produced: the logged columns and :class:`SimResult`."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from simpro_mj.plant.faults import FAULT_COLUMNS

#: Logged columns (SI, units in the names), in CSV order.
COLUMNS = (
    ["time_s"]
    + [f"{a}_ref_{u}" for a, u in (("roll", "rad"), ("pitch", "rad"), ("heave", "m"))]
    + ["roll_rad", "pitch_rad", "heave_m"]
    + ["roll_meas_rad", "pitch_meas_rad", "heave_meas_m"]
    + ["roll_cmd_rad", "pitch_cmd_rad", "heave_cmd_m"]
    + [f"q{i}_ref_m" for i in (1, 2, 3)]
    + [f"q{i}_m" for i in (1, 2, 3)]
    + [f"q{i}_meas_m" for i in (1, 2, 3)]
    + [f"u{i}_v" for i in (1, 2, 3)]
    + [f"f{i}_n" for i in (1, 2, 3)]
    + [f"p{i}{c}_pa" for i in (1, 2, 3) for c in ("a", "b")]
    + ["loop_closure_m"]
    + list(FAULT_COLUMNS)  # fault_flags (bit mask, faults.FLAG_BITS), supply_pa
)


@dataclass
class SimResult:
    """What one run produced. ``columns`` holds copies, never MuJoCo views."""

    columns: dict
    status: str  # "ok" | "diverged" | "interrupted"; the runner judges an ok run's end
    reason: str | None
    sim: dict
    scenario: dict
    sensor_floor: dict = field(default_factory=dict)
    #: the sensors' floor without the IMU's static bias: what the verdict's
    #: oscillation threshold scales with (a bias does not oscillate)
    noise_floor: dict = field(default_factory=dict)
    #: where :func:`simpro_mj.report.runner.execute` wrote the result folder (None: not written)
    folder: Path | None = None
    #: ``qpos`` at every logged row, (rows, nq), a copy: the whole closed chain, so
    #: ``simpro-sim render`` replays the run exactly without re-simulating it.
    qpos: np.ndarray | None = None
    #: the joint owning each ``qpos`` entry (all hinges and slides: one entry each)
    qpos_names: tuple = ()


def qpos_names(model: mujoco.MjModel) -> tuple:
    """Name of the joint of each ``qpos`` entry (the model has only 1-DOF joints)."""
    names = []
    for j in range(model.njnt):
        width = {0: 7, 1: 4}.get(int(model.jnt_type[j]), 1)  # free, ball, slide/hinge
        name = model.joint(j).name
        names += [name] if width == 1 else [f"{name}[{i}]" for i in range(width)]
    return tuple(names)
