"""Faults acting in the co-simulation, end to end.

``simpro_mj.sim.loop`` calls the hooks of :class:`simpro_mj.plant.faults.FaultSchedule`
as the module docstring of ``simpro_mj/plant/faults.py`` describes and logs the
columns ``fault_flags`` and ``supply_pa``.

Each fault runs a few seconds of a shipped scenario and checks a physical
outcome, not just that something changed.
"""

from __future__ import annotations

import numpy as np
import pytest

from simpro_mj.config.scenario import load_scenario
from simpro_mj.plant.faults import FLAG_BITS, flag_series
from simpro_mj.sim.build import simulate

PA = 101325.0


def _run(name, faults, duration, *extra):
    sc = load_scenario(name, [f"duration_s={duration}", f"faults={faults}", *extra])
    res = simulate(sc)
    assert res.status == "ok", res.reason
    c = res.columns
    for key, col in c.items():
        assert np.all(np.isfinite(col)), key
    return sc, c


def test_supply_drop_settles_on_the_lower_end_stops():
    sc = load_scenario("fault_supply_drop")
    res = simulate(sc)
    assert res.status == "ok", res.reason
    c, t = res.columns, res.columns["time_s"]
    for key, col in c.items():
        assert np.all(np.isfinite(col)), key  # pressures and forces too, at the stops
    drop = sc.faults[0]
    p_low = PA + drop.pressure_bar_gauge * 1e5
    after = t >= drop.time_s + drop.ramp_s
    np.testing.assert_allclose(c["supply_pa"][after], p_low)
    assert np.all(c["supply_pa"][t < drop.time_s] == pytest.approx(6e5 + PA))
    for i in (1, 2, 3):
        for side in ("a", "b"):
            p = c[f"p{i}{side}_pa"]
            # no clipping at the supply: a chamber above the
            # fallen supply flows back through its supply edge; physical bounds:
            # positive, never above the initial supply (the load cannot pump)
            assert np.all(p > 0.5 * PA) and np.all(p <= 6e5 + PA + 1e3), (i, side)
        q = c[f"q{i}_m"]
        last = t > t[-1] - 1.0
        # on the lower end stop (limit at 0; the soft limit lets it in a few mm)
        assert np.all(q[last] < 2e-3) and np.all(q > -10e-3), i
        assert np.ptp(q[last]) < 1e-4  # settled, not bouncing
    assert c["heave_m"][-1] < 1.265 - 0.25  # the platform came down
    np.testing.assert_array_equal(c["fault_flags"], flag_series(sc, t))


def test_valve_stuck_holds_the_voltage_and_the_leg_drifts():
    faults = "[{type: valve_stuck, time_s: 2.0, leg: 2, voltage_v: 6.5}]"
    sc, c = _run("step_pitch", faults, 4.0)
    t = c["time_s"]
    on = t >= 2.0
    assert np.all(c["u2_v"][on] == 6.5)
    assert not np.all(c["u2_v"][~on] == 6.5)
    i2 = int(np.searchsorted(t, 2.0))
    # 1.5 V above the centre: the cylinder extends whatever the controller does
    assert c["q2_m"][-1] - c["q2_m"][i2] > 0.02
    assert np.all(c["fault_flags"][on] == FLAG_BITS["valve_stuck"])


def test_sensor_frozen_repeats_one_value():
    # frozen during the rise (step at 1 s): the outer loop keeps integrating the error
    # it last saw, so the platform keeps moving
    faults = "[{type: sensor_frozen, time_s: 1.1, sensor: imu, axis: pitch}]"
    _, c = _run("step_pitch", faults, 3.0)
    on = c["time_s"] >= 1.1
    assert np.ptp(c["pitch_meas_rad"][on]) == 0.0
    assert np.ptp(c["pitch_rad"][on]) > np.radians(0.5)  # the platform kept moving
    assert np.ptp(c["roll_meas_rad"][on]) > 0.0  # roll still read


def test_sensor_bias_is_measured_minus_true():
    faults = "[{type: sensor_bias, time_s: 1.0, sensor: height_encoder, bias_mm: 2.0}]"
    _, c = _run("step_pitch", faults, 3.0)
    on = c["time_s"] >= 1.0
    diff = c["heave_meas_m"] - c["heave_m"]
    # the encoder quantises to 0.01 mm before the bias is added
    assert np.all(np.abs(diff[on] - 2e-3) <= 0.5e-5 + 1e-9)
    assert np.all(np.abs(diff[~on]) <= 0.5e-5 + 1e-9)


def test_sensor_dropout_holds_about_the_given_fraction_of_samples():
    faults = (
        "[{type: sensor_dropout, time_s: 1.0, end_s: 3.0, sensor: imu, axis: roll, "
        "probability: 0.5}]"
    )
    _, c = _run("step_pitch", faults, 4.0)
    t, roll = c["time_s"], c["roll_meas_rad"]
    k = np.rint(t / 1e-3).astype(int)
    update = (k % 5 == 0) & (k > 0)  # 200 Hz IMU samples; noise makes each one new
    repeated = np.zeros_like(update)
    repeated[1:] = roll[1:] == roll[:-1]
    window = (t >= 1.0) & (t < 3.0)
    frac_in = repeated[update & window].mean()
    frac_out = repeated[update & ~window].mean()
    assert 0.35 < frac_in < 0.65, frac_in
    assert frac_out < 0.01


def test_potentiometer_failure_reads_the_rail():
    faults = "[{type: potentiometer_failure, time_s: 1.0, leg: 3, mode: open}]"
    _, c = _run("step_pitch", faults, 3.0)
    on = c["time_s"] >= 1.0
    assert np.all(c["q3_meas_m"][on] == 0.0)  # open wiper: 0 V, read as 0 mm
    assert np.all(c["q3_meas_m"][~on] > 0.2)
    # the joint loop believes leg 3 fully retracted and drives it out at full valve
    # opening (10 V); the leg rises fast until the task-space loop, seeing the
    # platform roll and rise, pulls leg 3's set-point down to its lower limit
    # (mostly at the 10 V rail: the controller's own lead dynamics ring once
    # under a 0.25 m error step, 1325 V before the clip)
    soon = (c["time_s"] >= 1.0) & (c["time_s"] < 1.2)
    assert c["u3_v"][soon].mean() > 8.0
    k = np.searchsorted(c["time_s"], 1.5)
    assert c["q3_m"][k] - c["q3_m"][np.searchsorted(c["time_s"], 1.0)] > 0.05
