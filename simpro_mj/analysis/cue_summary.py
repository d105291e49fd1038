"""The cueing summary a run prints: per channel shape, time and strength, then the floors.

Reads the ``cueing`` block of ``metrics.json`` (:func:`simpro_mj.analysis.cue_metrics.cue_metrics`)
and prints it as two tables (shape and time; strength against the bound), the workspace,
valves and solve times, and the floors met or missed
(:func:`simpro_mj.analysis.cue_metrics.cue_floors`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simpro_mj.analysis.cue_metrics import cue_floors


def _cell(v, fmt: str) -> str:
    """``v`` formatted by ``fmt``, or a dash as wide for None."""
    width = int(fmt.split(".")[0])
    return f"{'-':>{width}}" if v is None else format(v, fmt)


def _rows(cue: Mapping, head: str, file):
    """Print a table's ``head`` and its rule; then the channels of ``cue``, one per row."""
    print(head, file=file)
    print("-" * len(head), file=file)
    return (cue.get("channels") or {}).items()


def print_cue_summary(cue: Mapping, file=None) -> None:
    """The cueing summary of a run: per channel the perceived correlation, lag, onset
    delay, raw wrong-sign peak and false cues; workspace, valves and solve times."""
    import sys

    file = sys.stdout if file is None else file

    print(f"cueing ({cue.get('algorithm', '?')}, {cue.get('source', '')}), perceived:", file=file)
    head = (
        f"{'channel':<15}{'corr':>6}{'lag[s]':>8}{'onset[s]':>9}{'raw wrong':>11}"
        f"{'false[s]':>9}{'false rot[s]':>13}"
    )
    for name, ch in _rows(cue, head, file):
        print(
            f"{name:<15}{_cell(ch.get('correlation'), '6.2f')}{_cell(ch.get('mean_lag_s'), '8.2f')}"
            f"{_cell(ch.get('onset_delay_s'), '9.2f')}"
            f"{_cell(ch.get('onset_raw_wrong_sign_peak'), '11.2f')}"
            f"{_cell(ch.get('false_cue_s'), '9.2f')}{_cell(ch.get('false_rotation_s'), '13.2f')}",
            file=file,
        )
    print(file=file)
    print_strength(cue, file=file)
    ws = cue.get("workspace") or {}
    box = ws.get("box_fraction_max") or {}
    margin = ws.get("end_stop_margin_m")
    print(
        "workspace: box used "
        + ", ".join(f"{k} {v * 100:.0f} %" for k, v in box.items())
        + (f"; end-stop margin {margin * 1e3:.0f} mm" if margin is not None else ""),
        file=file,
    )
    sat = (cue.get("valves") or {}).get("saturated_fraction")
    if sat is not None:
        print(f"valves: saturated {sat * 100:.1f} % of the time", file=file)
    st = cue.get("solve_time")
    if st:
        print(
            f"MPC solve time: p50 {st['p50_ms']:.2f} ms, p99 {st['p99_ms']:.2f} ms, "
            f"max {st['max_ms']:.2f} ms over {st['solves']} solves",
            file=file,
        )
    floors = cue_floors(cue)
    print(
        f"floors ({', '.join(floors.channels)}): "
        + ("met" if floors.met else "missed: " + "; ".join(floors.missed)),
        file=file,
    )
    print(
        "(raw wrong: the head's specific force against the vehicle's onset, m/s^2, "
        "threshold 0.17; lag, onset: seconds)",
        file=file,
    )


def print_strength(cue: Mapping, file=None) -> None:
    """The strength table of a cueing summary: per channel the perceived gain (least
    squares, and the RMS ratio), the RMS perceived error (m/s^2, deg/s), and beside them
    the bound's gain and error and the law's share of it
    (:func:`~simpro_mj.analysis.cue_signals.bound_share`)."""

    bound = (cue.get("bound") or {}).get("channels") or {}
    head = (
        f"{'channel':<15}{'gain':>6}{'rms ratio':>10}{'rms err':>9}{'unit':>7}"
        f"{'bound gain':>12}{'rms err':>9}{'gain share':>12}{'err share':>10}"
    )
    for name, ch in _rows(cue, head, file):
        deg = ch.get("unit") == "rad/s"
        err = ch.get("rms_error_deg_s") if deg else ch.get("rms_error")
        b = bound.get(name) or {}
        berr = b.get("rms_error")
        if deg and berr is not None:
            berr = float(np.degrees(berr))
        print(
            f"{name:<15}{_cell(ch.get('gain'), '6.2f')}{_cell(ch.get('gain_rms'), '10.2f')}"
            f"{_cell(err, '9.3f')}{'deg/s' if deg else 'm/s^2':>7}"
            f"{_cell(b.get('gain'), '12.2f')}{_cell(berr, '9.3f')}"
            f"{_cell(ch.get('gain_share'), '12.2f')}{_cell(ch.get('error_share'), '10.2f')}",
            file=file,
        )
    note = (cue.get("bound") or {}).get("note")
    print(
        "(gain: least squares of the head's perceived signal on the car's at the mean lag; "
        "bound: the best platform motion with the whole drive known, same model, cost and "
        "limits, the car at full scale" + (f"; bound {note}" if note else "") + ")",
        file=file,
    )
