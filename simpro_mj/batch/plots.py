"""Summary figures of a batch (``OUT/plots/*.png``), matplotlib Agg only.

Per scenario file (``<folder>`` is its folder name under OUT):

* ``<folder>_vs_<label>.png``: metrics against the swept parameter (the
  gain ``controller.outer.gains`` if swept, else the numeric grid path with
  the most values), one line per combination of the other grid values:
  rms error of roll, pitch (deg) and heave (mm), and the measured envelope
  growth rate (1/s) with the analytic one dashed. Unstable variants are
  ringed in red; the analytic limit is a dashed vertical line, the simulated
  one dotted; each is in the legend only when drawn. Not drawn for Monte
  Carlo files or grids without a numeric path.
* ``<folder>_responses.png``: the task-space responses of every variant
  overlaid (roll, pitch in deg; heave in mm) with their set-points dashed:
  one black line when every variant has the same, else each variant's in its
  colour; one colour per variant (Monte Carlo: per grid combination);
  unstable or failed runs in grey behind, the y range that of the others. It reads
  the variants' ``timeseries.csv``: under ``--timeseries failing`` it overlays
  those written (its title says of how many), under ``none`` it is not drawn.
* ``<folder>_mc_ss_error.png`` (Monte Carlo files): box plots with the
  samples of the absolute steady-state error per axis, one box per grid
  combination (e.g. joint_only vs task_space), log scale.
* ``<folder>_map.png`` (Monte Carlo files drawing the payload and the Coulomb
  friction): payload x the smallest leg's friction, coloured by verdict, overshoot
  and settling (:mod:`simpro_mj.batch.robustness`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from controllers.geometry import H0
from simpro_mj.analysis.cue_metrics import FLOORS
from simpro_mj.analysis.verdict import FINISHED_STATUSES, VERDICTS
from simpro_mj.batch.robustness import map_figure
from simpro_mj.batch.stability import Analytic
from simpro_mj.batch.summary import AXES, Row
from simpro_mj.batch.tables import StabilityLimit, number
from simpro_mj.config.sweep import format_value
from simpro_mj.report.figures import envelope, log_ticks, save
from simpro_mj.report.results import read_timeseries

__all__ = [
    "plot_summary",
    "metric_vs_param_figure",
    "responses_figure",
    "mc_figure",
    "cue_comparison_figure",
    "cue_tradeoff_figure",
]

DPI = 110
MAX_OVERLAY = 100
_GAIN = "controller.outer.gains"


def _swept_number(rows: list[Row], grid) -> str | None:
    """The grid path drawn along x: the gain if swept, else the numeric path with the
    most values (None: no path is a number with two values or more)."""
    count = {p: len({number(r.values.get(p)) for r in rows}) for p in grid}
    numeric = [p for p in grid if count[p] >= 2 and all(number(r.values.get(p)) is not None
                                                          for r in rows)]  # fmt: skip
    if not numeric:
        return None
    return _GAIN if _GAIN in numeric else max(numeric, key=count.__getitem__)


def _combo(row: Row, paths, skip=None) -> str:

    parts = [f"{p.split('.')[-1]}={format_value(row.values[p])}" for p in paths if p != skip]
    return ", ".join(parts) or "all"


def _colours(labels: list[str]) -> dict[str, str]:
    uniq = list(dict.fromkeys(labels))
    return {lab: f"C{i % 10}" for i, lab in enumerate(uniq)}


def metric_vs_param_figure(rows: list[Row], info: Mapping, stability: list[StabilityLimit]):
    """Metrics against the swept parameter (module docstring), or None if not applicable;
    its label is the swept key's last part."""
    grid = info["grid_paths"]
    xpath = None if info["monte_carlo"] else _swept_number(rows, grid)
    if xpath is None:
        return None
    label = xpath.split(".")[-1]
    groups: dict[str, list[Row]] = {}
    for r in rows:
        groups.setdefault(_combo(r, grid, skip=xpath), []).append(r)
    colours = _colours(list(groups))
    has_growth = any(r.growth_rate_1_s is not None for r in rows)
    n = 3 + int(has_growth)
    fig = Figure(figsize=(8, 2.6 * n), layout="constrained")
    fig.set_label(label)
    axes = fig.subplots(n, 1, sharex=True)
    ringed = False
    for name, members in groups.items():
        members = sorted(members, key=lambda r: number(r.values[xpath]) or math.inf)
        xs = np.array([number(r.values[xpath]) for r in members])
        bad = np.array([r.stable is False or r.status != "ok" for r in members])
        col = colours[name]
        for i, ax in enumerate(axes[:3]):
            ys = np.array([r.axes[i].rms_err or np.nan for r in members], float)
            ax.plot(xs, ys, "o-", color=col, lw=1.2, ms=4, label=name)
            if bad.any():
                first = not ringed
                ringed = True
                ax.plot(xs[bad], ys[bad], "o", mfc="none", mec="red", ms=9, mew=1.5,
                        label="unstable or not ok" if first else None)  # fmt: skip
        if has_growth:
            ax = axes[3]
            gs = np.array([r.growth_rate_1_s for r in members], float)
            ax.plot(xs, gs, "o-", color=col, lw=1.2, ms=4, label=f"{name} (simulated)")
            if bad.any():
                ax.plot(xs[bad], gs[bad], "o", mfc="none", mec="red", ms=9, mew=1.5)
            ana = np.array([(r.analytic or Analytic()).growth_rate_1_s for r in members], float)
            if np.isfinite(ana).any():
                ax.plot(xs, ana, "--", color=col, lw=1.0, label=f"{name} (analysis)")
    limits = set()  # which kinds of limit line are drawn (each in the legend once)
    for s in stability:
        name = ", ".join(f"{k.split('.')[-1]}={v}" for k, v in s.group.items()) or "all"
        col = colours.get(name, "k")
        limit_a, limit_s = s.analytic_limit, s.simulated_limit
        for kind, x, ls, lw in (("analytic", limit_a, "--", 0.9), ("simulated", limit_s, ":", 1.2)):
            if x is None or not math.isfinite(x):
                continue
            for k, ax in enumerate(axes):
                first = k == 0 and kind not in limits
                ax.axvline(x, color=col, ls=ls, lw=lw, label=f"{kind} limit" if first else None)
            limits.add(kind)
    for ax, (axis, unit, _) in zip(axes[:3], AXES, strict=True):
        ax.set_ylabel(f"{axis} rms error [{unit}]")
        ys = np.concatenate([np.asarray(ln.get_ydata(), float) for ln in ax.lines] or [np.empty(0)])
        ys = ys[np.isfinite(ys) & (ys > 0)]
        if ys.size and ys.max() > 10 * ys.min():  # a log axis only where it spans a decade
            ax.set_yscale("log")
            log_ticks(ax, "y")
        ax.grid(True, which="both", alpha=0.3)
    if has_growth:
        axes[3].axhline(0.0, color="k", lw=0.6)
        axes[3].set_ylabel("envelope growth [1/s]")
        axes[3].grid(True, alpha=0.3)
        axes[3].legend(loc="best", fontsize=7)
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel(f"{xpath}" + (" (K K_I, 1/s)" if xpath == _GAIN else ""))
    fig.suptitle(f"{info['scenario']}: metrics vs {label}", fontsize=9)
    return fig


