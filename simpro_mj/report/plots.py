"""Figures of a run in the paper's style (Figs. 14-16), matplotlib Agg only.

The figures are built with :class:`matplotlib.figure.Figure` (no pyplot, no
global state, no display): desired values in blue, the platform's output in
green as in Figs. 14 and 16, each leg in its colour of
:data:`simpro_mj.report.figures.LEG_COLOURS`, angles in degrees and heights in
millimetres. Long curves are drawn through :func:`simpro_mj.report.figures.envelope`
(the same pixels for a tenth of the points). Columns that a run did not log are
skipped (the figure needing them is not written).

A cueing run adds two figures in the style of the motion-cueing literature
(:func:`cueing_figures`). ``cueing.png``: per channel (longitudinal, lateral,
vertical specific force; roll and pitch rate) the vehicle's stimulus (grey), the
vehicle's perceived (black) and the simulator's perceived (red), with the
perception threshold band shaded, as Reid & Nahon (1986) and Telban & Cardullo
(2005) compare cueing algorithms. ``cue_pose.png``: the cueing law's set-points
(blue; the MPC's or the classical washout's) and the platform's pose (green) with
the workspace box (dashed), and the leg strokes.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from simpro_mj.analysis.cue_metrics import CHANNELS, perceived
from simpro_mj.config.models import Scenario, as_scenario, as_tree
from simpro_mj.plant.faults import fault_intervals
from simpro_mj.report.figures import (
    DESIRED,
    DPI,
    LEG_COLOURS,
    MEASURED,
    OUTPUT,
    TASK_AXES,
    envelope,
    loop_label,
    margins,
    save,
)


def _has(columns: Mapping, *names: str) -> bool:
    return all(n in columns for n in names)


def _col(columns: Mapping, name: str) -> np.ndarray:
    return np.asarray(columns[name], dtype=float)


def _title(scenario: Mapping, what: str) -> str:
    return f"{scenario.get('name', 'run')}: {what} ({loop_label(scenario)})"


def _line(ax, t, y, **kwargs):
    """``ax.plot`` of a time series through :func:`envelope`."""
    return ax.plot(*envelope(t, y), **kwargs)


#: Colours of the fault intervals shaded on every time plot of a run.
_FAULT_COLOURS = {
    "supply_drop": "tab:red",
    "valve_stuck": "tab:orange",
    "sensor_frozen": "tab:purple",
    "sensor_dropout": "tab:pink",
    "sensor_bias": "tab:brown",
    "potentiometer_failure": "tab:olive",
}


def _shade_faults(fig: Figure, scenario: Scenario) -> None:
    """Shade each scheduled fault's interval on every axis of ``fig`` (one legend entry)."""
    spans = fault_intervals(scenario)
    if not spans:
        return
    axes = [ax for ax in fig.axes if ax.get_visible()]
    for n, ax in enumerate(axes):
        seen = set()
        for kind, start, end in spans:
            label = f"fault: {kind}" if n == 0 and kind not in seen else None
            seen.add(kind)
            ax.axvspan(start, end, color=_FAULT_COLOURS.get(kind, "0.5"), alpha=0.12, lw=0,
                       label=label)  # fmt: skip
    if axes:
        axes[0].legend(loc="best", fontsize=8)


def _task_axes(columns: Mapping, axes):
    """Draw the three task-space panels into ``axes`` (three, one above the other)."""
    t = _col(columns, "time_s")
    drawn = []
    for ax, (title, ref, true, meas, scale, unit, zero) in zip(axes, TASK_AXES, strict=True):
        if not _has(columns, ref, true):
            ax.set_visible(False)
            continue
        if meas in columns:
            _line(ax, t, (_col(columns, meas) - zero) * scale, color=MEASURED, lw=0.6,
                  label="measured (sensors)")  # fmt: skip
        _line(ax, t, (_col(columns, ref) - zero) * scale, color=DESIRED, lw=1.4, label="desired")
        _line(ax, t, (_col(columns, true) - zero) * scale, color=OUTPUT, lw=1.2, label="output")
        ax.set_ylabel(f"{title.split(') ')[1]} [{unit}]")
        ax.grid(True, alpha=0.3)
        drawn.append(ax)
    if drawn:
        drawn[-1].set_xlabel("time [s]")
    return drawn


