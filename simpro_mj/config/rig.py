"""A rig of your own: the platform's geometry in one YAML file.

A rig file gives the points of section 5.2.1 in millimetres, base frame (z up,
x to the back of the platform), at the home pose, with the cylinders' stroke::

    base_anchors_mm:            # A_i, the cylinders' floor pivots
      A1: [-180, 0, 0]
      A2: [180, -500, 0]
      A3: [180, 500, 0]
    platform_anchors_mm:        # B1 the U joint, B2 and B3 the SPS legs' balls
      B1: [-840, 0, 1265]
      B2: [896, -500, 1265]
      B3: [896, 500, 1265]
    bracket_mm:                 # C1 (leg 1's joint) and C2 (the lower guide link's)
      C1: [-760, 0, 1055]
      C2: [-840, 0, 1115]
    guide_centre_from_b1_mm: [1672, -860]   # (x, z) of the guide arc's centre from B1
    stroke_mm: 500
    home_stroke_mm: 250         # slide position at home: sets the retracted lengths

A scenario names it (``plant.rig: my_rig.yaml``: beside the scenario, then the
current folder, then the shipped rigs of ``scenarios/rigs/`` by name); the
resolved scenario holds the rig's numbers (its ``scenario.yaml`` and its hash
carry them). Both sides follow from this one record: the MJCF is rebuilt from it
(:func:`simpro_mj.plant.model.load_spec`) and the controllers' inverse kinematics,
workspace and Jacobian take :func:`controllers.geometry.geometry_from_rig` of it.
The as-built errors (``plant.anchor_offsets_mm``, ``plant.guide``) stay errors of
the plant on top of the rig, which the controllers do not know.

Rules beyond each number's range (:func:`check_rig`): leg 1 and the guide move in
the x-z plane (A1, B1, C1, C2 at y = 0); B1 at the paper's home height 1265 mm
(set-points, plots and the cueing frames measure heave from it); the home stroke
inside the stroke; each leg longer at home than its home stroke; the guide radius
at least 100 mm.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from controllers.geometry import H0, PAPER_RIG_MM
from simpro_mj.config.messages import user_error
from simpro_mj.config.rules import Each, Numbers
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import Block, Real, block, param, read_yaml, value_text
from simpro_mj.core.shipped import SCENARIOS_DIR, user_path

#: The shipped rigs (``plant.rig: NAME`` picks ``NAME.yaml`` here).
RIGS_DIR = SCENARIOS_DIR / "rigs"
#: Farthest point from the base origin (mm, per axis): a driving-simulator base a few
#: metres across.
MAX_POINT_MM = 5000.0
#: Shortest guide radius (mm): the bracket's arc must stay an arc at the platform's heave.
MIN_GUIDE_RADIUS_MM = 100.0

_P = PAPER_RIG_MM
Point = Numbers[list[float], Each(3, ge=-MAX_POINT_MM, le=MAX_POINT_MM)]
Vector2 = Numbers[list[float], Each(2, ge=-MAX_POINT_MM, le=MAX_POINT_MM)]


class BaseAnchors(Block):
    """A_i, the cylinders' floor pivots (mm, base frame)."""

    A1: Point = param(_P["base_anchors_mm"]["A1"], "mm", "leg 1's revolute joint (y = 0)")
    A2: Point = param(_P["base_anchors_mm"]["A2"], "mm", "leg 2's universal joint")
    A3: Point = param(_P["base_anchors_mm"]["A3"], "mm", "leg 3's universal joint")


class PlatformAnchors(Block):
    """B_i at the home pose (mm, base frame): B1 the U joint, B2 and B3 the balls."""

    B1: Point = param(
        _P["platform_anchors_mm"]["B1"], "mm", "the U joint on the bracket (y = 0, z = 1265)"
    )
    B2: Point = param(_P["platform_anchors_mm"]["B2"], "mm", "leg 2's ball joint")
    B3: Point = param(_P["platform_anchors_mm"]["B3"], "mm", "leg 3's ball joint")


class Bracket(Block):
    """The C1-C2-B1 bracket at the home pose (mm, base frame; y = 0)."""

    C1: Point = param(_P["bracket_mm"]["C1"], "mm", "leg 1's spherical joint")
    C2: Point = param(_P["bracket_mm"]["C2"], "mm", "the lower guide link's joint")


class Rig(Block):
    """The platform's geometry (section 5.2.1), millimetres, at the home pose."""

    base_anchors_mm: BaseAnchors = block(BaseAnchors)
    platform_anchors_mm: PlatformAnchors = block(PlatformAnchors)
    bracket_mm: Bracket = block(Bracket)
    guide_centre_from_b1_mm: Vector2 = param(
        _P["guide_centre_from_b1_mm"],
        "mm",
        "(x, z) of the guide arc's centre from B1 (eq. 30: 1672 behind, 860 below)",
    )
    stroke_mm: Real = param(_P["stroke_mm"], "mm", "cylinder stroke (DNC-125-500)", gt=0, le=3000)
    home_stroke_mm: Real = param(
        _P["home_stroke_mm"], "mm", "slide position at the home pose (mid-stroke)", gt=0
    )


