"""``simpro-sim response SCENARIO``: closed-loop frequency response per task axis (OMCT-style).

Stepped sines on each axis in turn (:mod:`simpro_mj.analysis.response`), fitted by
least squares over settled whole periods, beside the prediction of the
linearised loop (:mod:`controllers.frequency`, python-control). Writes
``response.csv`` (one row per input axis, output axis, signal and
frequency), ``response.json`` (what ``--json`` prints), ``bode.png`` (each
axis: measured true and measured pose, predicted, their difference) and
``cross_axis.png`` into ``--out`` (default ``results/<name>-response``).

``--chain``: the whole motion-cueing chain instead (issue 16,
:mod:`simpro_mj.analysis.chain_response`): a sine on one vehicle channel (specific
force ``fx, fy, fz``, roll and pitch rates ``wx, wy``; ISO 8855) through the
scenario's washout (its ``setpoint.cueing`` parameters, or the defaults when
it has none), the loops, the pneumatics and the multibody, to the specific
force and angular velocity at the driver's head, at the twelve OMCT
frequencies; beside it the washout alone and the linearised chain. Writes
``chain.csv``, ``chain.json`` and ``chain_bode.png`` into ``--out`` (default
``results/<name>-chain``). It is an option rather than automatic for a
cueing scenario: the set-point -> pose response of a cueing scenario's loop
stays one flag away from its cue response.
"""

from __future__ import annotations

import csv
import io
import math
import os
import sys
from pathlib import Path

HELP = (
    "closed-loop frequency response per task axis, or (--chain) of the whole cueing chain "
    "vehicle -> head (stepped sines, OMCT frequencies)"
)

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


def _floats(text: str) -> list[float]:
    import argparse

    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"not a comma-separated list of numbers: {text!r}"
        ) from None


