"""Fault schedule (simpro_mj.plant.faults) on arrays: events, hooks, validation.

The end-to-end runs (faults acting in the co-simulation) are in
``tests/test_faults_sim.py``.
"""

import math

import numpy as np
import pytest

from simpro_mj.config.scenario import load_scenario, resolve, resolve_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.plant.faults import FLAG_BITS, NEVER, FaultSchedule, flag_series

DT = 1e-3
PA = 101325.0
PS = 6e5 + PA


def _schedule(faults, duration=10.0, seed=1):
    sc = resolve({"duration_s": duration, "faults": faults, "seed": seed}, default_name="t")
    return sc, FaultSchedule(sc, DT)


def _run_events(sched, n):
    """Drive the schedule like the loop does; yield (k, changes or None)."""
    for k in range(n + 1):
        ch = sched.at_event(k) if k == sched.next_event else None
        yield k, ch


def test_no_faults_costs_nothing():
    _, s = _schedule([])
    assert s.events.size == 0 and s.next_event == NEVER
    assert not s.valve_active and not s.sensor_active and s.flags == 0


def test_supply_drop_step_and_ramp():
    _, s = _schedule([{"type": "supply_drop", "time_s": 2.0, "pressure_bar_gauge": 1.5}])
    assert s.supply_pa == pytest.approx(PS)
    assert list(s.events) == [2000]
    ch = s.at_event(2000)
    assert ch.supply_pa == pytest.approx(1.5e5 + PA)
    assert ch.flags == FLAG_BITS["supply_drop"] and s.next_event == NEVER

    _, s = _schedule(
        [{"type": "supply_drop", "time_s": 1.0, "pressure_bar_gauge": 2.0, "ramp_s": 0.5}]
    )
    supply = {}
    for k, ch in _run_events(s, 3000):
        if ch is not None and ch.supply_pa is not None:
            supply[k] = ch.supply_pa
    assert min(supply) == 1001 and max(supply) == 1500  # the ramp starts at 1000
    assert supply[1250] == pytest.approx(PS + 0.5 * (2e5 + PA - PS))
    assert supply[1500] == pytest.approx(2e5 + PA)
    assert np.all(np.diff([supply[k] for k in sorted(supply)]) <= 0)


def test_valve_stuck_window_and_copy():
    _, s = _schedule(
        [{"type": "valve_stuck", "time_s": 1.0, "end_s": 2.0, "leg": 2, "voltage_v": 6.5}]
    )
    assert list(s.events) == [1000, 2000]
    ch = s.at_event(1000)
    assert ch.valves and s.valve_active and ch.flags == FLAG_BITS["valve_stuck"]
    u = np.array([5.0, 4.0, 3.0])
    out = s.apply_valves(u)
    assert list(out) == [5.0, 6.5, 3.0] and list(u) == [5.0, 4.0, 3.0]
    ch = s.at_event(2000)
    assert ch.valves and not s.valve_active and ch.flags == 0


def test_sensor_frozen_holds_the_reading_at_its_start():
    _, s = _schedule([{"type": "sensor_frozen", "time_s": 0.5, "sensor": "imu", "axis": "pitch"}])
    s.at_event(500)
    q = np.array([0.25, 0.25, 0.25])
    for k in range(500, 520):
        pose = np.array([0.01 * k, 0.02 * k, 1.2 + k])
        qo, po = s.apply_sensors(k, q, pose)
        assert po[1] == pytest.approx(0.02 * 500)  # pitch frozen
        assert po[0] == pose[0] and po[2] == pose[2] and np.array_equal(qo, q)
        assert po is not pose


def test_sensor_bias_units_and_channels():
    _, s = _schedule(
        [
            {"type": "sensor_bias", "time_s": 0.0, "sensor": "imu", "bias_deg": 0.5},
            {
                "type": "sensor_bias",
                "time_s": 0.0,
                "sensor": "potentiometer",
                "leg": 3,
                "bias_mm": 2.0,
            },  # fmt: skip
            {"type": "sensor_bias", "time_s": 0.0, "sensor": "height_encoder", "bias_mm": -1.0},
        ]
    )
    s.at_event(0)
    q, pose = np.array([0.1, 0.2, 0.3]), np.array([0.0, 0.0, 1.265])
    qo, po = s.apply_sensors(0, q, pose)
    np.testing.assert_allclose(qo - q, [0, 0, 2e-3], atol=1e-15)
    np.testing.assert_allclose(po - pose, [math.radians(0.5), math.radians(0.5), -1e-3])


def test_potentiometer_failure_reads_a_rail():
    _, s = _schedule(
        [
            {"type": "potentiometer_failure", "time_s": 0.1, "leg": 1},
            {"type": "potentiometer_failure", "time_s": 0.1, "leg": 2, "mode": "short"},
        ]
    )
    ch = s.at_event(100)
    assert ch.flags == FLAG_BITS["potentiometer_failure"] and s.sensor_active
    qo, _ = s.apply_sensors(100, np.array([0.25, 0.25, 0.25]), np.zeros(3))
    assert qo[0] == 0.0  # open: 0 V = 0 mm
    # short: the 10 V feed, clipped to the 14-bit ADC's top code (10 V - 1 LSB)
    assert qo[1] == pytest.approx((10.0 - 20.0 / 2**14) / 0.02 * 1e-3)
    assert qo[2] == 0.25


