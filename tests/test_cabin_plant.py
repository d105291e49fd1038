"""The heavy cabin's plant: seal friction (breakaway, Stribeck, Coulomb, viscous).

Numbers are those of the ``heavy_cabin`` preset's DNC-125 seals: breakaway
250 N, Coulomb 150 N, Stribeck velocity 10 mm/s, viscous 300 N s/m,
regularising velocity 3 mm/s (``docs/paper-notes.md``, seal friction). Both
friction models: ``stick`` (MuJoCo's dry friction carries the breakaway, the
step the rest of the curve) and ``regularised`` (the whole curve as a tanh).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from simpro_mj.core.errors import UserInputError
from simpro_mj.plant.friction import seal_friction
from simpro_mj.plant.pneumatics.nonlinear import NonlinearActuators
from simpro_mj.plant.pneumatics.params import PneumaticParams

FS, FC, VS, BETA, VR = 250.0, 150.0, 0.010, 300.0, 0.003
DT = 1e-3


def test_friction_is_zero_at_rest_and_odd():
    assert seal_friction(0.0, FS, FC, VS, BETA, VR) == 0.0
    for v in (1e-4, 2e-3, 0.01, 0.3):
        assert seal_friction(-v, FS, FC, VS, BETA, VR) == -seal_friction(v, FS, FC, VS, BETA, VR)


def test_stribeck_curve():
    """With a vanishing regularisation the law is the Stribeck curve itself:
    F_S just above rest, F_C + (F_S - F_C)/e + β v_S at v_S, F_C + β v far above."""
    vr = 1e-9
    assert seal_friction(1e-6, FS, FC, VS, BETA, vr) == pytest.approx(FS, abs=1e-3)
    assert seal_friction(VS, FS, FC, VS, BETA, vr) == pytest.approx(
        150.0 + 100.0 / math.e + 3.0, rel=1e-12
    )
    # 10 v_S: the peak has decayed to e^-100
    assert seal_friction(0.1, FS, FC, VS, BETA, vr) == pytest.approx(150.0 + 30.0, rel=1e-12)
    # between the peak and the Coulomb level the curve falls (negative damping) ...
    f = [seal_friction(v, FS, FC, VS, BETA, vr) for v in (0.001, 0.005, 0.01, 0.02)]
    assert f[0] > f[1] > f[2] > f[3]
    # ... and with the regularisation it rises from 0 through the peak below ~2 v_r
    assert seal_friction(VR, FS, FC, VS, BETA, VR) == pytest.approx(
        (FC + (FS - FC) * math.exp(-0.09)) * math.tanh(1.0) + BETA * VR, rel=1e-12
    )


def test_without_breakaway_the_law_is_the_smoothed_coulomb_and_viscous_one():
    for v in (-0.2, -0.004, 0.0007, 0.05):
        want = FC * math.tanh(v / 0.005) + BETA * v
        assert seal_friction(v, FC, FC, VS, BETA, 0.005) == pytest.approx(want, rel=1e-15)


def _slide(force, mass=150.0, seconds=3.0):
    """A mass pushed by ``force`` against the seals, stepped as the co-simulation
    steps a slide: the friction of the present velocity applied over the next 1 ms."""
    x = v = 0.0
    for _ in range(int(round(seconds / DT))):
        v += (force - seal_friction(v, FS, FC, VS, BETA, VR)) / mass * DT
        x += v * DT
    return x, v


def test_below_breakaway_the_seals_hold_the_leg():
    """200 N (0.8 F_S) from rest: the leg creeps at the speed where the seals
    carry 200 N, about v_r artanh(0.8) = 3.3 mm/s (3.6 with the peak's decay
    at that speed), not the 1.33 m/s^2 of a free 150 kg; 300 N (1.2 F_S) breaks
    it away towards (F - F_C)/β = 0.5 m/s."""
    lo, hi = 0.0, 0.006  # creep speed: F_f(v) = 200 N (the law rises to 214 N at 6 mm/s)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if seal_friction(mid, FS, FC, VS, BETA, VR) < 200.0 else (lo, mid)
    assert VR * math.atanh(0.8) < lo < 4e-3
    x, v = _slide(200.0)
    assert v == pytest.approx(lo, rel=1e-3)
    assert x < 3.0 * 4e-3  # under 12 mm in 3 s (free: 6 m)
    x, v = _slide(300.0)
    # v(t) = 0.5 (1 - exp(-β t / m)) past the peak: 0.5 (1 - e^-6) at 3 s
    assert v == pytest.approx(0.5 * (1 - math.exp(-6.0)), rel=0.02)


def test_the_actuators_subtract_the_seal_friction():
    tree = {
        "cylinder": {
            "coulomb_friction_n": FC,
            "breakaway_friction_n": [FS, FS + 10.0, FS + 20.0],
            "stribeck_velocity_mm_per_s": 10.0,
            "viscous_friction_n_s_per_m": BETA,
            "coulomb_smoothing_mm_per_s": 3.0,
            "friction_model": "regularised",
        }
    }
    act = NonlinearActuators(tree)
    f0 = act.force_now(np.zeros(3)).copy()
    v = np.array([0.004, -0.01, 0.2])
    got = f0 - act.force_now(v)
    want = [seal_friction(v[i], FS + 10.0 * i, FC, VS, BETA, VR) for i in range(3)]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    # one step at rest: the pressures' force only (friction 0 at rest)
    act.reset(np.full(3, 0.25), np.zeros(3))
    np.testing.assert_array_equal(
        act.step([5.0] * 3, [0.25] * 3, [0.0] * 3, DT), act.force_now(np.zeros(3))
    )


def test_breakaway_below_coulomb_is_refused():
    with pytest.raises(UserInputError, match=r"breakaway_friction_n.*coulomb_friction_n"):
        PneumaticParams.from_tree(
            {"cylinder": {"coulomb_friction_n": 150, "breakaway_friction_n": [250, 100, 250]}}
        )
    P = PneumaticParams.from_tree({"cylinder": {"coulomb_friction_n": [1, 2, 3]}})
    np.testing.assert_array_equal(P.breakaway, [1.0, 2.0, 3.0])  # null: no Stribeck peak


def test_breakaway_ratio_scales_each_legs_coulomb_force():
    """A sweep over the Coulomb force draws whole seals: 5/3 of 150 N is the
    preset's 250 N breakaway, and a ratio beside an explicit breakaway is refused."""
    P = PneumaticParams.from_tree(
        {"cylinder": {"coulomb_friction_n": [150, 60, 0], "breakaway_ratio": 5 / 3}}
    )
    np.testing.assert_allclose(P.breakaway, [250.0, 100.0, 0.0], rtol=1e-15)
    with pytest.raises(UserInputError, match=r"breakaway_ratio.*set one of the two"):
        PneumaticParams.from_tree(
            {"cylinder": {"breakaway_friction_n": 250, "breakaway_ratio": 1.5}}
        )
    with pytest.raises(UserInputError, match=r"breakaway_ratio"):
        PneumaticParams.from_tree({"cylinder": {"breakaway_ratio": 0.5}})