_RESPONSE_COLUMNS = ("time_s", "roll_rad", "pitch_rad", "heave_m", "roll_ref_rad",
                     "pitch_ref_rad", "heave_ref_m")  # fmt: skip


#: Line styles of the other grid values when the variants are coloured by one number.
_STYLES = ("-", ":", "-.", (0, (3, 1, 1, 1, 1, 1)))


def _shade_by_number(series, labels: list[str], info: Mapping):
    """Colours by the swept number (the gain if swept) and line styles by the rest of
    the grid, for more than 12 variants in colour (too many to name in a legend).

    Returns ``(colours, group_of, groups, mappable)``: each label's colour and its
    group (the rest of the grid as text), each group's line style, the colour bar's
    mappable and label; or None to colour by variant.
    """
    grid = info["grid_paths"]
    ok = [(r, lab) for (r, _), lab in zip(series, labels, strict=True)
          if not (r.stable is False or r.status != "ok")]  # fmt: skip
    if info["monte_carlo"] or len({lab for _, lab in ok}) <= 12 or not grid:
        return None
    path = _swept_number([r for r, _ in series], grid)
    if path is None:
        return None
    rest = [_combo(r, grid, skip=path) for r, _ in series]
    kinds = list(dict.fromkeys(rest))
    if len(kinds) > len(_STYLES):
        return None
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    xs = [number(r.values[path]) or 0.0 for r, _ in series]  # path's values are numbers
    norm = Normalize(min(xs), max(xs))
    cmap = colormaps["viridis"]
    colours = {lab: cmap(norm(x)) for lab, x in zip(labels, xs, strict=True)}
    groups = {kind: _STYLES[i] for i, kind in enumerate(kinds)}
    group_of = dict(zip(labels, rest, strict=True))
    scale = ScalarMappable(norm=norm, cmap=cmap)
    return colours, group_of, groups, (scale, path + (" (K K_I, 1/s)" if path == _GAIN else ""))


