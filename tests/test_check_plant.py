"""``simpro-sim check-plant``: the plant's physics checked against physics.

Each check's expectation is a law (static friction, the first law, ISO 6358)
or the plant's own parameter; ``simpro_mj.analysis.plant_checks`` states each.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from simpro_mj.analysis.plant_checks import CHECKS, breakaway, check_plant
from simpro_mj.config.scenario import resolve_scenario

pytestmark = pytest.mark.slow


def _cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "simpro_mj.commands.main", "check-plant", *args],
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.parametrize(
    "preset, sets",
    [("paper", []), ("heavy_cabin", ["actuator.pneumatics.cylinder.friction_model=stick"])],
)
def test_every_check_holds_on_a_plant_whose_seals_stick(preset, sets):
    checks = check_plant(resolve_scenario({"plant": {"preset": preset}}, sets))
    assert len(checks) == len(CHECKS) >= 7
    assert [c.name for c in checks if not c.ok] == []


def test_the_tanh_seal_fails_stiction_and_breakaway():
    """The regularised law creeps under any load: a leg slides at a few percent
    of its breakaway force, and the table says so."""
    sc = resolve_scenario(
        {"plant": {"preset": "heavy_cabin"}},
        ["actuator.pneumatics.cylinder.friction_model=regularised"],
    )
    b = breakaway(sc)
    assert not b.ok and b.measured < 0.2 * b.expected


def test_the_command_prints_the_table_and_exits_by_the_checks():
    ok = _cli("--preset", "paper", "--json")
    assert ok.returncode == 0, ok.stderr
    doc = json.loads(ok.stdout)
    assert {c["name"].split(" (")[0] for c in doc["checks"]} >= {
        "stiction", "breakaway force", "sealed chamber energy", "null leakage",
        "chamber filling", "supply sag", "loop closure",
    }  # fmt: skip
    bad = _cli("--preset", "heavy_cabin")  # the preset's seals are the tanh law
    assert bad.returncode == 1 and "NO" in bad.stdout
    wrong = _cli("--preset", "nope")
    assert wrong.returncode == 2 and wrong.stderr.count("\n") == 1 and "allowed" in wrong.stderr
