"""``simpro-sim telemetry import SOURCE``: a recorded drive as a telemetry CSV;
``simpro-sim telemetry judge [FILE ...]``: the shipped cueing law on the shipped drives
and on these recordings, the done-when table.

``import`` reads a phone's or a data logger's accelerometer and gyroscope (a CSV, two
CSVs, or a comma2k19 segment folder), estimates the car's axes (``--frame``) and writes
the cueing chain's input (:mod:`simpro_mj.config.telemetry_import`, the method and its
quality figures; the file's comment lines repeat them). ``judge`` plays each drive
through the shipped law, the loop's model and the bound
(:mod:`simpro_mj.analysis.cue_corpus`) and prints, per judged channel, the perceived
correlation, mean lag, gain, the bound's gain and the share, the worst onset and the
raw wrong-way peak, with the floors each misses.
"""

from __future__ import annotations

from pathlib import Path

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.jsonout import emit_json
from simpro_mj.report.single_files import check_file, write_telemetry_file

HELP = (
    "import a recorded drive (accelerometer + gyroscope) as telemetry CSV; judge the "
    "shipped cueing law on drives"
)
COMMON_OPTIONS = ("json", "quiet")


def add_arguments(parser) -> None:
    parser.add_argument("action", choices=("import", "judge"), help="what to do")
    parser.add_argument(
        "source",
        nargs="*",
        help="import: the recording (a CSV, or a comma2k19 segment folder); judge: "
        "telemetry CSVs to judge beside the shipped drives",
    )
    parser.add_argument("--format", default="csv", choices=("csv", "comma2k19"))
    parser.add_argument(
        "--frame",
        default=None,
        choices=("vehicle", "device", "level", "earth"),
        help="the axes the sensors read in (simpro_mj/config/telemetry_import.py)",
    )
    parser.add_argument("--out", default=None, help="import: the telemetry CSV to write")
    parser.add_argument(
        "--law",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="judge: a change to the shipped law's parameters (YAML name; repeatable)",
    )
    parser.add_argument(
        "--no-shipped", action="store_true", help="judge: the files only, not the shipped drives"
    )
    parser.add_argument("--gyro-file", default=None, help="the gyroscope's own CSV")
    parser.add_argument("--time", default="time_s", help="time column (default time_s)")
    parser.add_argument("--gyro-time", default=None, help="the gyroscope's time column")
    parser.add_argument("--accel", default="ax,ay,az", help="accelerometer columns x,y,z")
    parser.add_argument("--gyro-columns", default="wx,wy,wz", help="gyroscope columns x,y,z")
    parser.add_argument("--time-scale", type=float, default=1.0, help="to seconds")
    parser.add_argument("--accel-scale", type=float, default=1.0, help="to m/s^2")
    parser.add_argument("--gyro-scale", type=float, default=1.0, help="to rad/s")
    parser.add_argument("--axes", default="x,y,z", help="--frame vehicle: the car's axis of each")
    parser.add_argument("--start-s", type=float, default=0.0, help="trim: from (s)")
    parser.add_argument("--end-s", type=float, default=0.0, help="trim: to (s; 0 the end)")
    parser.add_argument("--rate-hz", type=float, default=100.0, help="output rate")
    parser.add_argument("--window-s", type=float, default=20.0, help="heading window (s)")
    parser.add_argument("--bias-tau-s", type=float, default=None, help="bias removal (s; 0 off)")
    parser.add_argument("--vibration-hz", type=float, default=None, help="low-pass (Hz; 0 off)")
    parser.add_argument("--overwrite", "--force", dest="force", action="store_true",
                        help="replace --out even if simpro-sim did not write it")  # fmt: skip


def _finite(x: float) -> float | None:
    """``x``, or None where nothing was estimated (NaN: the vehicle frame)."""
    return None if x != x else float(x)


def _judge(args) -> int:
    import yaml

    from simpro_mj.analysis.cue_corpus import SHIPPED, judge, table

    changes = {}
    for item in args.law:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UserInputError(f"invalid value at --law: {item!r}; allowed: KEY=VALUE")
        changes[key.strip()] = yaml.safe_load(value)
    for p in args.source:
        if not Path(p).is_file():
            raise UserInputError(f"invalid value at FILE: {p!r} is not a file")
    try:
        rows = judge(args.source, shipped=() if args.no_shipped else SHIPPED, changes=changes)
    except (ValueError, TypeError) as exc:  # a parameter the law refuses names itself
        raise UserInputError(f"invalid value at --law: {exc}") from None
    if args.json:
        emit_json({"changes": changes, "rows": rows})
    else:
        print(table(rows))
    return 0


def run(args) -> int:
    if args.action == "judge":
        return _judge(args)
    if len(args.source) != 1 or args.frame is None or args.out is None:
        raise UserInputError(
            "telemetry import: one SOURCE, --frame (vehicle, device, level, earth) and --out "
            "are required"
        )
    args.source = args.source[0]
    from controllers.conditioning import BIAS_TAU_S, VIBRATION_HZ
    from simpro_mj.config.telemetry_import import (
        import_recording,
        read_comma2k19,
        read_csv_sensors,
    )

    out = Path(args.out)
    if not out.parent.is_dir():
        raise UserInputError(f"invalid value at --out: folder {out.parent} does not exist")
    out = check_file(out, args.force)
    if args.format == "comma2k19":
        rec = read_comma2k19(args.source)
    else:
        rec = read_csv_sensors(
            args.source,
            time=args.time,
            accel=args.accel,
            gyro=args.gyro_columns,
            gyro_path=args.gyro_file,
            gyro_time=args.gyro_time,
            time_scale=args.time_scale,
            accel_scale=args.accel_scale,
            gyro_scale=args.gyro_scale,
        )
    tel, report = import_recording(
        rec,
        args.frame,
        rate_hz=args.rate_hz,
        start_s=args.start_s,
        end_s=args.end_s,
        window_s=args.window_s,
        axes=args.axes,
        bias_tau_s=BIAS_TAU_S if args.bias_tau_s is None else args.bias_tau_s,
        vibration_hz=VIBRATION_HZ if args.vibration_hz is None else args.vibration_hz,
    )
    comment = "\n".join(
        [
            f"simpro-sim telemetry import: {rec.source}",
            *report.lines(),
            "frame: ISO 8855 vehicle frame (x forward, y left, z up); specific force "
            "includes gravity; format: simpro_mj/config/telemetry.py",
        ]
    )
    write_telemetry_file(out, tel, comment)
    if args.json:
        emit_json(
            {
                "file": str(out),
                "source": rec.source,
                "duration_s": float(tel.t[-1]),
                "samples": int(tel.t.size),
                "frame": report.frame,
                "tilt_deg": report.tilt_deg,
                "heading_deg": list(report.heading_deg),
                "lateral_yaw_corr": _finite(report.lateral_yaw_corr),
                "straight_lateral_share": _finite(report.straight_lateral_share),
                "trimmed_s": list(report.trimmed),
            }
        )
    else:
        print(f"wrote {out}: {rec.source}, {tel.t[-1]:.2f} s, {tel.t.size} samples")
        for line in report.lines():
            print(f"  {line}")
    return 0
