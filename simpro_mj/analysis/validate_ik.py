"""``simpro-sim validate-ik``: the paper's Fig. 11 with MuJoCo in place of ADAMS.

The IK (vector loops, eqs. 3-14) gives q(t) for a trajectory that sweeps
roll, pitch and heave together (a Lissajous figure with incommensurate
frequencies, so that combinations are covered); q(t) is imposed on the
MuJoCo slide joints; the pose MuJoCo's closed chain then takes is compared
with the desired one. The paper's closed-form IK (eqs. 30-33) is evaluated on
the same trajectory and its disagreement in leg displacement reported.

Drive modes
-----------
``dynamic`` (default): gravity and payload on, each slide held by a MuJoCo
joint-equality constraint whose target is updated every 1 ms step. A soft
constraint tracks a moving target with a constant time lag (MuJoCo's
reference acceleration ``-b v - k r``); the lag, measured as 3.0 ms at
timeconst 2 ms and a 1 ms step, is cancelled by leading the target by
``drive_lead_s``. ``kinematic``: the
closed chain is assembled exactly (Newton) at each sample, like ADAMS'
kinematic simulation, which isolates geometry from compliance.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import mujoco
import numpy as np
from pydantic import Field

from controllers.errors import WorkspaceError
from controllers.geometry import geometry_from_rig
from controllers.kinematics import check_reachable, inverse_kinematics, paper_inverse_kinematics
from simpro_mj.config.rig import rig_value
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import Block, Real, Whole, block, param
from simpro_mj.plant.model import (
    PlantIndex,
    add_slide_drives,
    assemble,
    check_physics,
    load_spec,
    loop_closure_error,
    measured_pose,
)
from simpro_mj.plant.model_params import DEFAULT_MODEL_PARAMS

Drive = Literal["dynamic", "kinematic"]
Positive = Annotated[Real, Field(gt=0)]


class Trajectory(Block):
    """Sines that start at home; incommensurate periods, so that the Lissajous figure
    covers the combinations of the three axes."""

    duration_s: Real = param(60.0, "s", "the trajectory's length", gt=0, le=3600)
    roll_deg: Real = param(10.0, "deg", "roll amplitude")
    pitch_deg: Real = param(8.0, "deg", "pitch amplitude")
    heave_mm: Real = param(120.0, "mm", "heave amplitude")
    roll_period_s: Positive = param(17.0, "s", "period of the roll sine")
    pitch_period_s: Positive = param(13.0, "s", "period of the pitch sine")
    heave_period_s: Positive = param(23.0, "s", "period of the heave sine")
    log_every_ms: Whole = param(10, "ms", "log every n ms", ge=1, le=10**6)


class IkParams(Block):
    """The parameters of ``simpro-sim validate-ik`` (``--set drive=kinematic``)."""

    drive: Drive = param("dynamic", "", "how q(t) is imposed on the slides (module docstring)")
    trajectory: Trajectory = block(Trajectory)
    paper_ik_reading: Literal["corrected", "printed"] = param(
        "corrected", "", "reading of the paper's closed-form IK (eqs. 30-33)"
    )
    # a soft joint equality tracks a moving target with a constant time lag; a fit
    # of the slide error against the slide speed gives 3.0 ms for solref timeconst
    # 2 ms at a 1 ms step (residual 2e-7 m), so 3 ms cancels it
    drive_lead_s: Real = param(
        0.003, "s", "dynamic drive: the slide targets lead the IK by this time", ge=0, le=1
    )
    model: dict[str, Any] = param(
        DEFAULT_MODEL_PARAMS, "", "the plant model's parameters (simpro_mj.plant.model)"
    )


def trajectory(t: np.ndarray, tr: Trajectory, home: np.ndarray) -> np.ndarray:
    """Desired pose (n, 3) at times t: sines that start at home and cover the workspace."""
    amp = np.array([np.radians(tr.roll_deg), np.radians(tr.pitch_deg), tr.heave_mm * 1e-3])
    period = np.array([tr.roll_period_s, tr.pitch_period_s, tr.heave_period_s])
    return home + amp * np.sin(2 * np.pi * t[:, None] / period)


@dataclass
class IkValidation:
    """A validation's figures (SI) and its logged series (``t``: s; poses: rad, rad, m;
    slides: m); :meth:`to_json` gives the figures ``--json`` reports."""

    t: np.ndarray
    x_des: np.ndarray
    x_sim: np.ndarray
    q_des: np.ndarray
    q_sim: np.ndarray
    dq_paper: np.ndarray
    dq_ours: np.ndarray
    closure: np.ndarray
    max_position_error_m: float
    max_angle_error_rad: float
    max_joint_tracking_error_m: float
    max_loop_closure_error_m: float
    #: eqs. 30-33 against the vector loops: on the paper's rig only (None on another)
    paper_ik_max_leg_error_m: float | None
    paper_ik_max_leg_error_per_leg_m: list[float] | None
    paper_ik_reading: str
    drive: str
    rig: dict | None
    samples: int
    wall_s: float

    def to_json(self) -> dict:
        """The figures of :data:`SUMMARY_KEYS`, in that order (the time series stay out)."""
        return {k: getattr(self, k) for k in SUMMARY_KEYS}


def validate(p: IkParams | None = None) -> IkValidation:
    """Run the validation; its figures (SI) and time series."""
    p = p or IkParams()
    # the rig (model.rig: a file or its keys) gives the MJCF and the IK alike
    rig = rig_value(p.model.get("rig"), where="model.rig")
    geometry = geometry_from_rig(rig)
    spec = load_spec({**p.model, "rig": rig})
    add_slide_drives(spec)  # impose q on the slides (dynamic drive)
    model = spec.compile()
    data = mujoco.MjData(model)
    idx = PlantIndex.of(model)
    drive_ids = np.array([model.eq(f"drive{i}").id for i in (1, 2, 3)])
    q_ref0 = model.qpos0[idx.slide_qpos].copy()  # joint equality acts on qpos - qpos0

    home = geometry.home
    dt = model.opt.timestep
    n = int(round(p.trajectory.duration_s / dt))
    every = int(p.trajectory.log_every_ms * 1e-3 / dt + 0.5) or 1
    t = np.arange(n + 1) * dt
    x_des = trajectory(t, p.trajectory, home)
    try:
        check_reachable(x_des, geometry)  # names the violated stroke limit
    except WorkspaceError as exc:
        raise UserInputError(
            f"unreachable trajectory at trajectory: {' '.join(str(exc).split())}; allowed: "
            "amplitudes inside the workspace (see simpro-sim workspace)"
        ) from exc
    q_des = inverse_kinematics(x_des, geometry)
    lead = p.drive_lead_s if p.drive == "dynamic" else 0.0
    q_cmd = inverse_kinematics(trajectory(t + lead, p.trajectory, home), geometry, check=False)

    data.qpos[:] = model.qpos0
    assemble(model, data, q_des[0], index=idx)
    logged = np.arange(0, n + 1, every)
    x_sim = np.empty((logged.size, 3))
    q_sim = np.empty((logged.size, 3))
    closure = np.empty(logged.size)
    warn0 = data.warning.number.copy()
    wall = time.perf_counter()
    k_log = 0
    for k in range(n + 1):
        if p.drive == "dynamic":
            if k > 0:
                model.eq_data[drive_ids, 0] = q_cmd[k] - q_ref0
                mujoco.mj_step(model, data)
                check_physics(model, data, warn0, loop_bound=5e-4, index=idx)
        elif k % every == 0:
            assemble(model, data, q_des[k], index=idx)
        if k % every == 0:
            # mj_step leaves site_xpos at the pre-integration state: refresh
            mujoco.mj_kinematics(model, data)
            x_sim[k_log] = measured_pose(data, idx.site_p)
            q_sim[k_log] = data.qpos[idx.slide_qpos]
            closure[k_log] = loop_closure_error(model, data, idx).max()
            k_log += 1
    wall = time.perf_counter() - wall

    xd = x_des[logged]
    err = x_sim - xd
    # paper IK: displacement from the home pose, compared with ours
    dq_ours = q_des[logged] - inverse_kinematics(home, geometry)
    # eqs. 30-33 hold the paper's numbers: compared on the paper's rig only
    dq_paper = paper_inverse_kinematics(xd, reading=p.paper_ik_reading)
    paper_err = dq_paper - dq_ours
    paper = rig is None
    return IkValidation(
        t=t[logged],
        x_des=xd,
        x_sim=x_sim,
        q_des=q_des[logged],
        q_sim=q_sim,
        dq_paper=dq_paper,
        dq_ours=dq_ours,
        closure=closure,
        max_position_error_m=float(np.abs(err[:, 2]).max()),
        max_angle_error_rad=float(np.abs(err[:, :2]).max()),
        max_joint_tracking_error_m=float(np.abs(q_sim - q_des[logged]).max()),
        max_loop_closure_error_m=float(closure.max()),
        paper_ik_max_leg_error_m=float(np.abs(paper_err).max()) if paper else None,
        paper_ik_max_leg_error_per_leg_m=(
            np.abs(paper_err).max(axis=0).tolist() if paper else None
        ),
        paper_ik_reading=p.paper_ik_reading,
        drive=p.drive,
        rig=rig,
        samples=int(logged.size),
        wall_s=wall,
    )


def plot(res: IkValidation, out: Path) -> Path:
    """Desired vs simulated pose and the paper IK's leg displacements (Agg)."""
    # matplotlib when the figure is drawn (--no-plot skips it)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = res.t
    fig, ax = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    labels = [("roll", "deg", np.degrees), ("pitch", "deg", np.degrees), ("heave h", "mm", None)]
    for k, (name, unit, f) in enumerate(labels):
        conv = f if f else (lambda v: v * 1e3)
        ax[k].plot(t, conv(res.x_des[:, k]), "b-", lw=2, label="desired (IK input)")
        ax[k].plot(t, conv(res.x_sim[:, k]), "g--", lw=1.2, label="MuJoCo")
        ax[k].set_ylabel(f"{name} [{unit}]")
        ax[k].grid(alpha=0.3)
    ax[0].legend(loc="upper right")
    for i in range(3):
        ax[3].plot(t, res.dq_ours[:, i] * 1e3, f"C{i}-", label=f"q{i + 1} vector loops")
        if res.rig is None:  # eqs. 30-33 are the paper's rig's
            ax[3].plot(t, res.dq_paper[:, i] * 1e3, f"C{i}:", label=f"q{i + 1} eqs. 30-33")
    ax[3].set(ylabel="leg displacement from home [mm]", xlabel="time [s]")
    ax[3].legend(ncol=3, fontsize=7)
    ax[3].grid(alpha=0.3)
    fig.suptitle(
        f"IK validation ({res.drive} drive{', own rig' if res.rig else ''}): "
        f"max |e_h| = {res.max_position_error_m * 1e3:.4f} mm,"
        f" max |e_angle| = {np.degrees(res.max_angle_error_rad):.5f} deg"
    )
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    path = out / "validate_ik.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


