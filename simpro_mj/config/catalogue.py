"""What ships with simpro-sim: the scenarios, the plant presets and the telemetry files,
each with the one line that says what it is (``simpro-sim list``).

Found through the functions that load them (:func:`simpro_mj.config.scenario.scenarios_dir`,
:func:`simpro_mj.config.presets.presets_dir`, :data:`simpro_mj.core.shipped.TELEMETRY_DIR`),
so the listing is what ``run``, ``plant.preset`` and ``setpoint.cueing.telemetry`` accept.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from simpro_mj.config.presets import presets_dir, shipped_presets
from simpro_mj.config.scenario import scenarios_dir, shipped_scenarios
from simpro_mj.core.shipped import TELEMETRY_DIR

__all__ = ["catalogue"]


def _yaml_description(path: Path) -> str:
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except (OSError, yaml.YAMLError) as exc:
        return f"(unreadable: {type(exc).__name__})"
    text = str(doc.get("description", "") if isinstance(doc, dict) else "")
    if isinstance(doc, dict) and isinstance(doc.get("sweep"), dict):
        text += " [sweep: simpro-sim batch]"
    return " ".join(text.split())


def _csv_description(path: Path) -> str:
    try:
        with path.open(encoding="utf-8") as fh:
            first = fh.readline().strip()
    except OSError as exc:
        return f"(unreadable: {type(exc).__name__})"
    return first.lstrip("#").strip() if first.startswith("#") else ""


def catalogue() -> dict[str, list[tuple[str, str]]]:
    """``scenarios``, ``presets``, ``telemetry``: (name, one-line description) each, sorted."""
    folder = scenarios_dir()
    scenarios = []
    for name in shipped_scenarios():
        path = next(
            folder / f"{name}{e}" for e in (".yaml", ".yml") if (folder / f"{name}{e}").is_file()
        )
        scenarios.append((name, _yaml_description(path)))
    presets = [(n, _yaml_description(presets_dir() / f"{n}.yaml")) for n in shipped_presets()]
    telemetry = [(p.name, _csv_description(p)) for p in sorted(Path(TELEMETRY_DIR).glob("*.csv"))]
    return {"scenarios": scenarios, "presets": presets, "telemetry": telemetry}