# ---------------------------------------------------------------- the heavy cabin preset


def test_heavy_cabin_resolves_to_a_cabin_with_its_driver_and_real_seals():
    """As a run writes it (scenario.yaml is the resolved tree): a payload of at
    least 150 kg, at least 50 N of Coulomb friction on every leg, a breakaway
    above it, the catalogue valve; MuJoCo's payload body carries that mass and
    the principal moments of the given inertia tensor."""
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.plant.model import load_model

    sc = load_scenario("step_pitch", ["plant.preset=heavy_cabin"]).model_dump()
    payload = sc["plant"]["payload"]
    assert payload["mass_kg"] >= 150.0
    cyl = sc["actuator"]["pneumatics"]["cylinder"]
    assert min(cyl["coulomb_friction_n"]) >= 50.0
    fs, fc = cyl["breakaway_friction_n"], cyl["coulomb_friction_n"]
    assert all(b > c for b, c in zip(fs, fc, strict=True))
    assert sc["actuator"]["pneumatics"]["valve"]["sonic_conductance_dm3_per_s_bar"] == 7.87
    m = load_model({k: v for k, v in sc["plant"].items() if k != "preset"})
    body = m.body("payload").id
    assert m.body_mass[body] == pytest.approx(payload["mass_kg"])
    ixx, iyy, izz, ixy, ixz, iyz = payload["inertia_kg_m2"]
    tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    np.testing.assert_allclose(np.sort(m.body_inertia[body]), np.linalg.eigvalsh(tensor), rtol=1e-9)
    # the centre of mass where the preset puts it (the body's frame origin)
    np.testing.assert_allclose(m.body_pos[body], np.asarray(payload["com_mm"]) * 1e-3)
    np.testing.assert_allclose(m.body_ipos[body], 0.0)