#: The figures of a validation that ``--json`` reports (the time series stay out).
SUMMARY_KEYS = (
    "max_position_error_m",
    "max_angle_error_rad",
    "paper_ik_max_leg_error_m",
    "paper_ik_max_leg_error_per_leg_m",
    "paper_ik_reading",
    "max_joint_tracking_error_m",
    "max_loop_closure_error_m",
    "drive",
    "rig",
    "samples",
)


def summary(res: IkValidation) -> str:
    """The human summary of a validation (mm, deg)."""
    lines = [
        f"IK validation, {res.drive} drive, {res.samples} samples:",
        f"  max heave error         {res.max_position_error_m * 1e3:10.5f} mm",
        f"  max roll/pitch error    {np.degrees(res.max_angle_error_rad):10.6f} deg",
        f"  max slide tracking err  {res.max_joint_tracking_error_m * 1e3:10.5f} mm",
        f"  max loop-closure error  {res.max_loop_closure_error_m * 1e3:10.5f} mm",
    ]
    if res.paper_ik_max_leg_error_m is None:
        lines.append("  paper IK (eqs. 30-33): not compared (they hold the paper's rig)")
    else:
        lines.append(
            f"  paper IK (eqs. 30-33, {res.paper_ik_reading}) vs vector loops, "
            f"max leg-displacement difference {res.paper_ik_max_leg_error_m * 1e3:.1f} mm"
        )
    return "\n".join(lines)
