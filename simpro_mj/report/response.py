"""What ``simpro-sim response`` writes and prints: the frequency responses as CSV,
figures and a summary (pose response, and ``--chain``: vehicle to head).

The measurements and predictions are :mod:`simpro_mj.analysis.response` and
:mod:`simpro_mj.analysis.chain_response`; :func:`write_result` installs a result
folder as a whole (:func:`simpro_mj.report.folders.install_folder`).
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from simpro_mj.report.figures import log_ticks, margins, save
from simpro_mj.report.folders import install_folder
from simpro_mj.report.results import jsonable

if TYPE_CHECKING:  # the records' module loads the analysis: when a response is summarised
    from simpro_mj.analysis.chain_response import ChainSummary
    from simpro_mj.analysis.response_summary import CurveFigures, PoseResponse


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return "nan" if not math.isfinite(v) else f"{v:.6g}"
    return str(v)


def csv_text(rows: list[dict], columns) -> str:
    """The rows (documents' dicts) as CSV with the ``columns`` header, in that order."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([_cell(r[c]) for c in columns])
    return buf.getvalue()


def plot(resp: PoseResponse, axes_in, title: str, folder: Path) -> list[str]:
    """``bode.png`` (excited axes) and ``cross_axis.png`` into ``folder``."""
    figs = bode_figures(resp, axes_in, title)
    return [save(fig, folder / f"{name}.png", 110).name for name, fig in figs.items()]


#: measured points per signal: marker, and the prediction's line style
_SIGNALS = (("true", "o", "-"), ("measured", "x", "--"))


def bode_figures(resp: PoseResponse, axes_in, title: str) -> dict:
    """``bode`` and ``cross_axis`` figures of a pose response on the excited axes
    ``axes_in``; ``title``: the scenario and its loop.

    The measured points are markers; the linearised loop's prediction is a
    curve through its dense grid (``predicted_curves``), and the bottom row
    the difference at the measured frequencies.
    """
    from matplotlib.figure import Figure

    rows = resp.rows
    figs = {}
    fig = Figure(figsize=(4.2 * len(axes_in), 8.5))
    ax = fig.subplots(3, len(axes_in), squeeze=False, sharex=True)
    for c, a in enumerate(axes_in):
        for k, (sig, marker, ls) in enumerate(_SIGNALS):
            rs = [r for r in rows if r.input_axis == a and r.output_axis == a and r.signal == sig]
            f = [r.frequency_hz for r in rs]
            colour = f"C{k}"
            ax[0, c].semilogx(f, [r.gain_db for r in rs], marker, color=colour, ls="none",
                              label=f"measured, {sig} pose")  # fmt: skip
            ax[1, c].semilogx(f, [r.phase_deg for r in rs], marker, color=colour, ls="none")
            curve = resp.predicted_curves.get(a)
            if curve:
                fc, bode = curve.frequency_hz, getattr(curve, sig)
                ax[0, c].semilogx(fc, bode.gain_db, color="k", ls=ls, lw=1,
                                  label=f"predicted, {sig} pose")  # fmt: skip
                ax[1, c].semilogx(fc, bode.phase_deg, color="k", ls=ls, lw=1)
            with_pred = [r for r in rs if r.diff_db is not None and r.diff_deg is not None]
            if with_pred:
                fp = [r.frequency_hz for r in with_pred]
                ax[2, c].semilogx(fp, [r.diff_db for r in with_pred], marker, color=colour,
                                  ls="none", label=f"gain (dB), {sig}")  # fmt: skip
                ax[2, c].semilogx(fp, [(r.diff_deg or 0.0) / 10 for r in with_pred], marker,
                                  color=colour, ls="none", mfc="none", alpha=0.6,
                                  label=f"phase (deg/10), {sig}")  # fmt: skip
        ax[0, c].axhline(-3, color="r", lw=0.6, ls=":", label="-3 dB")
        ax[2, c].axhline(0, color="k", lw=0.6)
        ax[0, c].set_title(f"{a}: set-point -> pose", fontsize=9)
        ax[0, c].set_ylabel("gain (dB)")
        ax[1, c].set_ylabel("phase (deg)")
        ax[2, c].set_ylabel("measured - predicted")
        ax[2, c].set_xlabel("frequency (Hz)")
        for k in range(3):
            ax[k, c].grid(alpha=0.3, which="both")
            log_ticks(ax[k, c])
        ax[0, c].legend(fontsize=7)
        if ax[2, c].lines[1:]:
            ax[2, c].legend(fontsize=7)
    fig.suptitle(f"{title}: closed-loop frequency response", fontsize=10)
    margins(fig, left=0.75, top=0.75, bottom=0.55, wspace=0.35, hspace=0.12)
    figs["bode"] = fig

    fig = Figure(figsize=(4.2 * len(axes_in), 3.8))
    ax = fig.subplots(1, len(axes_in), squeeze=False)
    for c, a in enumerate(axes_in):
        for o in ("roll", "pitch", "heave"):
            if o == a:
                continue
            rs = [
                r for r in rows if r.input_axis == a and r.output_axis == o and r.signal == "true"
            ]
            f = [r.frequency_hz for r in rs]
            unit = f"{'mm' if o == 'heave' else 'deg'}/{'mm' if a == 'heave' else 'deg'}"
            ax[0, c].loglog(f, [max(r.gain, 1e-9) for r in rs], "o", label=f"{o} ({unit})")
        ax[0, c].set_title(f"cross-axis: {a} command (measured, true pose)", fontsize=9)
        ax[0, c].set_xlabel("frequency (Hz)")
        ax[0, c].grid(alpha=0.3, which="both")
        log_ticks(ax[0, c])
        ax[0, c].legend(fontsize=7)
    fig.suptitle(f"{title}: cross-axis gains", fontsize=10)
    margins(fig, left=0.75, top=0.75, bottom=0.55, wspace=0.35)
    figs["cross_axis"] = fig
    return figs


def _fmt(v, d=1) -> str:
    return "-" if v is None else f"{v:.{d}f}"


def _bandwidth(v: CurveFigures | None) -> str:
    if v is None:
        return "-"
    if v.bandwidth_3db_hz is None and v.bandwidth_above_hz:
        return f">{v.bandwidth_above_hz:.2f}"
    return _fmt(v.bandwidth_3db_hz, 2)


def print_summary(resp: PoseResponse, title: str, folder, file=None) -> None:
    file = file or sys.stdout
    print(f"{title}, set-point -> true pose:", file=file)
    print(
        "axis    bandwidth_3db_hz  phase@0.5Hz  phase@1Hz  delay_ms | predicted: bw  "
        "ph@0.5  ph@1  delay",
        file=file,
    )
    for a, v in resp.axes.items():
        p = v.predicted
        print(
            f"{a:7s} {_bandwidth(v):>16s}  {_fmt(v.phase_deg_at_0_5_hz):>11s}  "
            f"{_fmt(v.phase_deg_at_1_hz):>9s}  {_fmt(v.equivalent_delay_ms):>8s} | "
            f"{_bandwidth(p):>12s}  {_fmt(p and p.phase_deg_at_0_5_hz):>6s}  "
            f"{_fmt(p and p.phase_deg_at_1_hz):>4s}  {_fmt(p and p.equivalent_delay_ms)}",
            file=file,
        )
    for a, by_signal in resp.agreement.items():
        t = by_signal["true"]
        print(
            f"{a}: measured - predicted up to 1 Hz: {_fmt(t.max_abs_diff_db, 2)} dB, "
            f"{_fmt(t.max_abs_diff_deg)} deg",
            file=file,
        )
    for f in resp.failed:
        print(f"FAILED {f.input} {f.period_ms} ms: {f.status}: {f.reason}", file=file)
    print(f"results: {folder}", file=file)


def write_result(out: Path, doc: dict, stem: str, csv_body: str, plotter) -> None:
    """``<stem>.csv``, ``<stem>.json`` and the plots (``plotter(doc, folder)``, or None)
    installed into ``out`` as a whole (:func:`simpro_mj.report.folders.install_folder`)."""

    def fill(tmp: Path) -> None:
        (tmp / f"{stem}.csv").write_text(csv_body, encoding="utf-8")
        files = [f"{stem}.csv", f"{stem}.json"]
        if plotter is not None:
            files += plotter(doc, tmp)
        doc["files"] = files
        text = json.dumps(jsonable(doc), indent=2)
        (tmp / f"{stem}.json").write_text(text + "\n", encoding="utf-8")

    install_folder(out, fill, kind="response")


def plot_chain(summary: ChainSummary, title: str, folder: Path) -> list[str]:
    """``chain_bode.png``: gain and phase per OMCT pair (measured, washout, predicted)."""
    fig = chain_figure(summary, title)
    if fig is None:
        return []
    return [save(fig, folder / "chain_bode.png", 110).name]


def chain_figure(summary: ChainSummary, title: str):
    """Gain and phase per OMCT pair: measured points, the washout alone and the
    linear chain as curves (``curves``); None when no pair was measured. ``title``:
    the scenario and its loop."""
    from matplotlib.figure import Figure

    # the chain's analysis loads python-control and scipy.signal: only when drawn
    from simpro_mj.analysis.chain_response import PAIRS

    tests = [n for n in PAIRS.values() if any(r.test == n for r in summary.rows)]
    if not tests:
        return None
    ncol = min(len(tests), 5)
    nrow = -(-len(tests) // ncol)
    fig = Figure(figsize=(3.3 * ncol, 5.0 * nrow))
    ax = fig.subplots(2 * nrow, ncol, squeeze=False)
    for k, name in enumerate(tests):
        g, p = ax[2 * (k // ncol), k % ncol], ax[2 * (k // ncol) + 1, k % ncol]
        rs = [r for r in summary.rows if r.test == name]
        f = [r.omega_rad_s for r in rs]
        g.semilogx(f, [r.gain_db for r in rs], "o", label="measured (co-simulation)")
        p.semilogx(f, [r.phase_deg for r in rs], "o")
        curve = summary.curves.get(name)
        for key, ls, label in (("washout", "--", "washout alone"), ("predicted", "-",
                                                                   "linear chain")):  # fmt: skip
            bode = getattr(curve, key) if curve is not None else None
            if bode is not None and curve is not None:
                w = curve.omega_rad_s
                g.semilogx(w, bode.gain_db, color="k", ls=ls, lw=1, label=label)
                p.semilogx(w, bode.phase_deg, color="k", ls=ls, lw=1)
        g.set_title(f"{name} ({rs[0].input} -> {rs[0].output})", fontsize=9)
        g.set_ylabel(f"gain (dB, {rs[0].unit})", fontsize=7)
        p.set_ylabel("phase (deg)", fontsize=7)
        p.set_xlabel("frequency (rad/s)", fontsize=8)
        for a in (g, p):
            log_ticks(a)
            a.grid(alpha=0.3, which="both")
            a.tick_params(labelsize=7)
        g.legend(fontsize=6)
    for k in range(len(tests), nrow * ncol):
        ax[2 * (k // ncol), k % ncol].axis("off")
        ax[2 * (k // ncol) + 1, k % ncol].axis("off")
    fig.suptitle(
        f"{title}: whole cueing chain, vehicle -> driver's head (OMCT frequencies)",
        fontsize=10,
    )
    margins(fig, left=0.6, right=0.15, top=0.6, bottom=0.5, wspace=0.55, hspace=0.45)
    return fig


def print_chain_summary(summary: ChainSummary, title: str, folder, file=None) -> None:
    file = file or sys.stdout
    print(
        f"{title}, vehicle -> driver's head, measured | washout alone"
        " | linear chain (gain dB, phase deg):",
        file=file,
    )
    for r in summary.rows:
        flag = "  (limits acted)" if r.rate_limited_pct > 0 or r.softened_pct > 0 else ""
        print(
            f"{r.test:15s} {r.omega_rad_s:6.2f} rad/s  "
            f"{r.gain_db:7.2f} {r.phase_deg:7.1f}"
            f" | {_fmt(r.washout_gain_db, 2):>7s} {_fmt(r.washout_phase_deg):>7s}"
            f" | {_fmt(r.predicted_gain_db, 2):>7s} {_fmt(r.predicted_phase_deg):>7s}{flag}",
            file=file,
        )
    if summary.prediction_note:
        print(summary.prediction_note, file=file)
    for f in summary.failed:
        print(f"FAILED {f.input} {f.period_ms} ms: {f.status}: {f.reason}", file=file)
    print(f"results: {folder}", file=file)