def responses_figure(rows: list[Row], info: Mapping, batch_out: Path):
    """Task-space responses of the variants overlaid (module docstring); None if none
    has a time series."""
    grid = info["grid_paths"]
    runs = [r for r in rows if r.status in FINISHED_STATUSES and r.folder][:MAX_OVERLAY]
    series = []
    for r in runs:
        path = Path(batch_out) / r.folder / "timeseries.csv"
        if path.is_file():
            series.append((r, read_timeseries(path, _RESPONSE_COLUMNS)))
    if not series:
        return None
    labels = [_combo(r, grid) if info["monte_carlo"] else r.variant for r, _ in series]
    colours = _colours(labels)
    group_of: dict[str, str] = {}
    groups: dict[str, object] = {}
    shade = _shade_by_number(series, labels, info)  # too many variants to name one by one
    if shade is not None:
        colours, group_of, groups, (mappable, bar_label) = shade
    # one dashed set-point when every variant has the same, else each its own
    refs = [
        np.column_stack([c[f"{a}_ref_{'m' if a == 'heave' else 'rad'}"] for a, _u, _s in AXES])
        for _, c in series
    ]
    same_ref = all(x.shape == refs[0].shape and np.allclose(x, refs[0]) for x in refs)
    fig = Figure(figsize=(9, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    seen, n_bad = set(), 0
    span = [[np.inf, -np.inf] for _ in AXES]  # y range of the stable runs and set-points
    for n, ((r, c), lab) in enumerate(zip(series, labels, strict=True)):
        t = c["time_s"]
        # unstable runs in grey behind: they would hide the others' scale
        bad = r.stable is False or r.status != "ok"
        n_bad += bad
        for k, (ax, (axis, _unit, scale)) in enumerate(zip(axes, AXES, strict=True)):
            true = "heave_m" if axis == "heave" else f"{axis}_rad"
            ref = "heave_ref_m" if axis == "heave" else f"{axis}_ref_rad"
            home = H0 if axis == "heave" else 0.0  # heave from the home height
            y = (c[true] - home) * scale
            yr = (c[ref] - home) * scale
            if bad:
                label = "unstable or not ok" if n_bad == 1 and k == 0 else None
                ax.plot(*envelope(t, y), color="0.6", lw=0.5, alpha=0.35, zorder=1, label=label)
            else:
                label = lab if lab not in seen and k == 0 else None
                group = group_of.get(lab)
                if group is not None:  # the line style names the rest of the grid, once
                    label = group if k == 0 and group not in seen else None
                    seen.add(group)
                style = "-" if group is None else groups.get(group, "-")
                ax.plot(*envelope(t, y), color=colours[lab], lw=0.8, alpha=0.85, zorder=2,
                        ls=style, label=label)  # fmt: skip
                fin = np.concatenate([y[np.isfinite(y)], yr[np.isfinite(yr)]])
                if fin.size:
                    span[k] = [min(span[k][0], fin.min()), max(span[k][1], fin.max())]
            if same_ref and n == 0:
                ax.plot(*envelope(t, yr), "k--", lw=1.0, zorder=3,
                        label="set-point (all variants)" if k == 0 else None)  # fmt: skip
            elif not same_ref and not bad:
                first = k == 0 and not any(
                    ln.get_label().startswith("set-point") for ln in axes[0].lines
                )
                label = "set-point (dashed, the variant's colour)" if first else None
                ax.plot(*envelope(t, yr), color=colours[lab], ls="--", lw=0.9, zorder=3,
                        label=label)  # fmt: skip
        if not bad:
            seen.add(lab)
    for k, (ax, (axis, unit, _)) in enumerate(zip(axes, AXES, strict=True)):
        lo, hi = span[k]
        if np.isfinite(lo) and np.isfinite(hi):
            pad = 0.15 * max(hi - lo, 1e-3)
            ax.set_ylim(lo - pad, hi + pad)
        ax.set_ylabel(f"{axis} from home [{unit}]" if axis == "heave" else f"{axis} [{unit}]")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    if shade is not None:  # line styles in the legend, colours on the bar
        legend = axes[0].legend(loc="best", fontsize=7)
        for handle, text in zip(legend.legend_handles, legend.get_texts(), strict=True):
            if text.get_text() in groups:
                handle.set_color("0.3")
        fig.colorbar(mappable, ax=list(axes), shrink=0.6, pad=0.01).set_label(bar_label)
    elif len(seen) <= 12:
        axes[0].legend(loc="best", fontsize=7)
    else:  # too many variants to name: the legend keeps the set-point and the grey runs
        for line in axes[0].lines:
            if line.get_label() in seen:
                line.set_label("_" + line.get_label())
        axes[0].legend(loc="best", fontsize=7)
    what = "set-point" if same_ref else "set-points"
    # a batch that wrote only some time series (--timeseries failing) says whose these are
    whose = f"{len(series)} variants"
    if len(series) < len(runs):
        whose = f"{len(series)} of {len(runs)} variants (those with a time series)"
    fig.suptitle(
        f"{info['scenario']}: task-space responses of {whose} and their {what} (dashed)",
        fontsize=10,
    )
    return fig


def mc_figure(rows: list[Row], info: Mapping):
    """Distribution of |steady-state error| per axis and grid combination (Monte Carlo)."""
    if not info["monte_carlo"]:
        return None
    grid = info["grid_paths"]
    ok = [r for r in rows if r.status == "ok"]
    if not ok:
        return None
    groups: dict[str, list[Row]] = {}
    for r in ok:
        groups.setdefault(_combo(r, grid), []).append(r)
    names = list(groups)
    fig = Figure(figsize=(4 + 2 * len(names), 4.5), layout="constrained")
    axes = fig.subplots(1, 3)
    rng = np.random.default_rng(0)  # jitter of the dots only
    for i, (ax, (axis, unit, _)) in enumerate(zip(axes, AXES, strict=True)):
        data = []
        for name in names:
            v = [abs(e) for r in groups[name] if (e := r.axes[i].ss_err) is not None]
            data.append(np.maximum(np.array(v, float), 1e-9))
        ax.boxplot(data, showfliers=False)
        ax.set_xticks(range(1, len(names) + 1), names, rotation=20, fontsize=8)
        for i, d in enumerate(data, start=1):
            ax.plot(
                i + rng.uniform(-0.12, 0.12, d.size),
                d,
                "o",
                ms=3,
                alpha=0.6,
                color=f"C{(i - 1) % 10}",
            )
        ax.set_yscale("log")
        ax.set_ylabel(f"|{axis} steady-state error| [{unit}]")
        ax.grid(True, which="both", alpha=0.3)
    n = max(len(g) for g in groups.values())
    fig.suptitle(
        f"{info['scenario']}: steady-state error over {n} Monte Carlo samples", fontsize=10
    )
    return fig


def plot_summary(report, jobs) -> list[Path]:
    """All summary figures of a batch :class:`~simpro_mj.batch.summary.Report`."""
    out = Path(report.out) / "plots"
    out.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    for info in report.files:
        if info["error"]:
            continue
        rows = [
            r
            for r, j in zip(report.rows, jobs, strict=True)
            if j.folder.split("/")[0] == info["folder"] and j.variant != "-"
        ]
        if not rows:
            continue
        stab = [s for s in report.stability if s.scenario == info["scenario"]]
        table = next((t for t in report.robustness if t.scenario == info["scenario"]), None)
        for fig, name in (
            (metric_vs_param_figure([r for r in rows if r.status != "invalid"], info, stab),
             "{folder}_vs_{label}"),
            (responses_figure(rows, info, Path(report.out)), "{folder}_responses"),
            (mc_figure(rows, info), "{folder}_mc_ss_error"),
            (cue_tradeoff_figure(rows, info), "{scenario}_cue_tradeoff"),
            (cue_comparison_figure(rows, info), "{scenario}_cue_laws"),
            (None if table is None else map_figure(rows, table), "{folder}_map"),
        ):  # fmt: skip
            if fig is not None:
                name = name.format(label=fig.get_label(), **info)
                paths.append(save(fig, out / f"{name}.png", DPI))
    return paths


def cue_comparison_figure(rows: list[Row], info: Mapping):
    """Cueing laws side by side: per vehicle input (the grid's telemetry) and law, the
    perceived correlation, mean lag and worst onset delay of the channel the vehicle
    drives (``cue_main_channel``) and the felt false rotation, the floors dashed.
    Every run that ran to its end is drawn (a cue run's verdict on its final window,
    ``limit_cycle`` or ``not_settled``, leaves its cue figures whole). None unless the
    rows hold two laws or more."""
    pts = [r for r in rows if r.cue.get("cue_algorithm") is not None and r.status in VERDICTS]
    laws = []
    for r in pts:
        law = _law_label(r)
        if law not in laws:
            laws.append(law)
    if len(laws) < 2:
        return None
    inputs = []
    for r in pts:
        key = _input_label(r)
        if key not in inputs:
            inputs.append(key)
    panels = (  # the floors (FLOORS): the correlation's per main channel
        ("correlation", "perceived correlation", None, False),
        ("lag", "mean lag (s)", FLOORS.mean_lag_s, True),
        ("onset", "onset delay, worst (s)", FLOORS.onset_delay_s, True),
        ("false_rot", "felt false rotation (s)", FLOORS.false_rotation_s, True),
    )
    fig = Figure(figsize=(11, 3.4), layout="constrained")
    axes = fig.subplots(1, len(panels))
    width = 0.8 / len(laws)
    for ax, (what, label, floor, below) in zip(axes, panels, strict=True):
        for j, law in enumerate(laws):
            vals = []
            for key in inputs:
                hit = next(
                    (x for x in pts if _law_label(x) == law and _input_label(x) == key), None
                )
                vals.append(np.nan if hit is None else _main(hit, what))
            x = np.arange(len(inputs)) + (j - (len(laws) - 1) / 2) * width
            ax.bar(x, vals, width, label=law)
        if floor is None:  # the correlation's floor of each input's main channel
            for i, key in enumerate(inputs):
                r = next(x for x in pts if _input_label(x) == key)
                main = "lateral_f" if r.cue.get("cue_main_channel") == "lat" else "longitudinal_f"
                level = FLOORS.correlation[main]
                ax.plot([i - 0.45, i + 0.45], [level, level], color="k", ls="--", lw=1)
            ax.set_ylim(0.0, 1.6)  # room for the legend above the bars
            ax.set_yticks(np.linspace(0.0, 1.0, 6))
        else:
            ax.axhline(floor, color="k", ls="--", lw=1)
        ax.set_xticks(np.arange(len(inputs)), inputs, fontsize=7, rotation=20, ha="right")
        ax.set_title(label + (" (floor: at most)" if below else " (floor: at least)"), fontsize=8)
        ax.grid(True, axis="y", alpha=0.3)
        ax.tick_params(labelsize=7)
    axes[0].legend(fontsize=7, loc="upper center", framealpha=0.9)
    fig.suptitle(
        f"{info['scenario']}: cueing laws side by side, each input's main channel "
        "(dashed: the floors)",
        fontsize=10,
    )
    return fig


def _law_label(r: Row) -> str:
    law = "classical" if r.cue.get("cue_algorithm") == "classical_washout" else "MPC"
    extra = [
        format_value(v)
        for k, v in r.values.items()
        if "telemetry" not in k and "manoeuvre" not in k
    ]
    text = " ".join(extra)
    for key, name in (("preview_s=", "preview"), ("lead_s=", "lead")):
        if key in text:
            law += f", {name} " + text.split(key)[-1].split(",")[0].split(" ")[0] + " s"
    return law


def _input_label(r: Row) -> str:
    vals = [format_value(v) for k, v in r.values.items() if "telemetry" in k]
    return vals[0].removesuffix(".csv") if vals else r.scenario


def _main(r: Row, what: str) -> float:
    """The figure of the channel the vehicle input drives (``cue_main_channel``); the
    false rotation: the longer of roll and pitch."""
    if what == "false_rot":
        both = [r.cue.get("cue_roll_false_rot_s"), r.cue.get("cue_pitch_false_rot_s")]
        vals = [float(v) for v in both if v is not None]
        return max(vals) if vals else np.nan
    side = r.cue.get("cue_main_channel") or "long"
    v = r.cue.get(f"cue_{side}_{'corr' if what == 'correlation' else what + '_s'}")
    return np.nan if v is None else float(v)


def cue_tradeoff_figure(rows: list[Row], info: Mapping):
    """Perceived longitudinal correlation against the pitch workspace used, one
    point per variant labelled with its values and its valve saturation (the
    marker's area grows with it). None when the rows have no cueing columns."""
    pts = [r for r in rows if r.cue.get("cue_long_corr") is not None and r.status == "ok"]
    if not pts:
        return None
    fig = Figure(figsize=(7.5, 5), layout="constrained")
    ax = fig.add_subplot()
    for n, r in enumerate(pts):
        x = float(r.cue["cue_pitch_box_frac"])
        y = float(r.cue["cue_long_corr"])
        sat = float(r.cue.get("cue_valve_sat_frac") or 0.0)
        label = "variant (area, 'sat': time with a valve at a rail)" if n == 0 else None
        ax.scatter([x], [y], s=30 + 3000 * sat, color="tab:red", alpha=0.7, label=label)
        label = ", ".join(f"{k.split('.')[-1]}={format_value(v)}" for k, v in r.values.items())
        ax.annotate(f"{label}; sat {100 * sat:.1f} %", (x, y), fontsize=6, xytext=(4, 3),
                    textcoords="offset points")  # fmt: skip
    ax.set_xlabel("pitch workspace used (fraction of the cueing box)")
    ax.set_ylabel("perceived longitudinal correlation")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.suptitle(f"{info['scenario']}: cue correlation vs pitch workspace used")
    return fig
