"""``simpro-sim response SCENARIO``: closed-loop frequency response per task axis (OMCT-style).

Stepped sines on each axis in turn (:mod:`simpro_mj.analysis.response`), fitted by
least squares over settled whole periods, beside the prediction of the
linearised loop (:mod:`controllers.frequency`, python-control). Writes
``response.csv`` (one row per input axis, output axis, signal and
frequency), ``response.json`` (what ``--json`` prints), ``bode.png`` (each
axis: measured true and measured pose, predicted, their difference) and
``cross_axis.png`` into ``--out`` (default ``results/<name>-response``).

``--chain``: the whole motion-cueing chain instead
(:mod:`simpro_mj.analysis.chain_response`): a sine on one vehicle channel (specific
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

import argparse
import math
import os
from dataclasses import fields
from pathlib import Path
from typing import Any

from simpro_mj.core.errors import UserInputError

HELP = (
    "closed-loop frequency response per task axis, or (--chain) of the whole cueing chain "
    "vehicle -> head (stepped sines, OMCT frequencies)"
)


def _floats(text: str) -> list[float]:

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


#: options of one kind of response only: (dest, it is --chain's, its default, the other
#: kind's options)
_ONE_KIND = (
    ("amplitude_mps2", True, None, "--amplitude-deg, --amplitude-mm for the pose response"),
    ("amplitude_deg_s", True, None, "--amplitude-deg, --amplitude-mm for the pose response"),
    ("channels", True, "fx,fy,fz,wx,wy", "--axes"),
    ("amplitude_deg", False, None, "--amplitude-deg-s for the chain"),
    ("amplitude_mm", False, None, "--amplitude-mps2 for the chain"),
    ("axes", False, "roll,pitch,heave", "--channels"),
)


def run(args) -> int:
    # the measurement and its prediction load python-control and scipy, the scenario
    # pydantic, the report matplotlib: imported once argparse has checked the options
    from simpro_mj.analysis.chain_response import (
        DEFAULT_SETTLE_S,
        ChainRow,
        chain_summary,
        cue_block,
        measure_chain_point,
        plan_chain,
    )
    from simpro_mj.analysis.response import check_periods, measure, plan_response
    from simpro_mj.analysis.response_summary import ResponseRow, loop_model, summary
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.report.figures import loop_label
    from simpro_mj.report.folders import claim
    from simpro_mj.report.response import (
        csv_text,
        plot,
        plot_chain,
        print_chain_summary,
        print_summary,
        write_result,
    )
    from simpro_mj.sim.executors import MAX_JOBS, dask_module

    jobs = args.jobs if args.jobs is not None else (os.cpu_count() or 1)
    if not 1 <= jobs <= MAX_JOBS:
        raise UserInputError(f"invalid value at --jobs: {jobs}; allowed: an integer 1..{MAX_JOBS}")
    for dest, chain, default, other in _ONE_KIND:
        if chain != args.chain and getattr(args, dest) != default:
            flag, where = "--" + dest.replace("_", "-"), "only with" if chain else "not with"
            raise UserInputError(f"invalid value at {flag}: {where} --chain; allowed: {other}")
    spec = load_scenario(args.scenario, args.sets)
    scenario = spec.model_dump()  # the analyses' plans read the resolved dict
    if args.freq_hz is not None and not args.freq_hz:
        raise UserInputError("invalid value at --freq-hz: empty; allowed: one or more frequencies")
    periods_ms = None if args.freq_hz is None else check_periods(args.freq_hz)
    plan: Any  # a SinePlan of either kind, and their summaries and drawings below
    summ: Any
    if args.chain:
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
    else:
        deg = 0.5 if args.amplitude_deg is None else args.amplitude_deg
        mm = 5.0 if args.amplitude_mm is None else args.amplitude_mm
        axes = tuple(a.strip() for a in args.axes.split(",") if a.strip())
        plan = plan_response(
            scenario,
            periods_ms=periods_ms,
            amplitudes={"roll": deg, "pitch": deg, "heave": mm},
            axes=axes,
            settle_s=4.0 if args.settle_s is None else args.settle_s,
            periods=args.periods,
        )
    if args.scheduler is not None:
        dask_module()  # say so before anything runs
    kind = "chain" if args.chain else "response"
    out = Path(args.out) if args.out else Path("results") / f"{spec.name}-{kind}"
    with claim(out, "response", inputs=[args.scenario]):
        options = dict(
            jobs=min(jobs, len(plan.tasks)),
            scheduler=args.scheduler,
            progress=not args.quiet and not args.json,
        )
        if args.chain:
            results = measure(plan, fn=measure_chain_point, desc="chain response", **options)
            summ = chain_summary(plan, results)
            part = {
                "channels_excited": list(plan.inputs),
                "amplitude": {
                    "f_mps2": plan.amplitudes["fx"],
                    "w_deg_s": math.degrees(plan.amplitudes["wx"]),
                },
                "settle_s": plan.settle_s,
                "periods": plan.periods,
                "frequencies_rad_s": [2000.0 * math.pi / p for p in plan.periods_ms],
                "washout": cue_block(scenario),
            }
        else:
            model = loop_model(scenario)
            summ = summary(plan, measure(plan, **options), model)
            part = {
                # the law as analysed: an I law by backward Euler is the PI form with c = 0
                "analysed_law": model.mode,
                "axes_excited": list(plan.inputs),
                "amplitude": {"roll_deg": deg, "pitch_deg": deg, "heave_mm": mm},
                "settle_s": plan.settle_s,
                "periods": plan.periods,
                "frequencies_hz": [1000.0 / p for p in sorted(plan.periods_ms, reverse=True)],
            }
        loop = loop_label(scenario)
        doc = {
            "scenario": spec.name,
            **({"kind": "chain"} if args.chain else {}),
            "mode": spec.controller.mode,
            "loop": loop,
            **part,
            **summ.to_json(),
        }
        title = f"{spec.name} ({loop})"

        def plotter(_doc, folder: Path) -> list[str]:
            if args.chain:
                return plot_chain(summ, title, folder)
            return plot(summ, plan.inputs, title, folder)

        rows = csv_text(
            doc["rows"], [f.name for f in fields(ChainRow if args.chain else ResponseRow)]
        )
        write_result(out, doc, kind, rows, None if args.no_plots else plotter)
    if args.json:
        from simpro_mj.core.jsonout import emit_json
        from simpro_mj.report.results import jsonable

        emit_json(jsonable(doc))
    else:
        (print_chain_summary if args.chain else print_summary)(summ, title, out)
    return 0 if not summ.failed else 1
