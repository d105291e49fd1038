"""``simpro-sim calibrate``: fit the plant's uncertain parameters to identified models.

The fit is :mod:`simpro_mj.analysis.calibrate`; this module parses, shows the
progress, writes the preset YAML and prints the verdict."""

from __future__ import annotations

import sys
from pathlib import Path

import yaml
from tqdm import tqdm

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.keys import apply_overrides
from simpro_mj.core.progress import show_progress
from simpro_mj.report.single_files import check_file, write_file

HELP = "fit masses, friction and valve flow so that identify reproduces target models"


def add_arguments(parser) -> None:
    parser.add_argument(
        "--targets",
        default=None,
        help="YAML of identified models per actuator ({b, a1, a0} in SI, or wn_rad_s, zeta, "
        "velocity_gain_m_s_per_v); default eqs. (34)-(35) under paper_units",
    )
    parser.add_argument("--start", default="paper", help="preset to start from (default paper)")
    parser.add_argument("--name", default="calibrated", help="name of the written preset")
    parser.add_argument(
        "--out", default=None, help="preset YAML to write (default results/calibrate/NAME.yaml)"
    )
    parser.add_argument(
        "--overwrite", action="store_true",
        help="replace --out even if simpro-sim did not write it (default: refuse)",
    )  # fmt: skip
    parser.add_argument(
        "--evaluations", type=int, default=30, help="budget of identification runs (30)"
    )
    parser.add_argument(
        "--duration", type=float, default=4.0, help="PRBS per actuator and evaluation, s (4)"
    )
    parser.add_argument(
        "--amplitudes", type=float, nargs="+", default=[0.3, 1.0], metavar="V",
        help="PRBS amplitudes fitted at once, V (0.3 1.0: small signal and the steps' range)",
    )  # fmt: skip


def _check(args) -> None:
    from simpro_mj.config.rules import NAME_RE

    if not (NAME_RE.match(args.name) and len(args.name) <= 100):
        raise UserInputError(
            f"invalid value at --name: {args.name!r}; allowed: letters, digits, '_', '-', '.' "
            "(a file-name-safe word of at most 100 characters, no path separator)"
        )
    amps = args.amplitudes
    for flag, value, ok, allowed in (
        ("--evaluations", args.evaluations, 1 <= args.evaluations <= 1000, "1..1000"),
        ("--duration", args.duration, 0.5 <= args.duration <= 60.0, "0.5..60 s"),
        ("--amplitudes", amps, all(0 < a <= 5 for a in amps), "amplitudes in (0, 5] V"),
    ):
        if not ok:
            raise UserInputError(f"invalid value at {flag}: {value}; allowed: {allowed}")


def run(args) -> int:
    _check(args)
    out = Path(args.out) if args.out else Path("results") / "calibrate" / f"{args.name}.yaml"
    if out.suffix not in (".yaml", ".yml"):
        raise UserInputError(f"invalid value at --out: {out}; allowed: a path ending in .yaml")
    # every input and the output checked before the fit (minutes of work) starts, and
    # before MuJoCo is imported, so that a mistake is refused within a second
    check_file(out, args.overwrite)
    from simpro_mj.analysis.targets import load_targets
    from simpro_mj.identification.settings import check_tree, default_tree

    user_targets = None if args.targets is None else load_targets(args.targets)
    tree = apply_overrides(default_tree(args.start), args.sets)
    ex = check_tree(tree)
    # the fit loads MuJoCo and SciPy: after every input has been checked
    from simpro_mj.analysis.calibrate import calibrate_preset, paper_targets

    targets = paper_targets(ex.paper_units) if user_targets is None else user_targets
    bar = tqdm(total=args.evaluations, desc="calibrate", unit="eval", file=sys.stderr,
               disable=not show_progress(args))  # fmt: skip

    def progress(i, cost):
        bar.set_postfix(cost=f"{cost:.3g}")
        bar.update(1)

    doc, result = calibrate_preset(
        tree, targets, args.name, duration_s=args.duration, max_evaluations=args.evaluations,
        amplitudes_v=args.amplitudes, progress=progress,
    )  # fmt: skip
    bar.close()
    out = write_file(out, yaml.safe_dump(doc, sort_keys=False), args.overwrite)
    worst = max(abs(v) for r in (result.residuals or {}).values() for v in r.values())
    if args.json:
        emit_json(doc)
    else:
        for a, r in (result.identified or {}).items():
            t = targets[a]
            print(
                f"{a}: wn {r.wn_rad_s:.2f} (target {t['wn_rad_s']:.2f}) rad/s, zeta "
                f"{r.zeta:.3f} ({t['zeta']:.3f}), b/a0 {r.velocity_gain_m_s_per_v:.4f} "
                f"({t['velocity_gain_m_s_per_v']:.4f}) m/s/V"
            )
        verdict = "within" if worst <= 1.0 else "OUTSIDE"
        print(f"worst residual {worst:.2f} x tolerance: {verdict} the tolerances; wrote {out}")
    return 0