def add_arguments(parser) -> None:
    parser.add_argument("scenario", help="shipped scenario name or a path")
    parser.add_argument(
        "--freq-hz",
        type=_floats,
        default=None,
        metavar="F,F,...",
        help="frequencies (Hz), periods on the 1 ms grid (default: the 12 OMCT frequencies "
        "0.1-15.85 rad/s, on the grid, plus 0.5 and 1 Hz)",
    )
    parser.add_argument(
        "--amplitude-deg",
        type=float,
        default=None,
        help="roll and pitch sine amplitude (deg, default 0.5; pose response)",
    )
    parser.add_argument(
        "--amplitude-mm", type=float, default=None, help="heave amplitude (mm, default 5)"
    )
    parser.add_argument(
        "--chain",
        action="store_true",
        help="whole cueing chain: vehicle specific force / angular velocity -> driver's head "
        "(OMCT pairs), beside the washout alone",
    )
    parser.add_argument(
        "--channels",
        default="fx,fy,fz,wx,wy",
        help="--chain: vehicle channels to excite (default fx,fy,fz,wx,wy)",
    )
    parser.add_argument(
        "--amplitude-mps2",
        type=float,
        default=None,
        help="--chain: specific-force sine amplitude (m/s^2, default 0.3)",
    )
    parser.add_argument(
        "--amplitude-deg-s",
        type=float,
        default=None,
        help="--chain: roll/pitch-rate sine amplitude (deg/s, default 1)",
    )
    parser.add_argument(
        "--axes", default="roll,pitch,heave", help="axes to excite (default roll,pitch,heave)"
    )
    parser.add_argument(
        "--settle-s",
        type=float,
        default=None,
        help="time before the fitted periods (s; default 4, with --chain 10)",
    )
    parser.add_argument("--periods", type=int, default=2, help="whole periods fitted (default 2)")
    parser.add_argument("--jobs", type=int, default=None, metavar="N", help="worker processes")
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a Dask distributed scheduler at ADDRESS, or 'local'",
    )
    parser.add_argument("--out", default=None, help="folder (default results/<name>-response)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


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


def run(args) -> int:
    from simpro_mj.analysis.response import (
        check_periods,
        loop_model,
        measure,
        plan_response,
        summary,
    )
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.core.errors import UserInputError
    from simpro_mj.report.results import claim
    from simpro_mj.sim.executors import MAX_JOBS

    jobs = args.jobs if args.jobs is not None else (os.cpu_count() or 1)
    if not 1 <= jobs <= MAX_JOBS:
        raise UserInputError(f"invalid value at --jobs: {jobs}; allowed: an integer 1..{MAX_JOBS}")
    if args.chain:
        return run_chain(args, jobs)
    for opt in ("amplitude_mps2", "amplitude_deg_s"):
        if getattr(args, opt) is not None:
            flag = "--" + opt.replace("_", "-")
            raise UserInputError(
                f"invalid value at {flag}: only with --chain; allowed: --amplitude-deg, "
                "--amplitude-mm for the pose response"
            )
    if args.channels != "fx,fy,fz,wx,wy":
        raise UserInputError("invalid value at --channels: only with --chain; allowed: --axes")
    args.amplitude_deg = 0.5 if args.amplitude_deg is None else args.amplitude_deg
    args.amplitude_mm = 5.0 if args.amplitude_mm is None else args.amplitude_mm
    args.settle_s = 4.0 if args.settle_s is None else args.settle_s
    scenario = load_scenario(args.scenario, args.sets)
    periods_ms = None if args.freq_hz is None else check_periods(args.freq_hz)
    if args.freq_hz is not None and not args.freq_hz:
        raise UserInputError("invalid value at --freq-hz: empty; allowed: one or more frequencies")
    axes = tuple(a.strip() for a in args.axes.split(",") if a.strip())
    plan = plan_response(
        scenario,
        periods_ms=periods_ms,
        amplitudes={
            "roll": args.amplitude_deg,
            "pitch": args.amplitude_deg,
            "heave": args.amplitude_mm,
        },  # fmt: skip
        axes=axes,
        settle_s=args.settle_s,
        periods=args.periods,
    )
    if args.scheduler is not None:
        from simpro_mj.sim.executors import dask_module

        dask_module()  # say so before anything runs
    out = Path(args.out) if args.out else Path("results") / f"{scenario['name']}-response"
    with claim(out, "response", inputs=[args.scenario]):
        model = loop_model(scenario)
        results = measure(
            plan,
            jobs=min(jobs, len(plan.tasks)),
            scheduler=args.scheduler,
            progress=not args.quiet and not args.json,
        )
        doc = summary(plan, results, model)
        doc = {
            "scenario": scenario["name"],
            "mode": model.mode,
            "axes_excited": list(plan.axes),
            "amplitude": {
                "roll_deg": args.amplitude_deg,
                "pitch_deg": args.amplitude_deg,
                "heave_mm": args.amplitude_mm,
            },  # fmt: skip
            "settle_s": plan.settle_s,
            "periods": plan.periods,
            "frequencies_hz": [1000.0 / p for p in sorted(plan.periods_ms, reverse=True)],
            **doc,
        }
        write_result(out, doc, "response", csv_text(doc["rows"]), None if args.no_plots else plot)
    return report(args, doc, out, print_summary)


def write_result(out: Path, doc: dict, stem: str, csv_body: str, plotter) -> None:
    """``<stem>.csv``, ``<stem>.json`` and the plots (``plotter(doc, folder)``, or None)
    installed into ``out`` as a whole (:func:`simpro_mj.report.results.install_folder`)."""
    from simpro_mj.report.results import _jsonable, install_folder

    def fill(tmp: Path) -> None:
        import json

        (tmp / f"{stem}.csv").write_text(csv_body, encoding="utf-8")
        files = [f"{stem}.csv", f"{stem}.json"]
        if plotter is not None:
            files += plotter(doc, tmp)
        doc["files"] = files
        text = json.dumps(_jsonable(doc), indent=2)
        (tmp / f"{stem}.json").write_text(text + "\n", encoding="utf-8")

    install_folder(out, fill, kind="response")


def report(args, doc: dict, out: Path, printer) -> int:
    """``--json`` or the printed summary; exit 1 if a frequency did not run."""
    if args.json:
        from simpro_mj.core.jsonout import emit_json
        from simpro_mj.report.results import _jsonable

        emit_json(_jsonable(doc))
    else:
        printer(doc, out)
    return 0 if not doc["failed"] else 1


# ------------------------------------------------------------ --chain (issue 16)

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
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

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
        g.semilogx(f, [r["washout_gain_db"] for r in rs], "k--", lw=1, label="washout alone")
        p.semilogx(f, [r["phase_deg"] for r in rs], "o")
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
            f" | {r['washout_gain_db']:7.2f} {r['washout_phase_deg']:7.1f}"
            f" | {_fmt(pg, 2):>7s} {_fmt(pp):>7s}{flag}",
            file=file,
        )
    if doc.get("prediction_note"):
        print(doc["prediction_note"], file=file)
    for f in doc["failed"]:
        print(f"FAILED {f['channel']} {f['period_ms']} ms: {f['status']}: {f['reason']}", file=file)
    print(f"results: {folder}", file=file)


