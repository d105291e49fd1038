"""``simpro-sim workspace``: reachable ranges of roll, pitch and heave."""

from __future__ import annotations

import numpy as np

from controllers.geometry import nominal_geometry
from controllers.workspace import combined_ranges, workspace_ranges
from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.keys import apply_overrides, check_number

HELP = "print the reachable workspace (single-axis ranges and their combinations)"

DEFAULTS = {"margin_mm": 0.0, "heights": 5}


def add_arguments(parser) -> None:
    pass


def run(args) -> int:
    p = apply_overrides(DEFAULTS, args.sets)
    # stroke margin below half the 500 mm stroke; heights bounded to keep it quick
    check_number(p, "margin_mm", 0.0, 250.0, hi_open=True, unit=" mm")
    check_number(p, "heights", 1, 1000, integer=True)
    margin = p["margin_mm"] * 1e-3
    g = nominal_geometry()
    single = workspace_ranges(g, margin)
    combo = combined_ranges(g, int(p["heights"]), margin)
    out = {
        "home": {"roll_deg": 0.0, "pitch_deg": 0.0, "heave_mm": g.home[2] * 1e3},
        "roll_deg": np.degrees(single["roll"]).tolist(),
        "pitch_deg": np.degrees(single["pitch"]).tolist(),
        "heave_mm": (np.asarray(single["heave"]) * 1e3).tolist(),
        "at_heights": [
            {
                "heave_mm": r["heave"] * 1e3,
                "roll_deg": np.degrees(r["roll"]).tolist(),
                "pitch_deg": np.degrees(r["pitch"]).tolist(),
            }
            for r in combo
        ],
    }
    if args.json:
        emit_json(out)
        return 0
    print(f"Reachable workspace (stroke 0..500 mm, margin {p['margin_mm']} mm), about home:")
    print(f"  roll   {out['roll_deg'][0]:8.2f} .. {out['roll_deg'][1]:7.2f} deg")
    print(f"  pitch  {out['pitch_deg'][0]:8.2f} .. {out['pitch_deg'][1]:7.2f} deg")
    print(f"  heave  {out['heave_mm'][0]:8.1f} .. {out['heave_mm'][1]:7.1f} mm")
    print("  at other heights (roll and pitch with the other angle zero):")
    for r in out["at_heights"]:
        print(
            f"    h = {r['heave_mm']:7.1f} mm: "
            f"roll {r['roll_deg'][0]:7.2f}..{r['roll_deg'][1]:6.2f}"
            f" deg, pitch {r['pitch_deg'][0]:7.2f}..{r['pitch_deg'][1]:6.2f} deg"
        )
    return 0
