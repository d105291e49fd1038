"""``simpro-sim manoeuvre TYPE``: a vehicle manoeuvre as a telemetry CSV.

Runs the CommonRoad multi-body vehicle (:mod:`simpro_mj.config.manoeuvres`, extra
``[vehicle]``) and writes the driver's head motion in the telemetry format
(:mod:`simpro_mj.config.telemetry`), ready for a scenario's ``setpoint.cueing.telemetry``.
Parameters by ``--set``: ``speed_kmh``, ``vehicle``, ``deceleration_mps2``,
``bump_height_m``, ``bump_length_m``, ``lead_s``, ``duration_s`` (0: automatic),
``rate_hz``, ``tyre_offsets`` (``none``; ``commonroad``: the published tyre relay).
"""

from __future__ import annotations

from dataclasses import fields, replace
from pathlib import Path
from typing import Any

from simpro_mj.config.manoeuvres import MANOEUVRES, ManoeuvreSpec, generate
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.keys import apply_overrides
from simpro_mj.report.single_files import check_file, write_telemetry_file

HELP = (
    "generate a vehicle manoeuvre (braking, lane_change, slalom, bump, braking_turn) as "
    "telemetry CSV"
)

DEFAULT_SPEED_KMH = {
    "braking": 100.0,
    "lane_change": 80.0,
    "slalom": 60.0,
    "bump": 40.0,
    "braking_turn": 60.0,
}
#: The ``--set`` keys: the spec's fields and defaults; a speed or duration of 0 is the
#: manoeuvre's own (DEFAULT_SPEED_KMH, automatic)
DEFAULTS = {f.name: f.default for f in fields(ManoeuvreSpec)[1:]} | {
    "speed_kmh": 0.0,
    "duration_s": 0.0,
}


def add_arguments(parser) -> None:
    parser.add_argument("manoeuvre", choices=MANOEUVRES, help="what to drive")
    parser.add_argument(
        "--out", default=None, help="CSV to write (default <manoeuvre>_<speed>kmh.csv here)"
    )
    parser.add_argument(
        "--overwrite",
        "--force",
        dest="force",
        action="store_true",
        help="replace --out even if simpro-sim did not write it (default: refuse)",
    )


def spec_from(args) -> ManoeuvreSpec:
    # the --set values as the spec's fields: the words as text, the numbers as floats
    given: dict[str, Any] = {
        k: str(v) if isinstance(DEFAULTS[k], str) else float(v)
        for k, v in apply_overrides(DEFAULTS, args.sets).items()
    }
    spec = ManoeuvreSpec(args.manoeuvre, **given)
    speed = spec.speed_kmh or DEFAULT_SPEED_KMH[args.manoeuvre]
    spec = replace(spec, speed_kmh=float(speed), duration_s=spec.duration_s or None)
    spec.check()
    return spec


def run(args) -> int:
    spec = spec_from(args)
    out = Path(args.out or f"{spec.manoeuvre}_{spec.speed_kmh:g}kmh.csv")
    if not out.parent.is_dir():
        raise UserInputError(f"invalid value at --out: folder {out.parent} does not exist")
    out = check_file(out, args.force)
    tel = generate(spec)
    comment = (
        f"simpro-sim manoeuvre {spec.manoeuvre}: {tel.source}\n"
        "frame: ISO 8855 vehicle frame at the driver's head (x forward, y left, z up);\n"
        "specific force includes gravity (fz = +9.81 at rest); "
        "format: simpro_mj/config/telemetry.py"
    )
    write_telemetry_file(out, tel, comment)
    summary = {
        "file": str(out),
        "manoeuvre": spec.manoeuvre,
        "speed_kmh": spec.speed_kmh,
        "vehicle": spec.vehicle,
        "duration_s": float(tel.t[-1]),
        "samples": int(tel.t.size),
        "peak_abs_f_mps2": [
            float(abs(tel.f[:, k] - (9.81 if k == 2 else 0)).max()) for k in range(3)
        ],
    }
    if args.json:
        emit_json(summary)
    else:
        print(f"wrote {out}: {tel.source}, {tel.t[-1]:.2f} s, {tel.t.size} samples")
    return 0
