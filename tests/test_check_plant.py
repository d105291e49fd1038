"""``simpro-sim check-plant``: the plant's physics checked against physics.

Each check's expectation is a law (static friction, the first law, ISO 6358)
or the plant's own parameter; ``simpro_mj.analysis.plant_checks`` states each.
"""

from __future__ import annotations

import json

import pytest

from simpro_mj.analysis.plant_checks import CHECKS, breakaway, check_plant
from simpro_mj.commands.main import main
from simpro_mj.config.scenario import resolve_scenario

pytestmark = pytest.mark.slow


def _cli(capsys, *args) -> tuple[int, str, str]:
    """``simpro-sim check-plant args``: its exit status, stdout and stderr."""
    capsys.readouterr()
    code = main(["check-plant", *args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    "preset, sets",
    [("paper", []), ("heavy_cabin", [])],
)
def test_every_check_holds_on_a_plant_whose_seals_stick(preset, sets):
    checks = check_plant(resolve_scenario({"plant": {"preset": preset}}, sets))
    assert len(checks) == len(CHECKS) >= 7
    assert [c.name for c in checks if not c.ok] == []
    doc = json.loads(json.dumps([c.as_dict() for c in checks]))  # what --json prints
    assert all({"name", "measured", "expected", "ok"} <= set(d) for d in doc)


def test_the_tanh_seal_fails_stiction_and_breakaway():
    """The regularised law creeps under any load: a leg slides at a few percent
    of its breakaway force, and the table says so."""
    sc = resolve_scenario(
        {"plant": {"preset": "heavy_cabin"}},
        ["actuator.pneumatics.cylinder.friction_model=regularised"],
    )
    b = breakaway(sc)
    assert not b.ok and b.measured < 0.2 * b.expected


def test_the_command_prints_the_table_and_exits_by_the_checks(capsys):
    """The table names the seven checks; a plant that fails one exits 1 (the tanh law
    creeps under a held load), an unknown preset is one line, exit 2. That every check
    holds on both presets is the in-process test above."""
    tanh = ["--set", "actuator.pneumatics.cylinder.friction_model=regularised"]
    code, out, err = _cli(capsys, "--preset", "heavy_cabin", *tanh)
    assert code == 1, err
    rows = {line.split(" (")[0]: line for line in out.splitlines() if " (" in line}
    assert set(rows) >= {
        "stiction", "breakaway force", "sealed chamber energy", "null leakage",
        "chamber filling", "supply sag", "loop closure",
    }  # fmt: skip
    failed = sorted(name for name, line in rows.items() if line.rstrip().endswith("NO"))
    assert failed == ["breakaway force", "stiction"]
    code, _, err = _cli(capsys, "--preset", "nope")
    assert code == 2 and err.count("\n") == 1 and "allowed" in err


@pytest.mark.parametrize("hw", [0.0, 30.0, 1e4])
def test_the_energy_model_spans_adiabatic_to_isothermal(hw):
    """A sealed chamber compressed by 100 mm in 250 ms with the energy equation: no
    heat flow is the adiabatic chamber (effective index 1.4, the polytropic model's
    own numbers), a wall that exchanges heat fast enough makes it isothermal (1.0),
    and the first law holds over a whole cycle within the step's own residual."""
    import math

    import numpy as np

    from simpro_mj.analysis.plant_checks import _sealed, sealed_chamber_energy

    sets = [
        "actuator.pneumatics.thermal.model=energy",
        f"actuator.pneumatics.thermal.heat_transfer_w_per_m2_k={hw}",
    ]
    sc = resolve_scenario({"plant": {"preset": "paper"}}, sets)
    act = _sealed(sc)
    P, q0, dt = act.params, 0.25, 1e-3
    act.reset(np.full(3, q0), np.zeros(3))
    act.spool[:] = 0.0
    p0 = float(act.p1[0])
    w = 2.0 * math.pi
    for k in range(250):
        t = k * dt
        act.step([5.0] * 3, [q0 - 0.1 * math.sin(w * t)] * 3, [-0.1 * w * math.cos(w * t)] * 3, dt)
    v0 = P.dead_cap[0] + P.area_cap * q0
    v1 = P.dead_cap[0] + P.area_cap * (q0 - 0.1)
    n_eff = math.log(float(act.p1[0]) / p0) / math.log(v0 / v1)
    want = {0.0: 1.4, 30.0: 1.39, 1e4: 1.0}[hw]
    assert n_eff == pytest.approx(want, abs=0.03)
    assert sealed_chamber_energy(sc).ok


def test_the_supply_as_built_sags_and_conserves_mass():
    """Every valve open for 0.4 s on the cabin: the ideal source holds 6 bar; the
    receiver, regulator and line sag (by more than 0.5 bar here: the valves ask
    several times the compressor's 400 l/min) while receiver and line lose exactly
    the mass the valves take less the compressor's."""
    from simpro_mj.analysis.plant_checks import supply_sag

    ideal = supply_sag(resolve_scenario({"plant": {"preset": "heavy_cabin"}}))
    assert ideal.ok and ideal.measured == 0.0
    sc = resolve_scenario(
        {"plant": {"preset": "heavy_cabin"}}, ["actuator.pneumatics.supply.model=receiver"]
    )
    built = supply_sag(sc)
    assert built.ok, built
    sag = float(built.name.split("sags ")[1].split(" bar")[0])
    assert sag > 0.5


def test_a_pressure_switch_that_stops_below_it_starts_is_refused():
    from simpro_mj.core.errors import UserInputError

    with pytest.raises(UserInputError, match=r"cut_out_bar_gauge.*cut_in_bar_gauge"):
        resolve_scenario(
            {"plant": {"preset": "paper"}},
            [
                "actuator.pneumatics.supply.cut_in_bar_gauge=8",
                "actuator.pneumatics.supply.cut_out_bar_gauge=7",
            ],
        )