@pytest.mark.parametrize(
    "value",
    [[1, 1, 5, 0, 0, 0], [10, 10, 10, 20, 0, 0], [1, 2, 3], "heavy"],
    ids=["triangle inequality", "not positive definite", "3 numbers", "text"],
)
def test_an_impossible_inertia_is_one_line_naming_the_key(value):
    from simpro_mj.config.scenario import load_scenario

    with pytest.raises(UserInputError, match=r"plant\.payload\.inertia_kg_m2") as e:
        load_scenario("step_pitch", [f"plant.payload.inertia_kg_m2={value}"])
    assert "\n" not in str(e.value)


# ---------------------------------------------------------------- sensor errors


def test_accelerometer_tilt_reads_the_platforms_own_acceleration():
    """At rest the accelerometer's tilt is the true one; accelerating level at a
    it reads pitch -atan(a_x/g) and roll atan(a_y/g) (the specific force leans)."""
    from simpro_mj.plant.sensor_errors import G, accel_tilt

    for roll, pitch in ((0.0, 0.0), (0.05, -0.1), (-0.3, 0.2)):
        r, p = accel_tilt(0.0, 0.0, 0.0, roll, pitch)
        assert r == pytest.approx(roll, abs=1e-15) and p == pytest.approx(pitch, abs=1e-15)
    r, p = accel_tilt(1.0, 0.0, 0.0, 0.0, 0.0)
    assert r == 0.0 and p == pytest.approx(-math.atan(1.0 / G), rel=1e-14)  # -5.82 deg
    r, p = accel_tilt(0.0, -0.5, 0.0, 0.0, 0.0)
    assert p == pytest.approx(0.0, abs=1e-15) and r == pytest.approx(math.atan(-0.5 / G))
    # vertical acceleration only scales the specific force: no tilt error
    r, p = accel_tilt(0.0, 0.0, 3.0, 0.02, -0.04)
    assert r == pytest.approx(0.02, abs=1e-15) and p == pytest.approx(-0.04, abs=1e-15)


def test_potentiometer_bow_has_the_datasheet_linearity():
    """0.1 % of a 500 mm track: +0.5 mm at mid-stroke, -0.5 mm at both ends, no
    more anywhere (the independent linearity)."""
    from simpro_mj.plant.sensor_errors import pot_nonlinearity

    fs, nu = 0.5, 1e-3
    assert pot_nonlinearity(0.25, fs, nu) == pytest.approx(5e-4, rel=1e-12)
    assert pot_nonlinearity(0.0, fs, nu) == pytest.approx(-5e-4, rel=1e-12)
    assert pot_nonlinearity(0.5, fs, nu) == pytest.approx(-5e-4, rel=1e-12)
    e = [pot_nonlinearity(q, fs, nu) for q in np.linspace(0, fs, 1001)]
    assert max(abs(x) for x in e) == pytest.approx(5e-4, rel=1e-12)


def test_noise_density_and_bias_walk_per_sample():
    from simpro_mj.plant.sensor_errors import bias_walk_sigma, noise_sigma

    # 200 Hz samples: the Nyquist band is 100 Hz, so sigma = density x 10
    assert noise_sigma(0.01, 0.005) == pytest.approx(0.1, rel=1e-14)
    # a walk of w per sqrt(s), sampled every 5 ms: w sqrt(0.005) per sample
    assert bias_walk_sigma(0.01, 0.005) == pytest.approx(0.01 * math.sqrt(0.005), rel=1e-14)


def _sensor_arrays(tree_changes):
    """The step's sensor constants for the default sensors with ``tree_changes``."""
    from simpro_mj.plant import step_functions as ps
    from simpro_mj.plant.sensors import DEFAULT_SENSORS, SensorConfig

    tree = {k: dict(v) for k, v in DEFAULT_SENSORS.items()}
    for key, value in tree_changes.items():
        group, name = key.split(".")
        tree[group][name] = value
    return SensorConfig.from_tree(tree, DT).step_constants, np.zeros(ps.SS.LEN)


