"""Calibration targets: a rig owner's identified actuator models, read and checked.

Read before the fit loads MuJoCo, so that a mistake in the file is refused
within a second (one line, exit 2). Each model is eq. (19)'s ``{b, a1, a0}``
(SI) or ``{wn_rad_s, zeta, velocity_gain_m_s_per_v}``; both are checked in
the second form against :data:`PLAUSIBLE`, the range a pneumatic cylinder
on this platform can show.
"""

from __future__ import annotations

import math
from pathlib import Path

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import read_yaml

#: Allowed range of each target and why. Eqs. (34)-(35) give wn 15.9 and 36.7 rad/s,
#: zeta 0.87 and 0.10, b/a0 0.049 and 0.074 m/s/V.
PLAUSIBLE = {
    "wn_rad_s": (
        1.0, 1000.0,
        "the pneumatic spring of a cylinder on a moving mass: about 5..200 rad/s on this "
        "platform; outside 1..1000 rad/s no valve-cylinder pair fits eq. (19)",
    ),
    "zeta": (1e-3, 20.0, "damping ratio of a real cylinder: seal friction makes it > 0"),
    "velocity_gain_m_s_per_v": (
        1e-4, 1.0,
        "FESTO DNC cylinders run at most about 1 m/s (10 V is full valve opening: "
        "0.1 m/s/V); 1 m/s/V is ten times that",
    ),
}  # fmt: skip


def load_targets(path: str | Path) -> dict:
    """A rig owner's identified models from YAML.

    Each of ``actuator1``, ``actuator2``, ``actuator3`` is either eq. (19)'s
    coefficients in SI ``{b, a1, a0}`` (m/s^3/V, 1/s, 1/s^2) or
    ``{wn_rad_s, zeta, velocity_gain_m_s_per_v}``. Raises
    :class:`UserInputError` (one line, the field and what is allowed).
    """
    p = Path(path)
    doc = read_yaml(p, "targets")
    acts = ("actuator1", "actuator2", "actuator3")
    if not isinstance(doc, dict):
        raise UserInputError(
            f"wrong type at {p.name} (top level): {type(doc).__name__}; allowed: a mapping "
            f"with keys {list(acts)}"
        )
    extra = sorted(str(k) for k in doc if k not in acts)
    if extra:
        raise UserInputError(f"unknown key at {extra[0]}: allowed keys are {list(acts)}")
    out = {}
    for a in acts:
        if a not in doc:
            raise UserInputError(f"missing key at {a}: allowed: a mapping of b, a1, a0")
        node = doc[a]
        forms = ({"b", "a1", "a0"}, {"wn_rad_s", "zeta", "velocity_gain_m_s_per_v"})
        if not isinstance(node, dict) or set(node) not in forms:
            raise UserInputError(
                f"invalid value at {a}: {node!r}; allowed: {{b, a1, a0}} (SI) or "
                "{wn_rad_s, zeta, velocity_gain_m_s_per_v}"
            )
        vals = {}
        for k, v in node.items():
            ok = isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            if not ok or v <= 0 and k != "a1" or v < 0:
                raise UserInputError(
                    f"invalid value at {a}.{k}: {v!r}; allowed: a finite number > 0"
                    + (" (>= 0 for a1)" if k == "a1" else "")
                )
            vals[k] = float(v)
        if "b" in vals:
            wn = math.sqrt(vals["a0"])
            vals = {
                "wn_rad_s": wn,
                "zeta": vals["a1"] / (2 * wn),
                "velocity_gain_m_s_per_v": vals["b"] / vals["a0"],
            }
        given = "from b, a1, a0" if "b" in node else "given"
        for key, (lo, hi, why) in PLAUSIBLE.items():
            x = vals[key]
            if not (math.isfinite(x) and lo <= x <= hi):
                raise UserInputError(
                    f"implausible target at {a}.{key}: {x:.6g} ({given}); allowed: "
                    f"{lo:g}..{hi:g} ({why})"
                )
        out[a] = vals
    return out