def run_chain(args, jobs: int) -> int:
    from simpro_mj.analysis.chain_response import (
        DEFAULT_SETTLE_S,
        chain_summary,
        measure_chain,
        plan_chain,
    )
    from simpro_mj.analysis.response import check_periods
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.core.errors import UserInputError
    from simpro_mj.report.results import claim

    for opt, other in (
        ("amplitude_deg", "--amplitude-deg-s"),
        ("amplitude_mm", "--amplitude-mps2"),
    ):
        if getattr(args, opt) is not None:
            flag = "--" + opt.replace("_", "-")
            raise UserInputError(
                f"invalid value at {flag}: not with --chain; allowed: {other} for the chain"
            )
    if args.axes != "roll,pitch,heave":
        raise UserInputError("invalid value at --axes: not with --chain; allowed: --channels")
    scenario = load_scenario(args.scenario, args.sets)
    if args.freq_hz is not None and not args.freq_hz:
        raise UserInputError("invalid value at --freq-hz: empty; allowed: one or more frequencies")
    periods_ms = None if args.freq_hz is None else check_periods(args.freq_hz)
    channels = tuple(c.strip() for c in args.channels.split(",") if c.strip())
    plan = plan_chain(
        scenario,
        periods_ms=periods_ms,
        amplitude_mps2=args.amplitude_mps2,
        amplitude_deg_s=args.amplitude_deg_s,
        channels=channels,
        settle_s=DEFAULT_SETTLE_S if args.settle_s is None else args.settle_s,
        periods=args.periods,
    )
    if args.scheduler is not None:
        from simpro_mj.sim.executors import dask_module

        dask_module()  # say so before anything runs
    out = Path(args.out) if args.out else Path("results") / f"{scenario['name']}-chain"
    with claim(out, "response", inputs=[args.scenario]):
        results = measure_chain(
            plan,
            jobs=min(jobs, len(plan.tasks)),
            scheduler=args.scheduler,
            progress=not args.quiet and not args.json,
        )
        summ = chain_summary(plan, results)
        cue = plan.tasks[0]["scenario"]["setpoint"]["cueing"]
        doc = {
            "scenario": scenario["name"],
            "kind": "chain",
            "mode": scenario["controller"]["mode"],
            "channels_excited": list(plan.channels),
            "amplitude": {
                "f_mps2": plan.amplitudes["fx"],
                "w_deg_s": math.degrees(plan.amplitudes["wx"]),
            },
            "settle_s": plan.settle_s,
            "periods": plan.periods,
            "frequencies_rad_s": [2000.0 * math.pi / p for p in plan.periods_ms],
            "washout": {"algorithm": cue["algorithm"], "parameters": cue["parameters"]},
            **summ,
        }

        plotter = None if args.no_plots else plot_chain
        write_result(out, doc, "chain", csv_text(doc["rows"], CHAIN_CSV_COLUMNS), plotter)
    return report(args, doc, out, print_chain_summary)