def _walk_end_deg(seed):
    """The IMU's reading after 4 s of a bias walk of 0.02 deg/sqrt(s), no noise, at rest."""
    from simpro_mj.plant import step_functions as ps

    sc, ss = _sensor_arrays({"imu.bias_walk_deg_per_sqrt_s": 0.02, "imu.noise_deg": 0.0})
    walk = np.random.default_rng(seed).spawn(1)[0].standard_normal((4001, 2))
    noise, qm, pm, m = np.zeros(6), np.zeros(3), np.zeros(3), 0
    q, pose = np.full(3, 0.25), np.array([0.0, 0.0, 1.2])
    for k in range(4001):
        m += ps.sample_sensors(k, k == 0, q, pose, None, noise, walk[m], sc, ss, qm, pm)
    return [math.degrees(pm[0]), math.degrees(pm[1])]


def test_bias_walk_grows_as_its_density_says():
    """0.02 deg/sqrt(s) over 4 s: the bias's spread across 60 seeds (two axes) is
    0.02 sqrt(4) = 0.04 deg (within the 1/sqrt(120) sampling error); the other
    noise draws are those of a run without the walk (the walk's generator is
    spawned from the scenario's)."""
    ends = [v for seed in range(60) for v in _walk_end_deg(seed)]
    assert float(np.std(ends)) == pytest.approx(0.04, rel=0.2)
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.sim.build import Build

    sims = [
        Build(load_scenario("step_pitch", ["duration_s=0.1", *sets])).simulation()
        for sets in (["sensors.imu.bias_walk_deg_per_sqrt_s=0.02"], [])
    ]
    for sim in sims:
        sim._initial_state()
    assert sims[0].walk_rng is not None and sims[1].walk_rng is None
    assert np.array_equal(sims[0].noise.rows, sims[1].noise.rows)
    assert sims[0].rng.bit_generator.state == sims[1].rng.bit_generator.state


def test_sensor_errors_compiled_equal_interpreted():
    """Every error on (the walk, the accelerometer from the site's positions, the
    bow, the density): the compiled sensor step's readings are the interpreted
    one's, bit for bit."""
    pytest.importorskip("numba")
    from simpro_mj.plant import step_functions as ps
    from simpro_mj.sim import step

    errors = {
        "imu.bias_walk_deg_per_sqrt_s": 0.01,
        "imu.accel_crossover_hz": 2.0,
        "imu.noise_density_deg_per_sqrt_hz": 0.002,
        "imu.bias_deg": [0.1, -0.2],
        "potentiometer.nonlinearity_pct_fs": 0.1,
    }
    sc, ss_a = _sensor_arrays(errors)
    ss_b = ss_a.copy()
    compiled = step.compiled().sample_sensors
    rng = np.random.default_rng(2)
    noise, walk = rng.standard_normal((3000, 6)), rng.standard_normal((3000, 2))
    out = [np.zeros(3) for _ in range(4)]
    ma = mb = 0
    for k in range(3000):
        t = k * DT
        q = 0.25 + 0.05 * np.sin([t, 2 * t, 3 * t])
        pose = np.array([0.05 * math.sin(2 * t), 0.04 * math.cos(3 * t), 1.2 + 0.01 * math.sin(t)])
        site = np.array([0.84 + 0.01 * math.sin(5 * t), 0.0, pose[2] + 1e-4 * rng.normal()])
        force = k % 101 == 0
        ma += ps.sample_sensors(k, force, q, pose, site, noise[k], walk[ma], sc, ss_a, *out[:2])
        mb += compiled(k, force, q, pose, site, noise[k], walk[mb], sc, ss_b, *out[2:])
        assert np.array_equal(out[0], out[2]) and np.array_equal(out[1], out[3]), k
    samples = sum(1 for k in range(3000) if k % 5 == 0 or k % 101 == 0)  # 200 Hz + forced
    assert ma == mb == samples and np.array_equal(ss_a, ss_b)
    assert ss_a[ps.SS.walk] != 0.0 and ss_a[ps.SS.hn] == 2.0  # the walk and the history ran


def _pitch_error_deg(sets):
    import simpro_mj as s

    r = s.run("step_pitch", {"duration_s": 12.0, **sets})
    c = r.columns
    w = c["time_s"] >= 9.0
    return float(np.mean(c["pitch_ref_rad"][w] - c["pitch_rad"][w])) * 180 / math.pi


