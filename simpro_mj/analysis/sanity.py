"""Warnings where a unit mistake is likely and physics can tell: a scenario that runs,
but probably not as its author meant. Each is a ``warning:`` line on stderr and an entry
of ``metrics.json``'s ``warnings`` (through :func:`simpro_mj.analysis.preflight.preflight`).

The rules, with their reasons:

* **radians in a degrees key**: every non-zero step, ramp or sine value of
  ``setpoint.roll_deg`` or ``pitch_deg`` is below :data:`RADIANS_BELOW_DEG` (0.2 deg) in
  size. The platform tilts by degrees (the paper's steps are 2-3 deg; its IMU floor is
  0.001 deg), and 1-10 deg typed in radians is 0.017-0.17: a set-point that small is
  more likely radians than an intended tenth of a degree.
* **telemetry without gravity, or in g**: the mean ``fz_mps2`` of a cueing telemetry
  file differs from g = 9.81 m/s² by more than :data:`FZ_TOLERANCE_MPS2` (3 m/s²). The
  specific force at the driver's head (after the scenario's column mapping and its
  scale) includes gravity (ISO 8855, z up): a car's
  vertical specific force averages g within a few tenths over any manoeuvre that ends
  where it started in height; 0 means gravity was left out, 1 means the file is in g.
* **a poor identification fit**: an actuator fitted below :data:`FIT_WARN_PERCENT`
  (80 %) of the measured velocity's variance (``simpro-sim identify``): its model, and
  the joint loops designed on it, do not describe the cylinder.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

RADIANS_BELOW_DEG = 0.2
FZ_TOLERANCE_MPS2 = 3.0
FIT_WARN_PERCENT = 80.0
_G = 9.80665


def radians_warnings(scenario: Mapping) -> list[str]:
    """The radians-in-degrees rule (module docstring) on ``setpoint.roll_deg``, ``pitch_deg``."""
    out = []
    for key in ("roll_deg", "pitch_deg"):
        entries = (scenario.get("setpoint") or {}).get(key) or []
        values = []
        for e in entries:
            for field in ("value", "amplitude"):
                v = e.get(field) if isinstance(e, Mapping) else None
                if isinstance(v, (int, float)) and not isinstance(v, bool) and v != 0:
                    values.append(float(v))
        if values and max(abs(v) for v in values) < RADIANS_BELOW_DEG:
            big = max(values, key=abs)
            out.append(
                f"setpoint.{key}: every value is below {RADIANS_BELOW_DEG:g} deg (largest "
                f"{big:g}); if these are radians, {big:g} rad = {math.degrees(big):.3g} deg: "
                f"the key takes degrees"
            )
    return out


def telemetry_warnings(scenario: Mapping) -> list[str]:
    """The gravity rule (module docstring) on ``setpoint.cueing.telemetry``."""
    cue = (scenario.get("setpoint") or {}).get("cueing") or {}
    path = cue.get("telemetry") if isinstance(cue, Mapping) else None
    if not path:
        return []
    from simpro_mj.config.telemetry import read_telemetry

    try:
        tel = read_telemetry(path, columns=cue.get("columns"))  # the mapping's units applied
    except Exception:  # noqa: BLE001 - the scenario's checks report an unreadable file
        return []
    if not len(tel.t):
        return []
    mean_fz = float(tel.f[:, 2].mean())
    if abs(mean_fz - _G) <= FZ_TOLERANCE_MPS2:
        return []
    return [
        f"setpoint.cueing.telemetry {path}: mean fz_mps2 = {mean_fz:.3g} m/s², expected about "
        f"{_G:.2f} (the specific force includes gravity, z up): gravity left out, or the file "
        "in g rather than m/s²?"
    ]


def fit_warnings(results: Mapping) -> list[str]:
    """The identification rule (module docstring) on ``{actuator: {fit_percent, ...}}``."""
    out = []
    for name, r in results.items():
        fit = r.get("fit_percent") if isinstance(r, Mapping) else None
        if fit is not None and fit < FIT_WARN_PERCENT:
            out.append(
                f"{name}: the identified model fits {fit:.0f} % of the measured velocity "
                f"(below {FIT_WARN_PERCENT:g} %): it does not describe the cylinder; try a "
                "longer or larger excitation (--duration, --set identify.*)"
            )
    return out


def unit_warnings(scenario: Mapping) -> list[str]:
    """The scenario's unit warnings: radians in a degrees key, telemetry without gravity."""
    return radians_warnings(scenario) + telemetry_warnings(scenario)
