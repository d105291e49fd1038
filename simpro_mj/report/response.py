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

from simpro_mj.report.folders import install_folder
from simpro_mj.report.results import jsonable

__all__ = [
    "CHAIN_CSV_COLUMNS",
    "CSV_COLUMNS",
    "csv_text",
    "plot",
    "plot_chain",
    "print_chain_summary",
    "print_summary",
    "write_result",
]

CSV_COLUMNS = (
    "input_axis",
    "output_axis",
    "signal",
    "frequency_hz",
    "omega_rad_s",
    "period_ms",
    "amplitude",
    "gain",
    "gain_db",
    "phase_deg",
    "predicted_gain_db",
    "predicted_phase_deg",
    "diff_db",
    "diff_deg",
    "saturated_pct",
)


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return "nan" if not math.isfinite(v) else f"{v:.6g}"
    return str(v)


def csv_text(rows: list[dict], columns=CSV_COLUMNS) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([_cell(r[c]) for c in columns])
    return buf.getvalue()


def plot(doc: dict, folder: Path) -> list[str]:
    """``bode.png`` (excited axes) and ``cross_axis.png`` into ``folder``."""
    # matplotlib when a figure is drawn, not when the response command starts
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = doc["rows"]
    axes_in = doc["axes_excited"]
    files = []
    fig, ax = plt.subplots(3, len(axes_in), figsize=(4.2 * len(axes_in), 8), squeeze=False)
    for c, a in enumerate(axes_in):
        for sig, style in (("true", "o"), ("measured", "x")):
            rs = [r for r in rows if r["input_axis"] == a and r["output_axis"] == a]
            rs = [r for r in rs if r["signal"] == sig]
            f = [r["frequency_hz"] for r in rs]
            ax[0, c].semilogx(f, [r["gain_db"] for r in rs], style, label=f"measured, {sig} pose")
            ax[1, c].semilogx(f, [r["phase_deg"] for r in rs], style)
            if rs and rs[0]["predicted_gain_db"] is not None:
                ls = "-" if sig == "true" else ":"
                ax[0, c].semilogx(f, [r["predicted_gain_db"] for r in rs], "k" + ls, lw=1,
                                  label=f"predicted, {sig}")  # fmt: skip
                ax[1, c].semilogx(f, [r["predicted_phase_deg"] for r in rs], "k" + ls, lw=1)
                ax[2, c].semilogx(f, [r["diff_db"] for r in rs], style + "-", label=f"dB, {sig}")
                ax[2, c].semilogx(f, [r["diff_deg"] / 10 for r in rs], style + "--",
                                  label=f"deg/10, {sig}")  # fmt: skip
        ax[0, c].axhline(-3, color="r", lw=0.6, ls="--")
        ax[0, c].set_title(f"{a}: set-point -> pose", fontsize=9)
        ax[0, c].set_ylabel("gain (dB)")
        ax[1, c].set_ylabel("phase (deg)")
        ax[2, c].set_ylabel("measured - predicted")
        ax[2, c].set_xlabel("frequency (Hz)")
        for k in range(3):
            ax[k, c].grid(alpha=0.3, which="both")
        ax[0, c].legend(fontsize=7)
        ax[2, c].legend(fontsize=7)
    fig.suptitle(f"{doc['scenario']} ({doc['mode']}): closed-loop frequency response", fontsize=10)
    fig.tight_layout()
    f = folder / "bode.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    files.append(f.name)

    fig, ax = plt.subplots(1, len(axes_in), figsize=(4.2 * len(axes_in), 3.5), squeeze=False)
    for c, a in enumerate(axes_in):
        for o in ("roll", "pitch", "heave"):
            if o == a:
                continue
            rs = [
                r for r in rows
                if r["input_axis"] == a and r["output_axis"] == o and r["signal"] == "true"
            ]  # fmt: skip
            f = [r["frequency_hz"] for r in rs]
            unit = f"{'mm' if o == 'heave' else 'deg'}/{'mm' if a == 'heave' else 'deg'}"
            ax[0, c].loglog(f, [max(r["gain"], 1e-9) for r in rs], "o-", label=f"{o} ({unit})")
        ax[0, c].set_title(f"cross-axis: {a} command", fontsize=9)
        ax[0, c].set_xlabel("frequency (Hz)")
        ax[0, c].grid(alpha=0.3, which="both")
        ax[0, c].legend(fontsize=7)
    fig.tight_layout()
    f = folder / "cross_axis.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    files.append(f.name)
    return files


def _fmt(v, d=1) -> str:
    return "-" if v is None else f"{v:.{d}f}"


