"""``simpro-sim list``: the shipped scenarios, plant presets and telemetry files, one line each.

The catalogue is :func:`simpro_mj.config.scenario.catalogue`."""

from __future__ import annotations

HELP = "list the shipped scenarios, plant presets and telemetry files, one line each"
#: no parameter to override, nothing to wait for
COMMON_OPTIONS = ("json",)

#: section -> (heading, how it is used)
_SECTIONS = {
    "scenarios": ("scenarios", "simpro-sim run NAME"),
    "presets": ("plant presets", "--set plant.preset=NAME"),
    "telemetry": ("telemetry files", "setpoint.cueing.telemetry: NAME"),
}


def add_arguments(parser) -> None:
    parser.add_argument(
        "what", nargs="?", choices=tuple(_SECTIONS), default=None, help="one section only"
    )


def run(args) -> int:
    # on use: the catalogue reads the scenario package (pydantic), not needed for --help
    from simpro_mj.config.scenario import catalogue
    from simpro_mj.core.jsonout import emit_json

    items = catalogue()
    if args.what is not None:
        items = {args.what: items[args.what]}
    if args.json:
        emit_json({k: [{"name": n, "description": d} for n, d in v] for k, v in items.items()})
        return 0
    for n, (key, entries) in enumerate(items.items()):
        heading, usage = _SECTIONS[key]
        print(("\n" if n else "") + f"{heading} ({usage}):")
        width = max((len(name) for name, _ in entries), default=0)
        for name, description in entries:
            print(f"  {name:<{width}}  {description}".rstrip())
    return 0
