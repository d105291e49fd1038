"""``simpro-sim bench [SCENARIO]``: the cost of one co-simulation step.

The measurements are ``benchmarks/step_cost.py`` of a checkout (``--video``: its
``measure_video``), outside the package: no run needs them. The command finds that
folder beside the package (an editable install) or in the current folder (a clone);
an installed wheel alone refuses with one line. ``docs/performance.md`` holds the
figures.
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import ModuleType

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.keys import value_text

#: Upper bounds of the counts (a benchmark of the median of 100 is already minutes).
MAX_REPEATS = 100
MAX_BATCH_RUNS = 64

#: the harness, relative to a checkout's top folder
HARNESS = Path("benchmarks") / "step_cost.py"
#: its name in ``sys.modules`` (the folder is not an installed package)
HARNESS_MODULE = "simpro_benchmarks_step_cost"

HELP = "time the co-simulation step against bare mj_step, per stage, and batch throughput"


def add_arguments(parser) -> None:
    parser.add_argument(
        "scenario",
        nargs="?",
        default="step_pitch.yaml",
        help="shipped scenario name or a path (default step_pitch.yaml)",
    )
    parser.add_argument(
        "--repeats", default=5, help="measurements per figure; the median is reported (default 5)"
    )
    parser.add_argument(
        "--duration", default=None, help="simulated seconds per run (default: the scenario's)"
    )
    parser.add_argument(
        "--batch-runs",
        default=4,
        help="scenario copies per throughput measurement (default 4)",
    )
    parser.add_argument(
        "--no-batch", action="store_true", help="skip the 1- and 2-worker throughput part"
    )
    parser.add_argument(
        "--commands",
        default=0,
        help="also time N pairs of whole 'run --no-plots' commands at 41 s and 1 s, "
        "each a fresh process (default 0: not)",
    )
    parser.add_argument(
        "--video",
        action="store_true",
        help="instead: time simpro-sim render on a 20 s run at 25 fps, 640x480 with the plot "
        "strip (--duration changes the run's length; needs simpro-sim[video])",
    )


def harness() -> ModuleType:
    """The benchmark harness of the checkout, loaded once.

    Raises
    ------
    UserInputError
        When neither the package's checkout nor the current folder holds it.
    """
    if HARNESS_MODULE in sys.modules:
        return sys.modules[HARNESS_MODULE]
    places = (Path(__file__).resolve().parents[2], Path.cwd())  # the package's, the user's
    found = [p / HARNESS for p in places if (p / HARNESS).is_file()]
    if not found:
        raise UserInputError(
            f"bench needs {HARNESS.as_posix()} of a simpro-sim checkout, found neither beside "
            "the package nor in the current folder; allowed: run it from a clone of the "
            "repository (or install it with pip install -e)"
        )
    spec = importlib.util.spec_from_file_location(HARNESS_MODULE, found[0])
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[HARNESS_MODULE] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[HARNESS_MODULE]
        raise
    return module


def _positive_int(value, field: str, hi: int, lo: int = 1) -> int:
    text = str(value).strip()
    n = int(text) if text.isdigit() and len(text) <= 9 else -1
    if not lo <= n <= hi:
        raise UserInputError(
            f"invalid value at {field}: {value_text(value)}; allowed: an integer {lo}..{hi}"
        )
    return n


def _duration(value) -> float:
    try:
        s = float(value)
    except (TypeError, ValueError):
        s = math.nan
    if not (math.isfinite(s) and s >= 0.01):
        raise UserInputError(
            f"invalid value at --duration: {value_text(value)}; allowed: a number of seconds "
            ">= 0.01"
        )
    return s


def run(args) -> int:
    # the scenario's models on use: --help and argparse's refusals import none of them
    from simpro_mj.config.scenario import load_scenario, scenario_with

    repeats = _positive_int(args.repeats, "--repeats", MAX_REPEATS)
    pairs = _positive_int(args.commands, "--commands", MAX_REPEATS, lo=0)
    runs = _positive_int(args.batch_runs, "--batch-runs", MAX_BATCH_RUNS)
    sets = list(args.sets)
    if args.duration is not None:
        sets.append(f"duration_s={_duration(args.duration)!r}")
    scenario = load_scenario(args.scenario, sets)
    # the measurements load MuJoCo: only once the input is known good (a mistake is
    # refused within a second)
    bench = harness()
    if args.video:
        if args.duration is None:
            scenario = scenario_with(scenario, {"duration_s": 20.0})
        result = bench.measure_video(scenario.model_dump(), progress=not args.json)
        if args.json:
            emit_json(result)
        else:
            print(bench.video_table(result))
        return 0
    progress = None if args.json or args.quiet else (lambda msg: print(f"  {msg}", file=sys.stderr))
    # SIGTERM: exit 130 like Ctrl-C (commands.main), workers stopped
    result = bench.measure(
        scenario.model_dump(), repeats, batch=not args.no_batch, batch_runs=runs, log=progress
    )
    if pairs:
        bare = result["samples"]["bare_step_us"]
        result["separate_commands"] = bench.separate_commands(
            args.scenario, list(args.sets), pairs, bare, log=progress
        )
    if args.json:
        emit_json(result)
    else:
        print(bench.table(result))
    return 0