#: Start-up offsets smaller than these (roll/pitch rad, heave m) go unmentioned.
_START_NOTED = (math.radians(0.01), math.radians(0.01), 0.1e-3)


def start_offset_note(columns: Mapping, scenario: Mapping) -> str | None:
    """What the true pose at t = 0 is off the set-point by, and why (None when it is not).

    A run starts with the slides where the potentiometers read the inverse kinematics
    of the first set-point on the drawings' geometry (``CoSimulation._initial_state``);
    a platform built a few millimetres off its drawings (the as-built errors of the
    scenario's ``plant`` block, docs/paper-notes.md)
    then stands off that pose. The task-space loop measures it and removes it before
    the first step; joint control alone keeps it (the paper's Fig. 15a).
    """
    off = []
    for (_t, ref, true, _m, scale, unit, _z), floor in zip(TASK_AXES, _START_NOTED, strict=True):
        if not _has(columns, ref, true) or len(columns[true]) == 0:
            continue
        d = float(_col(columns, true)[0] - _col(columns, ref)[0])
        if abs(d) >= floor:
            off.append(f"{_t.split(') ')[1].split()[0].lower()} {d * scale:+.2f} {unit}")
    if not off:
        return None
    mode = (scenario.get("controller") or {}).get("mode")
    fate = (
        "joint control alone keeps this offset"
        if mode == "joint_only"
        else "the task-space loop measures and removes it within about a second"
    )
    return (
        f"t = 0: the slides start at the drawings' inverse kinematics of the set-point; the "
        f"platform as built stands off it by {', '.join(off)}: {fate}."
    )


#: The per-leg figures of a run: name -> (columns a leg's panel needs, its curves
#: (column, scale, style; the leg's colour unless the style says), y label, title)
_LEG_FIGURES: dict[str, tuple[tuple[str, ...], tuple[tuple[str, float, dict], ...], str, str]] = {
    "joints": (
        ("q{i}_ref_m", "q{i}_m"),
        (("q{i}_ref_m", 1e3, {"color": DESIRED, "lw": 1.4, "label": "set-point"}),
         ("q{i}_m", 1e3, {"color": OUTPUT, "lw": 1.2, "label": "position"})),
        "leg {i}: q{i} [mm]",
        "joint space, slide set-points vs positions",
    ),
    "valves": (
        ("u{i}_v",),
        (("u{i}_v", 1.0, {"lw": 0.9, "label": "valve {i}"}),),
        "u{i} [V]",
        "valve commands (0-10 V, 5 V closed)",
    ),
    "pressures": (
        ("p{i}a_pa", "p{i}b_pa"),
        (("p{i}a_pa", 1e-5, {"lw": 1.0, "label": "cap side (a)"}),
         ("p{i}b_pa", 1e-5, {"lw": 1.0, "ls": ":", "label": "rod side (b)"}),
         ("supply_pa", 1e-5, {"color": "k", "lw": 0.8, "ls": "--", "label": "supply"})),
        "leg {i} [bar abs]",
        "chamber pressures",
    ),
}  # fmt: skip

#: The figures of one run, by name (:func:`run_figures`), in the order they are written.
RUN_FIGURES = ("task_space", "joints", "valves", "pressures")