def test_an_imu_bias_shifts_the_converged_pitch_by_itself():
    """The task-space loop drives the measured pitch to the set-point: with the IMU
    reading 0.3 deg high the true pitch settles 0.3 deg low (within the
    0.0011 deg sensor floor and the shipped run's 0.0006 deg)."""
    base = _pitch_error_deg({})
    biased = _pitch_error_deg({"sensors.imu.bias_deg": [0.0, 0.3]})
    assert biased - base == pytest.approx(0.3, abs=0.003)


# ---------------------------------------------------------------- seals that stick


def test_stick_model_explicit_part_completes_the_stribeck_curve():
    """Under ``stick`` MuJoCo's dry friction carries F_S against the motion; the
    step's explicit part takes back the Stribeck drop, so that the sum is the
    curve itself: F_S just above rest, F_C + (F_S - F_C)/e + β v_S at v_S,
    F_C + β v far above; 0 at rest and odd."""
    assert seal_friction(0.0, FS, FC, VS, BETA, 0.0) == 0.0
    for v, want in ((1e-6, FS), (VS, FC + (FS - FC) / math.e + BETA * VS), (0.1, FC + 30.0)):
        total = FS + seal_friction(v, FS, FC, VS, BETA, 0.0)
        assert total == pytest.approx(want, abs=1e-3)
        assert seal_friction(-v, FS, FC, VS, BETA, 0.0) == -seal_friction(v, FS, FC, VS, BETA, 0.0)


def test_the_stick_model_sets_each_slides_dry_friction_to_its_breakaway():
    from simpro_mj.plant.model import PlantIndex, load_model
    from simpro_mj.plant.platform import Platform

    tree = {"cylinder": {"coulomb_friction_n": FC, "breakaway_friction_n": [FS, 260.0, 270.0]}}
    model = load_model()
    dofs = PlantIndex.of(model).slide_dof
    Platform(model, NonlinearActuators(tree))
    np.testing.assert_array_equal(model.dof_frictionloss[dofs], [FS, 260.0, 270.0])
    tree["cylinder"]["friction_model"] = "regularised"
    Platform(model, NonlinearActuators(tree))
    np.testing.assert_array_equal(model.dof_frictionloss[dofs], [0.0, 0.0, 0.0])


def test_the_stick_constraints_softness_is_the_mjcfs_unless_the_scenario_moves_it():
    """``stick_time_constant_ms`` / ``stick_impedance`` default to the MJCF's own
    solreffriction 2 ms and solimpfriction 0.9999 (a shipped run is unchanged) and,
    when set, are what MuJoCo's dry-friction rows of the three slides use."""
    from simpro_mj.plant.model import PlantIndex, load_model
    from simpro_mj.plant.platform import Platform

    model = load_model()
    dofs = PlantIndex.of(model).slide_dof
    np.testing.assert_array_equal(model.dof_solref[dofs, 0], [0.002] * 3)
    np.testing.assert_array_equal(model.dof_solimp[dofs, :2], [[0.9999, 0.9999]] * 3)
    tree = {"cylinder": {"coulomb_friction_n": FC, "breakaway_friction_n": FS}}
    Platform(model, NonlinearActuators(tree))
    np.testing.assert_array_equal(model.dof_solref[dofs, 0], [0.002] * 3)
    np.testing.assert_array_equal(model.dof_solimp[dofs, :2], [[0.9999, 0.9999]] * 3)
    tree["cylinder"].update(stick_time_constant_ms=4.0, stick_impedance=0.9998)
    Platform(model, NonlinearActuators(tree))
    np.testing.assert_allclose(model.dof_solref[dofs, 0], [0.004] * 3, rtol=1e-12)
    np.testing.assert_array_equal(model.dof_solimp[dofs, :2], [[0.9998, 0.9998]] * 3)
    tree["cylinder"]["stick_time_constant_ms"] = 1.0  # under two 1 ms steps
    with pytest.raises(ValueError, match="stick_time_constant_ms"):
        NonlinearActuators(tree)


@pytest.mark.parametrize("model_name, still", [("stick", True), ("regularised", False)])
def test_a_leg_loaded_below_breakaway_sticks_only_with_the_stick_model(model_name, still):
    """The platform at rest, leg 2 at valve null pushed by 80 % of its 250 N
    breakaway for 2 s: with seals that stick it stays within 0.05 mm (not at all
    with the preset's noslip pass); the tanh law lets it slide until the air
    springs carry the load (about 200 N / 70 kN/m, near 3 mm)."""
    from simpro_mj.analysis.plant_checks import stiction
    from simpro_mj.config.scenario import resolve_scenario

    sc = resolve_scenario(
        {"plant": {"preset": "heavy_cabin"}},
        [f"actuator.pneumatics.cylinder.friction_model={model_name}"],
    )
    check = stiction(sc)
    assert check.ok is still
    if not still:
        assert check.measured > 1.0  # mm