def check_rig(rig: Rig, where: str = "plant.rig") -> None:
    """The rules across a rig's fields (module docstring); one-line ``UserInputError``."""

    def refuse(key: str, value: Any, allowed: str) -> None:
        raise UserInputError(
            f"invalid value at {where}.{key}: {value_text(value)}; allowed: {allowed}"
        )

    base, plat, brk = rig.base_anchors_mm, rig.platform_anchors_mm, rig.bracket_mm
    for key, point in (
        ("base_anchors_mm.A1", base.A1),
        ("platform_anchors_mm.B1", plat.B1),
        ("bracket_mm.C1", brk.C1),
        ("bracket_mm.C2", brk.C2),
    ):
        if point[1] != 0:
            refuse(key, point, "[x, 0, z]: leg 1 (R-P-S-U) and the guide move in the x-z plane")
    if abs(plat.B1[2] - H0 * 1e3) > 1e-9:
        refuse(
            "platform_anchors_mm.B1",
            plat.B1,
            f"z = {H0 * 1e3:.0f} mm, the home height the set-points, plots and cueing frames "
            "measure heave from",
        )
    if rig.home_stroke_mm >= rig.stroke_mm:
        refuse("home_stroke_mm", rig.home_stroke_mm, f"< stroke_mm ({rig.stroke_mm:g} mm)")
    if math.hypot(*rig.guide_centre_from_b1_mm) < MIN_GUIDE_RADIUS_MM:
        refuse(
            "guide_centre_from_b1_mm",
            rig.guide_centre_from_b1_mm,
            f"a guide radius >= {MIN_GUIDE_RADIUS_MM:g} mm",
        )
    legs = (("A1", base.A1, brk.C1), ("A2", base.A2, plat.B2), ("A3", base.A3, plat.B3))
    for name, anchor, attach in legs:
        length = math.dist(anchor, attach)
        if length <= rig.home_stroke_mm:
            refuse(
                f"base_anchors_mm.{name}",
                anchor,
                f"a leg longer at home ({length:.1f} mm) than home_stroke_mm "
                f"({rig.home_stroke_mm:g} mm): a positive retracted length",
            )


def shipped_rigs() -> list[str]:
    """Names of the shipped rigs (``scenarios/rigs/*.yaml``), sorted."""
    return sorted(p.stem for p in RIGS_DIR.glob("*.yaml")) if RIGS_DIR.is_dir() else []


def _find(text: str, base: Path | None, where: str) -> Path:
    name = user_path(text, where)
    tries = [name] if name.is_absolute() else []
    if not name.is_absolute():
        if base is not None:
            tries.append(Path(base) / name)
        tries.append(Path.cwd() / name)
        if "/" not in text:
            stem = text[:-5] if text.endswith(".yaml") else text
            tries.append(RIGS_DIR / f"{stem}.yaml")
    for p in tries:
        if p.is_file():
            return p.resolve()
        if p.exists() and not p.is_dir():  # a FIFO, a device: refused, never opened
            raise UserInputError(
                f"invalid value at {where}: {str(p)!r} is not a regular file; allowed: a rig "
                "YAML file"
            )
    raise UserInputError(
        f"invalid value at {where}: {text!r} not found beside the scenario, here or among "
        f"the shipped rigs; allowed: null (the paper's rig), a rig YAML path or one of "
        f"{shipped_rigs()}"
    )


def rig_value(value: Any, base: Path | None = None, where: str = "plant.rig") -> dict | None:
    """A rig given as ``null``, a file path or a mapping, as the validated mapping (mm).

    Raises
    ------
    UserInputError
        One line naming the field (``plant.rig.stroke_mm``) and, for a file, the file.
    """
    if value is None:
        return None
    source = ""
    if isinstance(value, str):
        path = _find(value, base, where)
        value = read_yaml(path, "rig")
        source = f" (rig file {path})"
        if not isinstance(value, Mapping):
            raise UserInputError(
                f"wrong type at {where}{source}: got {type(value).__name__}; allowed: a mapping "
                f"of rig keys {sorted(Rig.model_fields)}"
            )
    if not isinstance(value, Mapping):
        raise UserInputError(
            f"wrong type at {where}: got {type(value).__name__} {value_text(value)}; allowed: "
            "null (the paper's rig), a rig YAML path or a mapping of rig keys"
        )
    try:
        rig = Rig.model_validate(copy.deepcopy(dict(value)))
        check_rig(rig, where)
    except ValidationError as exc:
        raise UserInputError(f"{user_error(exc, Rig, where)}{source}") from None
    except UserInputError as exc:
        raise UserInputError(f"{exc}{source}") from None
    return rig.model_dump()