def print_summary(doc: dict, folder, file=None) -> None:
    file = file or sys.stdout
    print(f"{doc['scenario']} ({doc['mode']}), set-point -> true pose:", file=file)
    print(
        "axis    bandwidth_3db_hz  phase@0.5Hz  phase@1Hz  delay_ms | predicted: bw  "
        "ph@0.5  ph@1  delay",
        file=file,
    )
    for a, v in doc["axes"].items():
        p = v.get("predicted") or {}
        bw = _fmt(v["bandwidth_3db_hz"], 2)
        if v["bandwidth_3db_hz"] is None and v.get("bandwidth_above_hz"):
            bw = f">{v['bandwidth_above_hz']:.2f}"
        pbw = _fmt(p.get("bandwidth_3db_hz"), 2)
        if p.get("bandwidth_3db_hz") is None and p.get("bandwidth_above_hz"):
            pbw = f">{p['bandwidth_above_hz']:.2f}"
        print(
            f"{a:7s} {bw:>16s}  {_fmt(v['phase_deg_at_0_5_hz']):>11s}  "
            f"{_fmt(v['phase_deg_at_1_hz']):>9s}  {_fmt(v['equivalent_delay_ms']):>8s} | "
            f"{pbw:>12s}  {_fmt(p.get('phase_deg_at_0_5_hz')):>6s}  "
            f"{_fmt(p.get('phase_deg_at_1_hz')):>4s}  {_fmt(p.get('equivalent_delay_ms'))}",
            file=file,
        )
    for a, v in doc["agreement"].items():
        t = v["true"]
        print(
            f"{a}: measured - predicted up to 1 Hz: {_fmt(t['max_abs_diff_db'], 2)} dB, "
            f"{_fmt(t['max_abs_diff_deg'])} deg",
            file=file,
        )
    for f in doc["failed"]:
        print(f"FAILED {f['axis']} {f['period_ms']} ms: {f['status']}: {f['reason']}", file=file)
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


CHAIN_CSV_COLUMNS = (
    "test",
    "input",
    "output",
    "unit",
    "frequency_hz",
    "omega_rad_s",
    "period_ms",
    "amplitude",
    "gain",
    "gain_db",
    "phase_deg",
    "washout_gain_db",
    "washout_phase_deg",
    "predicted_gain_db",
    "predicted_phase_deg",
    "platform_db",
    "platform_deg",
    "saturated_pct",
    "rate_limited_pct",
    "softened_pct",
)


def plot_chain(doc: dict, folder: Path) -> list[str]:
    """``chain_bode.png``: gain and phase per OMCT pair (measured, washout, predicted)."""
    # matplotlib when a figure is drawn, not when the response command starts
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    # the chain's analysis loads python-control and scipy.signal: only when drawn
    from simpro_mj.analysis.chain_response import PAIRS

    tests = [n for n in PAIRS.values() if any(r["test"] == n for r in doc["rows"])]
    if not tests:
        return []
    ncol = min(len(tests), 5)
    nrow = -(-len(tests) // ncol)
    fig, ax = plt.subplots(2 * nrow, ncol, figsize=(3.3 * ncol, 5.0 * nrow), squeeze=False)
    for k, name in enumerate(tests):
        g, p = ax[2 * (k // ncol), k % ncol], ax[2 * (k // ncol) + 1, k % ncol]
        rs = [r for r in doc["rows"] if r["test"] == name]
        f = [r["omega_rad_s"] for r in rs]
        g.semilogx(f, [r["gain_db"] for r in rs], "o", label="measured (co-simulation)")
        p.semilogx(f, [r["phase_deg"] for r in rs], "o")
        if rs[0]["washout_gain_db"] is not None:
            g.semilogx(f, [r["washout_gain_db"] for r in rs], "k--", lw=1, label="washout alone")
            p.semilogx(f, [r["washout_phase_deg"] for r in rs], "k--", lw=1)
        if rs[0]["predicted_gain_db"] is not None:
            g.semilogx(f, [r["predicted_gain_db"] for r in rs], "k-", lw=1, label="linear chain")
            p.semilogx(f, [r["predicted_phase_deg"] for r in rs], "k-", lw=1)
        g.set_title(f"{name} ({rs[0]['input']} -> {rs[0]['output']})", fontsize=9)
        g.set_ylabel(f"gain (dB, {rs[0]['unit']})", fontsize=7)
        p.set_ylabel("phase (deg)", fontsize=7)
        p.set_xlabel("frequency (rad/s)", fontsize=8)
        for a in (g, p):
            a.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            a.grid(alpha=0.3, which="both")
            a.tick_params(labelsize=7)
        if k == 0:
            g.legend(fontsize=6)
    for k in range(len(tests), nrow * ncol):
        ax[2 * (k // ncol), k % ncol].axis("off")
        ax[2 * (k // ncol) + 1, k % ncol].axis("off")
    fig.suptitle(
        f"{doc['scenario']} ({doc['mode']}): whole cueing chain, vehicle -> driver's head "
        "(OMCT frequencies)",
        fontsize=10,
    )
    fig.tight_layout()
    out = folder / "chain_bode.png"
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return [out.name]


def print_chain_summary(doc: dict, folder, file=None) -> None:
    file = file or sys.stdout
    print(
        f"{doc['scenario']} ({doc['mode']}), vehicle -> driver's head, measured | washout alone"
        " | linear chain (gain dB, phase deg):",
        file=file,
    )
    for r in doc["rows"]:
        pg, pp = r["predicted_gain_db"], r["predicted_phase_deg"]
        flag = "  (limits acted)" if r["rate_limited_pct"] > 0 or r["softened_pct"] > 0 else ""
        print(
            f"{r['test']:15s} {r['omega_rad_s']:6.2f} rad/s  "
            f"{r['gain_db']:7.2f} {r['phase_deg']:7.1f}"
            f" | {_fmt(r['washout_gain_db'], 2):>7s} {_fmt(r['washout_phase_deg']):>7s}"
            f" | {_fmt(pg, 2):>7s} {_fmt(pp):>7s}{flag}",
            file=file,
        )
    if doc.get("prediction_note"):
        print(doc["prediction_note"], file=file)
    for f in doc["failed"]:
        print(f"FAILED {f['channel']} {f['period_ms']} ms: {f['status']}: {f['reason']}", file=file)
    print(f"results: {folder}", file=file)