@pytest.mark.parametrize("seals", [(150.0, 250.0), (450.0, 750.0)])
def test_a_stuck_seal_creeps_only_without_the_noslip_pass(seals):
    """Leg 1 at valve null loaded by 80 % of its breakaway for 2 s. MuJoCo's soft
    dry-friction row yields: at rest it lets a velocity (1 - d) a_0 / b through, with
    a_0 the acceleration the load alone gives the leg (about 5 kg of the chain's
    inertia on the slide), d the impedance 0.9999 and b = 2 / (d tau) = 1000 1/s:
    4-12 um/s for 200-600 N, tens of micrometres in 2 s. The noslip pass (heavy_cabin:
    10, and 5 or 20) solves the row hard: the leg does not move (below 1 nm)."""
    from simpro_mj.analysis.plant_checks import stiction
    from simpro_mj.config.scenario import resolve_scenario

    cyl = "actuator.pneumatics.cylinder"
    sets = [f"{cyl}.coulomb_friction_n={seals[0]}", f"{cyl}.breakaway_friction_n={seals[1]}"]
    moved = {}
    for n in (0, 5, 10, 20):
        sc = resolve_scenario(
            {"plant": {"preset": "heavy_cabin"}}, [*sets, f"{cyl}.stick_noslip_iterations={n}"]
        )
        moved[n] = stiction(sc, leg=0).measured * 1e3  # um
    creep = 0.8 * seals[1] / 5.0 * 1e-4 / 1000.0 * 2.0 * 1e6  # um in 2 s, the estimate
    assert creep / 2 < moved[0] < 2 * creep
    assert max(moved[5], moved[10], moved[20]) < 1e-3


def test_a_drawn_payload_mass_scales_the_cabins_inertia():
    """The preset's inertia is its 230 kg cabin's (``inertia_mass_kg``): half the mass
    is the same cabin at half the density, half every moment; an empty platform
    carries no cabin inertia (not the 230 kg cabin's at 0 kg)."""
    from simpro_mj.config.scenario import resolve_scenario
    from simpro_mj.plant.model import load_model

    def moments(mass):
        sc = resolve_scenario({"plant": {"preset": "heavy_cabin", "payload": {"mass_kg": mass}}})
        m = load_model(sc["plant"])
        return m.body_inertia[m.body("payload").id].copy()

    full, half, empty = moments(230.0), moments(115.0), moments(0.0)
    np.testing.assert_allclose(half, 0.5 * full, rtol=1e-9)
    assert np.all(empty < 1e-5 * full)


def test_the_complementary_filter_passes_the_accelerometer_below_its_crossover():
    """A sinusoidal fore-aft acceleration of the IMU site (level platform): the
    filter's roll/pitch input carries the accelerometer's tilt error low-passed at
    the crossover, |H| = 1 / sqrt(1 + (f / f_c)^2): 5 % at 2 Hz for f_c = 0.1 Hz,
    1.4 % at 7 Hz, all of a sustained one."""
    from simpro_mj.plant import step_functions as ps
    from simpro_mj.plant.sensor_errors import G

    sc, _ = _sensor_arrays({"imu.accel_crossover_hz": 0.1})
    for f_hz in (2.0, 7.0):
        ss = np.zeros(ps.SS.LEN)
        amp = 1.0  # m/s^2 of fore-aft acceleration
        peaks = []
        n = int(round(20.0 / DT))
        for k in range(n):
            t = k * DT
            x = -amp * math.sin(2 * math.pi * f_hz * t) / (2 * math.pi * f_hz) ** 2
            _, p = ps.imu_input(0.0, 0.0, np.array([x, 0.0, 1.2]), sc, ss)
            if t > 15.0:
                peaks.append(abs(p))
        want = math.atan(amp / G) / math.sqrt(1.0 + (f_hz / 0.1) ** 2)
        assert max(peaks) == pytest.approx(want, rel=0.03), f_hz
