"""Figures of a cueing run, in the style of the motion-cueing literature.

``cueing.png``: per channel (longitudinal, lateral, vertical specific force;
roll and pitch rate) the vehicle's stimulus (grey), the vehicle's perceived
(black) and the simulator's perceived (red), with the perception threshold
band shaded, as Reid & Nahon (1986) and Telban & Cardullo (2005) compare
cueing algorithms. ``cue_pose.png``: the cueing law's set-points (blue; the MPC's
or the classical washout's) and the platform's pose (green) with the workspace box
(dashed), and the leg strokes.
matplotlib Agg only, no pyplot.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from controllers.geometry import H0
from simpro_mj.analysis.cue_metrics import CHANNELS, perceived
from simpro_mj.report.figures import DESIRED, LEG_COLOURS, OUTPUT, envelope, save

__all__ = ["cueing_figures", "plot_cueing"]

VEHICLE = "0.6"
VEHICLE_PERCEIVED = "k"
SIMULATOR_PERCEIVED = "tab:red"
_LABELS = {
    "longitudinal_f": ("a) longitudinal specific force", 1.0, "m/s²"),
    "lateral_f": ("b) lateral specific force", 1.0, "m/s²"),
    "vertical_f": ("c) vertical specific force − g", 1.0, "m/s²"),
    "roll_rate": ("d) roll rate", 180.0 / math.pi, "deg/s"),
    "pitch_rate": ("e) pitch rate", 180.0 / math.pi, "deg/s"),
}


def plot_cueing(columns: Mapping, scenario: Mapping, out_dir, dpi: int = 120) -> list[Path]:
    """Write ``cueing.png`` and ``cue_pose.png``; returns their paths."""
    out_dir = Path(out_dir)
    return [
        save(fig, out_dir / f"{name}.png", dpi)
        for name, fig in cueing_figures(columns, scenario).items()
    ]


def cueing_figures(columns: Mapping, scenario: Mapping) -> dict[str, Figure]:
    """``cueing`` and ``cue_pose`` (module docstring) as figures."""
    t, veh, sim = perceived(columns)
    name = scenario.get("name", "run")
    fig = Figure(figsize=(9, 10), layout="constrained")
    axes = fig.subplots(len(CHANNELS), 1, sharex=True)
    for ax, (ch, vc, _sc, kind, k) in zip(axes, CHANNELS, strict=True):
        title, scale, unit = _LABELS[ch]
        raw = np.asarray(columns[vc], float) - (9.80665 if ch == "vertical_f" else 0.0)
        pv = (veh.f if kind == "f" else veh.w)[:, k]
        ps = (sim.f if kind == "f" else sim.w)[:, k]
        thr = (veh.f_threshold if kind == "f" else veh.w_threshold)[k]
        ax.axhspan(-thr * scale, thr * scale, color="0.9", lw=0, label="threshold")
        ax.plot(*envelope(t, raw * scale), color=VEHICLE, lw=0.8, label="vehicle")
        ax.plot(*envelope(t, pv * scale), color=VEHICLE_PERCEIVED, lw=1.4,
                label="vehicle, perceived")  # fmt: skip
        ax.plot(*envelope(t, ps * scale), color=SIMULATOR_PERCEIVED, lw=1.2,
                label="simulator, perceived")  # fmt: skip
        ax.set_ylabel(unit)
        ax.set_title(title, fontsize=9, loc="left")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize=7, ncol=2)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"{name}: vehicle vs simulator, perceived (otoliths, canals)")
    figs = {"cueing": fig}

    fig = Figure(figsize=(9, 8), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    box = scenario_box(scenario)
    algorithm = (scenario.get("setpoint", {}).get("cueing") or {}).get("algorithm")
    law = _LAW_NAMES.get(algorithm or "", "cueing")
    for ax, (axis, unit, scale, disp) in zip(
        axes[:3],
        (("roll", "rad", 180 / math.pi, "deg"), ("pitch", "rad", 180 / math.pi, "deg"),
         ("heave", "m", 1e3, "mm")),
        strict=True,
    ):  # fmt: skip
        off = H0 if axis == "heave" else 0.0
        ax.plot(*envelope(t, (np.asarray(columns[f"{axis}_ref_{unit}"], float) - off) * scale),
                color=DESIRED, lw=1.3, label=f"{law} set-point")  # fmt: skip
        ax.plot(*envelope(t, (np.asarray(columns[f"{axis}_{unit}"], float) - off) * scale),
                color=OUTPUT, lw=1.1, label="platform")  # fmt: skip
        if box is not None:
            for k, v in enumerate(box[axis]):
                label = "workspace box" if axis == "roll" and k == 0 else None
                ax.axhline((v - off) * scale, color="k", ls="--", lw=0.7, label=label)
        ax.set_ylabel(f"{axis} from home [{disp}]" if axis == "heave" else f"{axis} [{disp}]")
        ax.grid(True, alpha=0.3)
    for i in (1, 2, 3):
        axes[3].plot(*envelope(t, np.asarray(columns[f"q{i}_m"], float) * 1e3),
                     color=LEG_COLOURS[i], lw=1.0, label=f"leg {i}")  # fmt: skip
    axes[3].axhline(0.0, color="k", lw=0.8, label="end stops")
    axes[3].axhline(500.0, color="k", lw=0.8)
    axes[3].set_ylabel("stroke [mm]")
    axes[3].set_xlabel("time [s]")
    axes[3].grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize=7)
    axes[3].legend(loc="best", fontsize=7, ncol=4)
    boxed = "; workspace box dashed" if box is not None else ""
    fig.suptitle(f"{name}: platform pose vs the {law} set-points{boxed}")
    figs["cue_pose"] = fig
    return figs


#: ``setpoint.cueing.algorithm`` -> the law's name in the figures.
_LAW_NAMES = {"mpc": "MPC", "classical_washout": "classical washout"}


def scenario_box(scenario: Mapping):
    from simpro_mj.config.cueing import vehicle_input

    try:
        return vehicle_input(scenario)[4]["box"]
    except Exception:  # noqa: BLE001 - a figure without the box is still a figure
        return None
