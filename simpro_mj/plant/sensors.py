"""Simulated sensors of the SIMPRO rig (paper section 5).

The rig reads, through a Humusoft MF624 board (14-bit, ±10 V ADC):

* joint potentiometers on q_i,
* an encoder for the height h,
* an IMU for roll and pitch;

:class:`SensorConfig` states how each turns MuJoCo's exact state into what
such a sensor reports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.rates import steps_per_period
from simpro_mj.plant.sensor_errors import bias_walk_sigma, noise_sigma
from simpro_mj.plant.step_functions import SC

#: Resolutions a potentiometer channel may be given (bits); the scenario checks
#: ``sensors.potentiometer.bits`` against the same range.
POT_BITS = (4, 24)
POT_BITS_TEXT = f"an integer {POT_BITS[0]}..{POT_BITS[1]}"

#: Edge-unit defaults; a scenario's ``sensors`` block overrides them.
DEFAULT_SENSORS: dict = {
    "potentiometer": {
        # MF624: 14-bit over ±10 V -> 1.22 mV per LSB
        "bits": 14,
        "range_v": 10.0,
        # 0-10 V over the 500 mm stroke (assumption: a linear potentiometer fed at 10 V)
        "volts_per_mm": 0.02,
        "noise_lsb": 0.5,  # RMS electrical noise, in LSB (assumption)
        "offset_mm": [0.0, 0.0, 0.0],  # as-built zero error of each potentiometer
        "gain_error_pct": [0.0, 0.0, 0.0],  # as-built scale error
        # independent linearity, % of full scale (the track's bow; sensor_errors)
        "nonlinearity_pct_fs": 0.0,
        "rate_ms": 1,
    },
    "height_encoder": {
        "resolution_mm": 0.01,  # linear encoder, 10 um (assumption)
        "noise_mm": 0.0,
        "rate_ms": 1,
    },
    "imu": {
        "noise_deg": 0.005,  # RMS per sample (assumption: MEMS AHRS class)
        # white noise given as a density, added to noise_deg (deg/sqrt(Hz))
        "noise_density_deg_per_sqrt_hz": 0.0,
        "bias_deg": [0.0, 0.0],  # roll, pitch
        # random walk of the bias, deg/sqrt(s), seeded by the scenario
        "bias_walk_deg_per_sqrt_s": 0.0,
        # crossover of the attitude's complementary filter, Hz: the accelerometer's tilt
        # below it, the gyro above (0: the gyro alone, the platform's own acceleration
        # unseen)
        "accel_crossover_hz": 0.0,
        "bandwidth_hz": 20.0,  # first-order output filter
        "rate_ms": 5,  # 200 Hz output
    },
}


@dataclass(frozen=True)
class SensorConfig:
    """Sensor parameters in SI, built from the edge-unit tree.

    The per-step models are :func:`simpro_mj.plant.step_functions.sample_sensors`
    (run by the co-simulation's step, :mod:`simpro_mj.sim.step`), each sensor
    sampled at its rate with zero-order hold between samples. Potentiometer i
    reports ``q_i^m = Q(g_i q_i + o_i [+ bow(q_i)] + n)`` with Q the ADC quantiser (one
    LSB = ``2 range / 2^bits`` volts) and saturation at the ADC's range; the
    controller converts with the nominal scale, so offset ``o_i`` and gain
    ``g_i`` appear as joint-space errors. The encoder reports
    ``round(h / res) res``. The IMU low-pass filters roll and pitch at its
    bandwidth, adds its bias (+ walk) and white noise, and updates every ``rate_ms``. The
    rig's further errors (:mod:`simpro_mj.plant.sensor_errors`): the track's
    non-linearity, the IMU bias's random walk, the accelerometer's share of
    the attitude. Every noise source draws from the scenario's seeded
    generator in a fixed order (:class:`simpro_mj.sim.stages.NoiseBlock`; the
    bias walk from a generator spawned from it).
    """

    pot_lsb_m: float  # one ADC count expressed as slide travel, m
    pot_noise_m: float
    pot_range_m: tuple  # measurable (min, max) slide reading, m
    pot_offset_m: np.ndarray
    pot_gain: np.ndarray  # 1 + gain error
    pot_full_scale_m: float  # the track's length, range_v / volts_per_m
    pot_nonlinearity: float  # independent linearity, fraction of full scale
    pot_every: int
    enc_res_m: float
    enc_noise_m: float
    enc_every: int
    imu_noise_rad: float
    imu_bias_rad: np.ndarray
    imu_walk_rad: float  # step of the bias's random walk per IMU sample
    imu_accel_alpha: float  # the complementary filter's 1 - exp(-2 pi f_c dt)
    imu_alpha: float  # first-order filter coefficient per physics step
    imu_every: int
    dt: float

    @classmethod
    def from_tree(cls, tree: dict, dt: float, path: str = "sensors") -> SensorConfig:
        pot, imu = tree["potentiometer"], tree["imu"]

        def every(where):
            return steps_per_period(tree[where]["rate_ms"], dt, f"{path}.{where}.rate_ms")

        def positive(where, zero_ok=False):
            """The value at ``where`` (a sensor's key; its default when absent), checked."""
            group, key = where.split(".")
            v = tree[group].get(key, DEFAULT_SENSORS[group][key])
            if not (math.isfinite(v) and (v >= 0 if zero_ok else v > 0)):
                allowed = ">= 0" if zero_ok else "> 0"
                raise UserInputError(f"invalid value at {path}.{where}: {v}; allowed: {allowed}")
            return float(v)

        bits = int(pot["bits"])
        if not POT_BITS[0] <= bits <= POT_BITS[1]:
            raise UserInputError(
                f"invalid value at {path}.potentiometer.bits: {bits}; allowed: {POT_BITS_TEXT}"
            )
        rng_v = positive("potentiometer.range_v")
        vpm = positive("potentiometer.volts_per_mm") * 1e3  # V/m
        lsb_v = 2.0 * rng_v / 2**bits
        bw = positive("imu.bandwidth_hz")
        imu_every = every("imu")
        imu_t = imu_every * dt
        sigma_imu = math.radians(positive("imu.noise_deg", True))
        density = positive("imu.noise_density_deg_per_sqrt_hz", True)
        if density > 0:
            sigma_imu = math.hypot(sigma_imu, noise_sigma(math.radians(density), imu_t))
        fc = float(imu.get("accel_crossover_hz", 0.0))
        if not 0.0 <= fc <= 0.5 / dt:
            raise UserInputError(
                f"invalid value at {path}.imu.accel_crossover_hz: {fc}; allowed: 0 (gyro "
                f"only) .. {0.5 / dt:g} Hz (the step's Nyquist frequency)"
            )
        walk = positive("imu.bias_walk_deg_per_sqrt_s", True)
        nl = positive("potentiometer.nonlinearity_pct_fs", True)
        return cls(
            pot_lsb_m=lsb_v / vpm,
            pot_noise_m=positive("potentiometer.noise_lsb", True) * lsb_v / vpm,
            pot_range_m=(-rng_v / vpm, (rng_v - lsb_v) / vpm),
            pot_offset_m=np.asarray(pot["offset_mm"], dtype=float) * 1e-3,
            pot_gain=1.0 + np.asarray(pot["gain_error_pct"], dtype=float) * 1e-2,
            pot_full_scale_m=rng_v / vpm,
            pot_nonlinearity=nl * 1e-2,
            pot_every=every("potentiometer"),
            enc_res_m=positive("height_encoder.resolution_mm", True) * 1e-3,
            enc_noise_m=positive("height_encoder.noise_mm", True) * 1e-3,
            enc_every=every("height_encoder"),
            imu_noise_rad=sigma_imu,
            imu_bias_rad=np.radians(np.asarray(imu["bias_deg"], dtype=float)),
            imu_walk_rad=bias_walk_sigma(math.radians(walk), imu_t),
            imu_accel_alpha=-math.expm1(-2.0 * math.pi * fc * dt),
            imu_alpha=1.0 - math.exp(-2.0 * math.pi * bw * dt),
            imu_every=imu_every,
            dt=float(dt),
        )

    @property
    def step_constants(self) -> np.ndarray:
        """``sc`` of :func:`~simpro_mj.plant.step_functions.sample_sensors`, packed by
        name (:data:`~simpro_mj.plant.step_functions.SC`)."""
        return SC.pack(
            lsb=self.pot_lsb_m, sigma=self.pot_noise_m, lo=self.pot_range_m[0],
            hi=self.pot_range_m[1], off=self.pot_offset_m, gain=self.pot_gain,
            fs=self.pot_full_scale_m, nl=self.pot_nonlinearity, pot_every=self.pot_every,
            res=self.enc_res_m, enc_noise=self.enc_noise_m, enc_every=self.enc_every,
            sigma_imu=self.imu_noise_rad, bias=self.imu_bias_rad, walk=self.imu_walk_rad,
            accw=self.imu_accel_alpha, alpha=self.imu_alpha, imu_every=self.imu_every,
            idt2=1.0 / (self.dt * self.dt),
        )  # fmt: skip

    def resolution_floor(self, with_bias: bool = True) -> dict:
        """Smallest steady-state error the task loop can be asked to remove, SI.

        The loop integrates the *measured* error, so the true pose settles
        within about one quantisation step plus the noise averaged over the
        metric window; we state the floor as the quantisation step plus three
        standard deviations of the sample noise averaged over 1 s of samples,
        plus the IMU's static bias (``with_bias``). A bias shifts the pose the
        loop settles at; it does not make it move, so the verdict's floor on
        oscillation leaves it out (``with_bias=False``).
        """
        n_imu = max(1, int(1.0 / (self.imu_every * self.dt)))
        imu = self.imu_noise_rad * 3 / math.sqrt(n_imu)
        b = np.abs(self.imu_bias_rad) if with_bias else np.zeros(2)
        return {
            "roll": imu + float(b[0]),
            "pitch": imu + float(b[1]),
            "heave": self.enc_res_m + 3 * self.enc_noise_m,
        }
