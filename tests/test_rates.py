"""simpro_mj.core.rates: every rate an integer multiple of the timestep, one check."""

from __future__ import annotations

import math

import pytest

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.rates import PHYSICS_DT_S, steps_per_period, whole_steps


@pytest.mark.parametrize(
    ("period_s", "steps"),
    [(1e-3, 1), (0.003, 3), (0.02, 20), (10.0, 10000), (0.1 + 0.2, 300)],  # 0.1+0.2: float noise
)
def test_whole_periods_give_their_steps(period_s, steps):
    assert whole_steps(period_s, PHYSICS_DT_S) == steps


@pytest.mark.parametrize("period_s", [0.0, -0.002, 0.0025, 0.0005, math.inf, math.nan, None])
def test_other_periods_have_none(period_s):
    assert whole_steps(period_s) is None


def test_the_error_names_the_field_and_the_allowed_values():
    with pytest.raises(UserInputError) as err:
        steps_per_period(2.5, 1e-3, "sensors.imu.rate_ms")
    assert str(err.value) == (
        "invalid value at sensors.imu.rate_ms: 2.5; allowed: a positive integer multiple "
        "of the 1 ms physics step"
    )


def test_the_plant_and_the_scenario_refuse_the_same_rate():
    """The sensors built directly (the Python API, no scenario) refuse what the
    scenario refuses, with the same words up to the scenario's upper bound."""
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.plant.sensors import DEFAULT_SENSORS, SensorConfig

    tree = {k: dict(v) for k, v in DEFAULT_SENSORS.items()}
    tree["imu"]["rate_ms"] = 2.5
    with pytest.raises(UserInputError) as plant:
        SensorConfig.from_tree(tree, 1e-3)
    with pytest.raises(UserInputError) as config:
        load_scenario("step_pitch", ["sensors.imu.rate_ms=2.5"])
    assert str(config.value).startswith(str(plant.value))


def test_the_potentiometer_bits_are_one_range():
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.plant.sensors import DEFAULT_SENSORS, POT_BITS, SensorConfig

    for bits in (POT_BITS[0] - 1, POT_BITS[1] + 1):
        tree = {k: dict(v) for k, v in DEFAULT_SENSORS.items()}
        tree["potentiometer"]["bits"] = bits
        with pytest.raises(UserInputError, match=r"allowed: an integer 4\.\.24") as plant:
            SensorConfig.from_tree(tree, 1e-3)
        with pytest.raises(UserInputError) as config:
            load_scenario("step_pitch", [f"sensors.potentiometer.bits={bits}"])
        assert str(config.value) == str(plant.value)
    for bits in POT_BITS:
        load_scenario("step_pitch", [f"sensors.potentiometer.bits={bits}"])
