"""Golden hashes of every shipped scenario and sweep variant.

``scenario_hash`` of the resolved scenario is what ``simpro-sim batch
--resume`` compares to decide that a finished variant need not run again
(:mod:`simpro_mj.batch.batch`). Reorganising the scenario's validation (typed
models) must not change a single resolved value, default, type or
key order that reaches the hash: this test pins the hash of every shipped
scenario (``load_scenario``) and of every variant of every shipped sweep file
(``load_sweep``).

A telemetry file enters the hash by its contents, not its absolute path (which
differs between checkouts), so the pins hold on any machine.

Regenerate only on purpose (a scenario or a default changed):
``python tests/test_scenario_hashes.py --write``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from unittest import mock

import pytest

from simpro_mj.config.models import scenario_model
from simpro_mj.config.scenario import load_scenario, scenario_hash, shipped_scenarios
from simpro_mj.config.variants import load_sweep

DATA = Path(__file__).resolve().parent / "data" / "scenario_hashes.json"
_EMPTY = {"scenarios": {}, "extra": {}, "variants": {}}
_PINNED = json.loads(DATA.read_text()) if DATA.is_file() else _EMPTY


#: Overrides that reach what no shipped file uses (every component and fault type, the
#: one-number per-leg list, free-form pneumatics, the other cueing inputs), pinned too.
EXTRA = {
    "components": [
        "setpoint.roll_deg=[{type: ramp, start_s: 1, end_s: 2, value: 2}, "
        "{type: sine, amplitude: 1, period_s: 2}]",
        "setpoint.heave_mm=[{type: table, times_s: [0, 1, 2], values: [0, 5, 10]}, "
        "{type: sine, amplitude: 3, period_s: 4, phase_deg: 90, start_s: 1, end_s: 9}]",
        "seed=7",
        "duration_s=10",
    ],
    "faults": [
        "faults=[{type: supply_drop, time_s: 5, pressure_bar_gauge: 2}, "
        "{type: valve_stuck, time_s: 1, leg: 2, voltage_v: 5}, "
        "{type: sensor_frozen, time_s: 2, sensor: potentiometer, leg: 1, end_s: 3}, "
        "{type: sensor_dropout, time_s: 2, sensor: imu, axis: roll, probability: 0.5}, "
        "{type: sensor_bias, time_s: 2, sensor: height_encoder, bias_mm: 1}, "
        "{type: sensor_bias, time_s: 2, sensor: imu, bias_deg: 0.5}, "
        "{type: potentiometer_failure, time_s: 3, leg: 3, mode: short}]",
    ],
    "plant": [
        "controller.setpoint_filter.time_ms=60",
        "actuator.pneumatics={supply_pressure_bar_gauge: 5.5, cylinder: "
        "{coulomb_friction_n: 30, viscous_friction_n_s_per_m: [9000, 500, 500]}}",
        "plant.preset=heavy_cabin",
        "controller.inner.variant=redesigned",
        "controller.inner.design_plant=identified",
        "sensors.potentiometer.bits=12",
        "logging.decimation=5",
    ],
    "cue_sine": [
        "setpoint.cueing={sine: {channel: fx_mps2, amplitude: 0.3, period_s: 4}}",
        "duration_s=8",
    ],
    "cue_manoeuvre": [
        "setpoint.cueing={manoeuvre: {type: lane_change, speed_kmh: 60}, "
        "parameters: {gain_x: 0.6}}",
        "duration_s=8",
    ],
}


def current_hashes() -> dict:
    """``{"scenarios": {name: hash}, "extra": {case: hash},
    "variants": {file: {variant: hash or error}}}``.

    Resolved without the set-point reachability check: it only raises, never changes
    the scenario, and on a cueing scenario it runs the whole cueing chain (an MPC run
    each, about 40 s for every file and variant); tests/test_scenario.py loads every
    shipped scenario with it.
    """
    with mock.patch("simpro_mj.config.scenario.check_setpoints", lambda scenario: None):
        return _hashes()


def _hashes() -> dict:
    names = shipped_scenarios()
    scenarios = {name: scenario_hash(load_scenario(name)) for name in names}
    extra = {name: scenario_hash(load_scenario("step_pitch", sets)) for name, sets in EXTRA.items()}
    variants = {}
    for name in shipped_scenarios():
        sweep = load_sweep(name)
        if sweep.spec is None:
            continue
        variants[name] = {
            v.name: scenario_hash(v.scenario) if v.scenario else f"error: {v.error}"
            for v in sweep.variants
        }
    return {"scenarios": scenarios, "extra": extra, "variants": variants}


@pytest.fixture(scope="module")
def pinned() -> dict:
    return _PINNED


@pytest.fixture(scope="module")
def current() -> dict:
    return current_hashes()


def test_every_shipped_scenario_is_pinned(pinned, current):
    assert sorted(current["scenarios"]) == sorted(pinned["scenarios"])
    assert sorted(current["variants"]) == sorted(pinned["variants"])


@pytest.mark.parametrize("name", sorted(_PINNED["scenarios"]))
def test_scenario_hash_unchanged(name, pinned, current):
    assert current["scenarios"][name] == pinned["scenarios"][name]


@pytest.mark.parametrize("name", sorted(EXTRA))
def test_extra_scenario_hash_unchanged(name, pinned, current):
    """step_pitch with the overrides of :data:`EXTRA` (what no shipped file reaches)."""
    assert current["extra"][name] == pinned["extra"][name]


@pytest.mark.parametrize("name", sorted(_PINNED["variants"]))
def test_sweep_variant_hashes_unchanged(name, pinned, current):
    want, got = pinned["variants"][name], current["variants"][name]
    assert list(got) == list(want)  # the same variants, in the same order
    changed = [v for v in want if got[v] != want[v]]
    assert not changed, f"{name}: {len(changed)} of {len(want)} changed, e.g. {changed[:3]}"


@pytest.mark.parametrize("name", ["step_pitch", "fault_supply_drop", "cue_braking"])
def test_the_typed_model_is_the_resolved_scenario(name):
    """``scenario_model`` of a resolved scenario gives it back (the typed view of the same
    data), its blocks as attributes."""
    resolved = load_scenario(name).model_dump()  # the resolved document
    model = scenario_model(resolved)
    assert model.model_dump() == resolved
    assert model.controller.outer.gains == resolved["controller"]["outer"]["gains"]
    assert model.duration_s == resolved["duration_s"]
    assert [f.type for f in model.faults] == [f["type"] for f in resolved["faults"]]


def test_a_recording_is_hashed_by_its_contents(tmp_path):
    """The same telemetry copied elsewhere hashes the same; one changed sample does
    not (``batch --resume`` must not keep a run of an edited recording)."""
    shipped = Path(load_scenario("cue_braking").setpoint.cueing.telemetry)
    copy_ = tmp_path / shipped.name
    copy_.write_bytes(shipped.read_bytes())
    here = load_scenario("cue_braking")
    there = load_scenario("cue_braking", [f"setpoint.cueing.telemetry={copy_}"])
    assert here.setpoint.cueing.telemetry != there.setpoint.cueing.telemetry
    assert scenario_hash(here) == scenario_hash(there)
    lines = copy_.read_text().splitlines()
    cells = lines[-1].split(",")
    cells[1] = repr(float(cells[1]) + 0.01)
    copy_.write_text("\n".join([*lines[:-1], ",".join(cells)]) + "\n")
    edited = load_scenario("cue_braking", [f"setpoint.cueing.telemetry={copy_}"])
    assert scenario_hash(edited) != scenario_hash(here)


def test_hash_sees_a_change():
    """The pins are not blind: one changed default value changes the hash."""
    a = load_scenario("step_pitch")
    b = load_scenario("step_pitch", ["controller.outer.pi_zero=0.25"])
    c = load_scenario("step_pitch", ["controller.outer.period_ms=60"])  # the default: same
    assert scenario_hash(a) != scenario_hash(b)
    assert scenario_hash(a) == scenario_hash(c)


if __name__ == "__main__":
    if "--write" not in sys.argv[1:]:
        sys.exit("usage: python tests/test_scenario_hashes.py --write")
    DATA.write_text(json.dumps(current_hashes(), indent=1, sort_keys=False) + "\n")
    print(f"wrote {DATA}")
