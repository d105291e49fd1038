"""``simpro-sim live SCENARIO --listen HOST:PORT``: the co-simulation paced to the wall clock.

A game's telemetry (UDP datagrams of ``--format``,
:mod:`simpro_mj.config.datagrams`) drives the scenario's cueing law, plant
and controllers at the pace of the wall clock; the platform's pose goes out
to ``--send`` as one ASCII line per ``1/--send-rate`` s. The session ends
after ``--duration`` s (default: the scenario's ``duration_s``) or on Ctrl-C /
SIGTERM, and writes a normal result folder (``render`` replays it) with a
``realtime`` block in ``metrics.json``. With ``SIMPRO_READY_FILE`` set, the
file is written once the session listens and its clock runs; it reads
``listening@HOST:PORT <pid>`` (port 0 in ``--listen`` picks a free one).
The formats and the pose line: docs/live.md. The session itself is
:mod:`simpro_mj.sim.live`, its folder :mod:`simpro_mj.report.live`.

Exit codes: 0 the session ran (to its end or to a signal), 1 diverged, 2 a
user's mistake (a busy port included).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from simpro_mj.config.datagrams import FORMATS
from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.jsonout import emit_json
from simpro_mj.report.folders import claim
from simpro_mj.report.live import execute_live, live_scenario
from simpro_mj.report.results import print_summary
from simpro_mj.sim.live import LiveOptions
from simpro_mj.sim.udp import check_listen, parse_address, pose_template

HELP = "run a cueing scenario live: UDP telemetry in, paced to the wall clock, the pose out"

#: Longest session (s): a day.
MAX_DURATION_S = 86400.0


def add_arguments(parser) -> None:
    parser.add_argument("scenario", help="a cueing scenario (e.g. cue_braking.yaml) or a path")
    parser.add_argument(
        "--listen",
        required=True,
        metavar="HOST:PORT",
        help="UDP address the telemetry comes to (port 0: any free port)",
    )
    parser.add_argument(
        "--format",
        dest="fmt",
        choices=FORMATS,
        default="outsim",
        help="telemetry datagrams: outsim (LFS OutSim, 64/68 bytes), csv (one line of the "
        "telemetry columns), forza_sled/forza_dash/forza_horizon (Forza Data Out, 232/311/324 "
        "bytes), codemasters (extradata=3, 264 bytes), beamng (MotionSim BNG1, 88 bytes), or "
        "auto (told by the first good datagram's size, and said); default outsim",
    )
    parser.add_argument(
        "--send",
        default=None,
        metavar="HOST:PORT",
        help="send the platform's pose there (UDP, one ASCII line a datagram)",
    )
    parser.add_argument(
        "--send-rate",
        type=float,
        default=100.0,
        metavar="HZ",
        help="pose datagrams per second, a divisor of 1000 (default 100)",
    )
    parser.add_argument(
        "--send-format",
        default=None,
        metavar="TEMPLATE",
        help="the pose line as a Python format string (docs/live.md); default "
        "'{t_s:.3f},{roll_deg:.4f},{pitch_deg:.4f},{heave_mm:.3f},{q1_mm:.3f},"
        "{q2_mm:.3f},{q3_mm:.3f}\\n'",
    )
    parser.add_argument(
        "--output",
        default=None,
        metavar="DEST",
        help="write a rig's output string there each period: udp:HOST:PORT or "
        "serial:DEVICE[@BAUD] (pyserial); docs/live.md",
    )
    parser.add_argument(
        "--output-string",
        default="S<q1><q2><q3>\\n",
        metavar="TEMPLATE",
        help="the string: literal text, the tokens <q1> <q2> <q3> (leg set-points) <roll> "
        "<pitch> <heave> (set-point pose), escapes \\n \\r \\t \\xHH; default "
        "'S<q1><q2><q3>\\n'",
    )
    parser.add_argument(
        "--output-bits", type=int, choices=(8, 16), default=16, help="counts of 8 or 16 bits"
    )
    parser.add_argument(
        "--output-text",
        action="store_true",
        help="counts as decimal text (default: binary, most significant byte first)",
    )
    parser.add_argument(
        "--output-rate",
        type=float,
        default=100.0,
        metavar="HZ",
        help="output strings per second, a divisor of 1000 (default 100)",
    )
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="session length (s); default the scenario's duration_s",
    )
    parser.add_argument(
        "--stale-after",
        type=float,
        default=0.3,
        metavar="S",
        help="input older than this is stale: held until then, then faded to "
        "rest over 1.5 s while the set-point goes home over 1.5 s (default 0.3)",
    )
    parser.add_argument(
        "--bias-tau",
        type=float,
        default=0.0,
        metavar="S",
        help="remove each channel's slow bias with this time constant (a real "
        "accelerometer's; e.g. 10); default 0: off",
    )
    parser.add_argument(
        "--vibration-hz",
        type=float,
        default=0.0,
        metavar="HZ",
        help="low-pass the input at this corner, 2nd-order Butterworth (e.g. 10); default 0: off",
    )
    parser.add_argument(
        "--rt", action="store_true", help="ask for real-time scheduling (SCHED_FIFO, locked memory)"
    )
    parser.add_argument(
        "--no-pin",
        action="store_true",
        help="leave the pacing thread and the cueing law's process where the kernel puts "
        "them (default with 2+ cores: the pacer on the last core, the law on the others)",
    )
    parser.add_argument(
        "--spin-us",
        type=float,
        default=0.0,
        metavar="US",
        help="sleep until this long before each deadline, then spin to it (0 to 5000 us; "
        "default 0: sleep to it)",
    )
    parser.add_argument("--out", default=None, help="result folder (default results/<name>-live)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    parser.add_argument("--quiet", action="store_true", help="no console line every second")


def _within(value: float, option: str, ok, allowed: str) -> float:
    """``value`` if finite and ``ok``; else the one-line error naming ``option``."""
    if not (math.isfinite(value) and ok(value)):
        raise UserInputError(f"invalid value at {option}: {value:g}; allowed: {allowed}")
    return float(value)


def _rate(rate: float, option: str) -> float:
    def divides(r: float) -> bool:  # 1000 Hz: the 1 ms step
        return 0 < r <= 1000 and abs(1000 / r - round(1000 / r)) < 1e-9

    allowed = "a divisor of 1000 Hz (1000, 500, 250, 200, 125, 100, 50, ...)"
    return _within(rate, option, divides, allowed)


def _options(args) -> LiveOptions:
    """The options checked, before anything heavy is loaded."""
    rate = _rate(args.send_rate, "--send-rate")
    template = None
    if args.output is not None:
        from simpro_mj.sim.rig_output import RigTemplate, open_destination

        _rate(args.output_rate, "--output-rate")
        template = RigTemplate(args.output_string, args.output_bits, args.output_text)
        open_destination(args.output, check_only=True)
    if args.duration is not None:
        _within(args.duration, "--duration", lambda v: 0 < v <= MAX_DURATION_S,
                f"> 0 and <= {MAX_DURATION_S:g} s")  # fmt: skip
    _within(args.stale_after, "--stale-after", lambda v: 0 < v <= 60, "> 0 and <= 60 s")
    _within(args.bias_tau, "--bias-tau", lambda v: 0 <= v <= 3600, "0 (off) to 3600 s")
    nyquist = "0 (off) or below 50 Hz (the Nyquist frequency of the 10 ms cueing period)"
    _within(args.vibration_hz, "--vibration-hz", lambda v: 0 <= v < 50, nyquist)
    _within(args.spin_us, "--spin-us", lambda v: 0 <= v <= 5000, "0 (sleep) to 5000 us")
    listen = parse_address(args.listen, "--listen", bind=True)
    check_listen(listen)  # a busy port refused now, not after the scenario's seconds
    return LiveOptions(
        listen=listen,
        fmt=args.fmt,
        send=None if args.send is None else parse_address(args.send, "--send"),
        send_rate_hz=rate,
        send_format=pose_template(args.send_format),
        stale_after_s=float(args.stale_after),
        rt=bool(args.rt),
        pin=not args.no_pin,
        spin_s=float(args.spin_us) * 1e-6,
        output=args.output,
        output_template=template,
        output_rate_hz=float(args.output_rate),
        bias_tau_s=float(args.bias_tau),
        vibration_hz=float(args.vibration_hz),
    )


def _say(line: str) -> None:
    sys.stderr.write(line + "\n")
    sys.stderr.flush()


def run(args) -> int:
    options = _options(args)
    scenario = live_scenario(load_scenario(args.scenario, args.sets), args.duration)
    out = Path(args.out) if args.out else Path("results") / f"{scenario.name}-live"
    with claim(out, "run", inputs=[args.scenario]):
        say = None if args.quiet else _say
        res, metrics = execute_live(scenario, options, out, plots=not args.no_plots, say=say)
    if args.json:
        emit_json(metrics)
    else:
        print_summary(metrics, res.folder)
        rt = metrics["realtime"]
        lat, pk = rt["lateness_us"], rt["packets"]
        print(
            f"realtime: lateness p50 {_us(lat['p50'])} p99 {_us(lat['p99'])} max "
            f"{_us(lat['max'])} us, missed {rt['missed_deadlines']} of {rt['deadlines']}, drift "
            f"{_ms(rt['drift_ms'])} ms; packets {pk['received']} (bad {pk['bad']}, late "
            f"{pk['late']}); stale {rt['stale_s']:.2f} s; pose sent "
            f"{(rt.get('pose_sent') or {}).get('datagrams', 0)}"
            + (f"; rig strings {rt['rig_out']['strings']}" if "rig_out" in rt else "")
        )
        if res.status == "diverged":
            print(f"DIVERGED: {res.reason}")
    return 0 if res.status == "ok" else 1


def _us(v) -> str:
    return "-" if v is None else f"{v:.0f}"


def _ms(v) -> str:
    return "-" if v is None else f"{v:+.1f}"
