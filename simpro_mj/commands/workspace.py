"""``simpro-sim workspace``: reachable ranges of roll, pitch and heave."""

from __future__ import annotations

import numpy as np

from controllers.geometry import nominal_geometry
from controllers.workspace import combined_ranges, workspace_ranges
from simpro_mj.config.messages import from_sets
from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.keys import Block, Real, Whole, param

HELP = "print the reachable workspace (single-axis ranges and their combinations)"


class WorkspaceParams(Block):
    """``--set`` keys of ``simpro-sim workspace``."""

    margin_mm: Real = param(
        0.0, "mm", "stroke margin kept at both ends (below half the 500 mm stroke)", ge=0, lt=250
    )
    heights: Whole = param(5, "", "heave levels of the combined ranges", ge=1, le=1000)


def add_arguments(parser) -> None:
    pass


def run(args) -> int:
    p = from_sets(WorkspaceParams, args.sets)
    margin = p.margin_mm * 1e-3
    g = nominal_geometry()
    single = workspace_ranges(g, margin)
    combo = combined_ranges(g, p.heights, margin)
    roll, pitch = np.degrees(single["roll"]).tolist(), np.degrees(single["pitch"]).tolist()
    heave = (np.asarray(single["heave"]) * 1e3).tolist()
    # per heave level (mm): the roll and pitch ranges (deg)
    levels = [
        (r["heave"] * 1e3, np.degrees(r["roll"]).tolist(), np.degrees(r["pitch"]).tolist())
        for r in combo
    ]
    if args.json:
        home = {"roll_deg": 0.0, "pitch_deg": 0.0, "heave_mm": g.home[2] * 1e3}
        at = [{"heave_mm": h, "roll_deg": rr, "pitch_deg": pr} for h, rr, pr in levels]
        emit_json({"home": home, "roll_deg": roll, "pitch_deg": pitch, "heave_mm": heave,
                   "at_heights": at})  # fmt: skip
        return 0
    print(f"Reachable workspace (stroke 0..500 mm, margin {p.margin_mm} mm), about home:")
    print(f"  roll   {roll[0]:8.2f} .. {roll[1]:7.2f} deg")
    print(f"  pitch  {pitch[0]:8.2f} .. {pitch[1]:7.2f} deg")
    print(f"  heave  {heave[0]:8.1f} .. {heave[1]:7.1f} mm")
    print("  at other heights (roll and pitch with the other angle zero):")
    for h, (r0, r1), (p0, p1) in levels:
        print(f"    h = {h:7.1f} mm: roll {r0:7.2f}..{r1:6.2f} deg, pitch {p0:7.2f}..{p1:6.2f} deg")
    return 0