def run_figures(
    columns: Mapping[str, np.ndarray], scenario: Scenario | Mapping, only: str | None = None
) -> dict[str, Figure]:
    """The figures of one run, by name (:data:`RUN_FIGURES`), each only if its columns
    are present; ``only`` builds just the one named. Scheduled faults are shaded.

    ``task_space``: desired (blue) vs output (green), roll/pitch in deg, height in mm
    (Figs. 14/16); ``joints``: slide set-points vs positions (mm); ``valves``: valve
    voltages (V); ``pressures``: chamber pressures (bar absolute, with the supply).
    """
    spec = scenario if isinstance(scenario, Scenario) else None
    scenario = as_tree(scenario)
    t = _col(columns, "time_s")
    figs: dict[str, Figure] = {}
    if only in (None, "task_space"):
        fig = Figure(figsize=(8, 8))
        drawn = _task_axes(columns, fig.subplots(3, 1, sharex=True))
        if drawn:
            drawn[0].legend(loc="best", fontsize=8)
            fig.suptitle(_title(scenario, "task space, desired (blue) vs output (green)"))
            note = start_offset_note(columns, scenario)
            if note:  # under the time axis, in the room margins() leaves for it
                fig.text(0.01, 0.01, note, fontsize=7, va="bottom", wrap=True)
            figs["task_space"] = fig

    for name, (needs, curves, ylabel, what) in _LEG_FIGURES.items():
        legs = [i for i in (1, 2, 3) if _has(columns, *(c.format(i=i) for c in needs))]
        if only not in (None, name) or not legs:
            continue
        valves = name == "valves"  # one panel per valve: legs 2 and 3 move alike in pitch
        fig = Figure(figsize=(8, 1.2 + 1.9 * len(legs) if valves else 8))
        axes = fig.subplots(len(legs), 1, sharex=True, sharey=valves, squeeze=False)[:, 0]
        for ax, i in zip(axes, legs, strict=True):
            for col, scale, style in curves:
                if col.format(i=i) in columns:
                    style = {"color": LEG_COLOURS[i], **style, "label": style["label"].format(i=i)}
                    _line(ax, t, _col(columns, col.format(i=i)) * scale, **style)
            if valves:
                ax.axhline(5.0, color="k", lw=0.6, ls="--",
                           label="closed centre (5 V)" if i == legs[0] else None)  # fmt: skip
                ax.set_ylim(-0.3, 10.3)
                ax.set_ylabel(ylabel.format(i=i))
            else:
                ax.set_ylabel(ylabel.format(i=i), color=LEG_COLOURS[i])
            ax.grid(True, alpha=0.3)
            if valves:
                ax.legend(loc="upper right", fontsize=8)
        if not valves:
            axes[0].legend(loc="best", fontsize=8)
        axes[-1].set_xlabel("time [s]")
        fig.suptitle(_title(scenario, what))
        figs[name] = fig

    if scenario.get("faults"):  # the typed scenario's schedule (validated once if a dict)
        spec = spec if spec is not None else as_scenario(scenario)
    for name, fig in figs.items():
        if spec is not None and spec.faults:
            _shade_faults(fig, spec)
        margins(fig, bottom=0.9 if name == "task_space" and fig.texts else 0.55)
    return figs


def plot_run(columns: Mapping[str, np.ndarray], scenario: Mapping, out_dir) -> list[Path]:
    """Write the figures of one run as PNG files.

    Parameters
    ----------
    columns : mapping of str to ndarray
        The logged time series (SI), see :func:`simpro_mj.analysis.metrics.compute_metrics`.
    scenario : mapping
        The resolved scenario (name and mode in the titles).
    out_dir : path
        Existing folder for the files.

    Returns
    -------
    list of Path
        ``task_space.png`` (desired blue vs output green, roll/pitch in deg,
        height in mm; Figs. 14/16), ``joints.png`` (slide set-points vs
        positions, mm), ``valves.png`` (valve voltages, V) and
        ``pressures.png`` (chamber pressures, bar absolute, with the supply
        pressure when logged), each only if its columns are present. Scheduled
        faults (``scenario["faults"]``) are shaded on every figure.
    """
    out_dir = Path(out_dir)
    figures = run_figures(columns, scenario)
    paths = [save(fig, out_dir / f"{name}.png") for name, fig in figures.items()]
    if _has(columns, "head_fx_mps2", "veh_fx_mps2"):  # a cueing run
        cue = cueing_figures(columns, scenario)
        paths += [save(fig, out_dir / f"{name}.png", DPI) for name, fig in cue.items()]
    return paths


