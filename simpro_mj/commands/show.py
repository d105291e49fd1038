"""``simpro-sim show SCENARIO``: every parameter with its value, default, unit, allowed
range and meaning (:func:`simpro_mj.config.scenario.parameters`)."""

from __future__ import annotations

HELP = "list every parameter of a scenario: value, default, unit, allowed range, meaning"


def add_arguments(parser) -> None:
    parser.add_argument("scenario", help="a shipped scenario name or a path to a YAML file")
    parser.add_argument(
        "--changed", action="store_true", help="only the parameters whose value is not the default"
    )


def run(args) -> int:
    from simpro_mj.config.scenario import load_scenario, parameters, text
    from simpro_mj.core.jsonout import emit_json

    scenario = load_scenario(args.scenario, args.sets)
    rows = parameters(scenario)
    if args.changed:
        rows = [r for r in rows if r.value != r.default]
    if args.json:
        emit_json({"scenario": scenario.name, "parameters": rows})
        return 0
    table = [(r.key, text(r.value), text(r.default), r.unit, r.allowed, r.meaning) for r in rows]
    head = ("key", "value", "default", "unit", "allowed", "meaning")
    width = [min(max(len(row[i]) for row in [head, *table]), cap)
             for i, cap in enumerate((56, 28, 28, 14, 40))]  # fmt: skip
    for row in [head, *table]:
        cells = [f"{c:<{w}}" for c, w in zip(row[:5], width, strict=True)]
        print("  ".join([*cells, row[5]]).rstrip())
    return 0
