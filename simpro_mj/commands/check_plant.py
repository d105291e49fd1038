"""``simpro-sim check-plant``: the physical checks of a plant as a table.

The checks are :mod:`simpro_mj.analysis.plant_checks`; exit 0 when all hold, 1 otherwise."""

from __future__ import annotations

from simpro_mj.core.jsonout import emit_json

HELP = "check a plant's physics: stiction, breakaway, chamber energy, leakage, supply, loops"


def add_arguments(parser) -> None:
    parser.add_argument(
        "--preset", default="paper", help="the plant preset (paper, heavy_cabin); default paper"
    )


def run(args) -> int:
    # the checks load MuJoCo: after argparse has checked the options
    from simpro_mj.analysis.plant_checks import check_plant, table
    from simpro_mj.config.scenario import resolve_scenario

    scenario = resolve_scenario({"plant": {"preset": args.preset}}, args.sets)
    checks = check_plant(scenario)
    if args.json:
        emit_json({"preset": args.preset, "checks": [c.as_dict() for c in checks]})
    else:
        print(f"plant: {args.preset}")
        print(table(checks))
    return 0 if all(c.ok for c in checks) else 1