def _paper_figure(scenario: Mapping) -> str | None:
    """The paper's figure a scenario reproduces, from its description ("Fig. 16: ...")."""
    m = re.match(r"\s*Figs?\. ([0-9a-c/]+)", str(scenario.get("description") or ""))
    return m.group(1) if m else None


def compare_title(scenario: Mapping) -> str:
    """compare.png's title: the paper's Fig. 15 a/b, or its comparison on another figure's
    steps (``step_all`` is Fig. 16, whose paper figure shows the task-space run only)."""
    name = scenario.get("name", "run")
    fig = _paper_figure(scenario)
    if fig == "15":
        what = "the paper's Fig. 15 a/b"
    elif fig:
        what = f"Fig. 15 a/b's comparison on Fig. {fig}'s steps (the paper shows b only)"
    else:
        what = "Fig. 15 a/b's comparison"
    return f"{name}: {what} (blue desired, green output)"


def compare_figure(
    columns_joint_only: Mapping[str, np.ndarray],
    columns_task_space: Mapping[str, np.ndarray],
    scenario: Mapping,
) -> Figure:
    """Fig. 15 a/b in one figure: joint control only (left) vs task-space control (right).

    Rows roll, pitch (deg) and height (mm) with shared y limits per row, so
    the steady-state error of a) and its absence in b) read directly.
    """
    fig = Figure(figsize=(12, 8))
    grid = fig.subplots(3, 2, sharex=True, sharey="row")
    _task_axes(columns_joint_only, grid[:, 0])
    _task_axes(columns_task_space, grid[:, 1])
    grid[0, 0].set_title("a) joint control only")
    grid[0, 1].set_title("b) joint control + kinematic task-space control")
    grid[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle(compare_title(scenario))
    return margins(fig, top=0.75, wspace=0.08)


def plot_compare(
    columns_joint_only: Mapping[str, np.ndarray],
    columns_task_space: Mapping[str, np.ndarray],
    scenario: Mapping,
    out_dir,
) -> list[Path]:
    """Write :func:`compare_figure` as ``compare.png``.

    Returns
    -------
    list of Path
        ``[out_dir / "compare.png"]``.
    """
    fig = compare_figure(columns_joint_only, columns_task_space, scenario)
    return [save(fig, Path(out_dir) / "compare.png")]


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
    for ax, (title, ref, true, _m, scale, unit, off) in zip(axes[:3], TASK_AXES, strict=True):
        axis = ref.split("_")[0]
        ax.plot(*envelope(t, (np.asarray(columns[ref], float) - off) * scale),
                color=DESIRED, lw=1.3, label=f"{law} set-point")  # fmt: skip
        ax.plot(*envelope(t, (np.asarray(columns[true], float) - off) * scale),
                color=OUTPUT, lw=1.1, label="platform")  # fmt: skip
        if box is not None:
            for k, v in enumerate(box[axis]):
                label = "workspace box" if axis == "roll" and k == 0 else None
                ax.axhline((v - off) * scale, color="k", ls="--", lw=0.7, label=label)
        ax.set_ylabel(f"{title.split(') ')[1].lower()} [{unit}]")
        ax.grid(True, alpha=0.3)
    for i in (1, 2, 3):
        axes[3].plot(*envelope(t, np.asarray(columns[f"q{i}_m"], float) * 1e3),
                     color=LEG_COLOURS[i], lw=1.0, label=f"leg {i}")  # fmt: skip
    axes[3].axhline(0.0, color="k", lw=0.8, label="end stops")
    axes[3].axhline(500.0, color="k", lw=0.8)
    axes[3].set(ylabel="stroke [mm]", xlabel="time [s]")
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