def test_dropout_holds_last_delivered_and_is_seeded():
    faults = [
        {
            "type": "sensor_dropout",
            "time_s": 1.0,
            "end_s": 3.0,
            "sensor": "height_encoder",
            "probability": 0.3,
        },  # fmt: skip
    ]

    def run(seed):
        _, s = _schedule(faults, seed=seed)
        out, held = [], 0
        for k, _ch in _run_events(s, 3500):
            h = 1.0 + 1e-3 * k
            if s.sensor_active:
                _, po = s.apply_sensors(k, np.zeros(3), np.array([0.0, 0.0, h]))
                held += po[2] != h
                out.append(po[2])
            else:
                out.append(h)
        return np.array(out), held

    a, held = run(1)
    b, _ = run(1)
    c, _ = run(2)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert 0.2 * 2000 < held < 0.45 * 2000  # about 30 % of the 2 s window
    assert np.all(np.diff(a) >= 0)  # a held value is an earlier reading, never a new one
    assert np.array_equal(a[3000:], 1.0 + 1e-3 * np.arange(3000, 3501))  # ended


def test_imu_dropout_decides_at_the_imu_rate():
    faults = [{"type": "sensor_dropout", "time_s": 0.0, "sensor": "imu", "probability": 0.5}]
    _, s = _schedule(faults, duration=2.0)
    s.at_event(0)
    prev = None
    for k in range(2000):
        _, po = s.apply_sensors(k, np.zeros(3), np.array([k, k, 0.0]))
        if k % 5 and prev is not None:  # between IMU samples the state carries over
            assert (po[0] == k) == (prev[0] == k - 1)
        prev = po


def test_flags_combine_and_flag_series_matches():
    faults = [
        {"type": "valve_stuck", "time_s": 1.0, "end_s": 2.0, "leg": 1, "voltage_v": 5.0},
        {"type": "sensor_bias", "time_s": 1.5, "sensor": "imu", "bias_deg": 0.1},
    ]
    sc, s = _schedule(faults, duration=3.0)
    got = np.zeros(3001, dtype=int)
    flags = 0
    for k, ch in _run_events(s, 3000):
        if ch is not None:
            flags = ch.flags
        got[k] = flags
    assert got[1600] == FLAG_BITS["valve_stuck"] | FLAG_BITS["sensor_bias"]
    np.testing.assert_array_equal(got, flag_series(sc, np.arange(3001) * DT))


BAD_FAULTS = [
    ({"type": "leak", "time_s": 1}, "faults[0].type", "supply_drop"),
    ({"type": "supply_drop", "time_s": 1}, "faults[0].pressure_bar_gauge", "missing"),
    ({"type": "supply_drop", "time_s": 1, "pressure_bar_gauge": 6.5}, "pressure_bar_gauge", "< "),
    ({"type": "supply_drop", "time_s": 1, "pressure_bar_gauge": -1}, "pressure_bar_gauge", "0"),
    ({"type": "valve_stuck", "time_s": 1, "leg": 0, "voltage_v": 5}, "faults[0].leg", "1, 2 or 3"),
    ({"type": "valve_stuck", "time_s": 1, "leg": 1, "voltage_v": 11}, "voltage_v", "0..10 V"),
    ({"type": "valve_stuck", "time_s": 99, "leg": 1, "voltage_v": 5}, "time_s", "duration_s"),
    ({"type": "valve_stuck", "time_s": 2, "end_s": 1, "leg": 1, "voltage_v": 5}, "end_s", "> "),
    ({"type": "sensor_frozen", "time_s": 1, "sensor": "gps"}, "faults[0].sensor", "imu"),
    ({"type": "sensor_frozen", "time_s": 1, "sensor": "imu", "leg": 1}, "faults[0].leg", "null"),
    ({"type": "sensor_bias", "time_s": 1, "sensor": "imu"}, "faults[0].bias_deg", "missing"),
    ({"type": "sensor_bias", "time_s": 1, "sensor": "imu", "bias_mm": 1}, "bias_mm", "bias_deg"),
    ({"type": "sensor_dropout", "time_s": 1, "sensor": "imu", "probability": 0}, "probability", ""),
    ({"type": "potentiometer_failure", "time_s": 1, "leg": 1, "mode": "fried"}, "mode", "open"),
    ({"type": "supply_drop", "time_s": 1, "pressure_bar_gauge": 1, "ramp": 1}, "ramp", "ramp_s"),
]


@pytest.mark.parametrize("fault, field, word", BAD_FAULTS, ids=[b[1] for b in BAD_FAULTS])
def test_bad_faults_name_the_field(fault, field, word):
    with pytest.raises(UserInputError) as info:
        resolve_scenario({"duration_s": 10.0, "faults": [fault]}, default_name="t")
    msg = str(info.value)
    assert field in msg and word in msg and "\n" not in msg


def test_faults_resolve_with_every_key_and_ship_an_example():
    sc = load_scenario("fault_supply_drop").model_dump()  # the resolved document
    (f,) = [f for f in sc["faults"] if f["type"] == "supply_drop"]
    assert set(f) == {"type", "time_s", "pressure_bar_gauge", "ramp_s"}
    assert load_scenario("step_pitch").faults == []
