"""``simpro-sim omct``: the Objective Motion Cueing Test of each cueing law.

Every law (:data:`simpro_mj.analysis.omct.LAWS`: the classical washout of
``cue_slalom``, the MPC of ``cue_braking`` with and without its preview) driven by a sine
on each vehicle channel at the twelve OMCT frequencies, through the platform loop's model
to a rigid cabin's head: gain and phase of every test (``omct.csv``, ``omct.json``), the
Bode plots (``omct_bode.png``) and the fidelity regions at 1 rad/s
(``omct_fidelity.png``). ``simpro-sim response --chain`` measures one law through the
whole plant instead.
"""

from __future__ import annotations

from pathlib import Path

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.jsonout import emit_json

HELP = "objective motion cueing test of each cueing law (gain, phase, fidelity at 1 rad/s)"


def add_arguments(parser) -> None:
    parser.add_argument(
        "--laws",
        default=None,
        help="comma-separated laws (default classical_washout,mpc_causal,mpc_shipped)",
    )
    parser.add_argument(
        "--amplitude-mps2", type=float, default=None, help="specific-force sine (default 0.3)"
    )
    parser.add_argument(
        "--amplitude-deg-s", type=float, default=None, help="rotation-rate sine (default 1)"
    )
    parser.add_argument("--out", default=None, help="result folder (default results/omct)")
    parser.add_argument("--no-plots", action="store_true", help="no figures")


def _amplitude(value, flag: str, low: float, high: float, unit: str):
    if value is None:
        return None
    if not (low <= value <= high):
        raise UserInputError(
            f"invalid value at {flag}: {value!r}; allowed: {low:g}..{high:g} {unit}"
        )
    return float(value)


def run(args) -> int:
    import math

    from simpro_mj.analysis.omct import law_blocks, omct
    from simpro_mj.report.omct import CSV_COLUMNS, plot_omct, print_omct_summary
    from simpro_mj.report.response import csv_text, write_result

    names = None if args.laws is None else [s.strip() for s in args.laws.split(",") if s.strip()]
    if names is not None and not names:
        raise UserInputError("invalid value at --laws: empty; allowed: a comma-separated list")
    blocks = law_blocks(names)
    amps = {}
    af = _amplitude(args.amplitude_mps2, "--amplitude-mps2", 0.01, 5.0, "m/s^2")
    aw = _amplitude(args.amplitude_deg_s, "--amplitude-deg-s", 0.1, 20.0, "deg/s")
    if af is not None:
        amps["f"] = af
    if aw is not None:
        amps["w"] = math.radians(aw)
    res = omct(blocks, amplitudes=amps)
    doc = {**res.to_json(), "kind": "omct"}
    out = Path(args.out) if args.out else Path("results") / "omct"

    def plotter(_doc, folder: Path) -> list[str]:
        return plot_omct(res, folder)

    write_result(out, doc, "omct", csv_text(doc["rows"], CSV_COLUMNS),
                 None if args.no_plots else plotter)  # fmt: skip
    if args.json:
        emit_json(doc)
        return 0
    print_omct_summary(res, out, doc["files"])
    return 0
