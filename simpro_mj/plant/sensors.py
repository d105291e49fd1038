"""Simulated sensors of the SIMPRO rig (paper section 5).

The rig reads, through a Humusoft MF624 board (14-bit, ±10 V ADC):

* joint potentiometers on q_i,
* an encoder for the height h,
* an IMU for roll and pitch.

Each sensor here turns MuJoCo's exact state into what such a sensor would
report: as-built errors (potentiometer offset and gain), noise, quantisation,
bandwidth (IMU), and a sampling rate with zero-order hold. Every noise source
draws from one :class:`numpy.random.Generator` seeded by the scenario, in a
fixed order, so the same scenario and seed give identical readings.

Noise is pre-drawn in blocks (no per-step generator calls in the 1 ms loop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.rates import steps_per_period
from simpro_mj.plant import sensors_kernel as _sk
from simpro_mj.plant.kernels import kernel_choice
from simpro_mj.plant.sensor_errors import (
    accel_tilt,
    bias_walk_sigma,
    noise_sigma,
    pot_nonlinearity,
)

__all__ = ["DEFAULT_SENSORS", "POT_BITS", "POT_BITS_TEXT", "SensorConfig", "Sensors"]

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
        # share of the accelerometer's tilt (which sees the platform's own linear
        # acceleration) in the attitude output, 0 (gyro only) .. 1 (accelerometer only)
        "accel_tilt_weight": 0.0,
        "bandwidth_hz": 20.0,  # first-order output filter
        "rate_ms": 5,  # 200 Hz output
    },
}


@dataclass(frozen=True)
class SensorConfig:
    """Sensor parameters in SI, built from the edge-unit tree."""

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
    imu_accel_weight: float
    imu_alpha: float  # first-order filter coefficient per physics step
    imu_every: int
    dt: float

    @classmethod
    def from_tree(cls, tree: dict, dt: float, path: str = "sensors") -> SensorConfig:
        pot, enc, imu = tree["potentiometer"], tree["height_encoder"], tree["imu"]

        def every(ms, where):
            return steps_per_period(ms, dt, f"{path}.{where}.rate_ms")

        def positive(v, where, zero_ok=False):
            if not (math.isfinite(v) and (v >= 0 if zero_ok else v > 0)):
                allowed = ">= 0" if zero_ok else "> 0"
                raise UserInputError(f"invalid value at {path}.{where}: {v}; allowed: {allowed}")
            return float(v)

        bits = int(pot["bits"])
        if not POT_BITS[0] <= bits <= POT_BITS[1]:
            raise UserInputError(
                f"invalid value at {path}.potentiometer.bits: {bits}; allowed: {POT_BITS_TEXT}"
            )
        rng_v = positive(pot["range_v"], "potentiometer.range_v")
        vpm = positive(pot["volts_per_mm"], "potentiometer.volts_per_mm") * 1e3  # V/m
        lsb_v = 2.0 * rng_v / 2**bits
        bw = positive(imu["bandwidth_hz"], "imu.bandwidth_hz")
        imu_every = every(imu["rate_ms"], "imu")
        imu_t = imu_every * dt
        sigma_imu = math.radians(positive(imu["noise_deg"], "imu.noise_deg", True))
        density = positive(
            imu.get("noise_density_deg_per_sqrt_hz", 0.0), "imu.noise_density_deg_per_sqrt_hz", True
        )
        if density > 0:
            sigma_imu = math.hypot(sigma_imu, noise_sigma(math.radians(density), imu_t))
        weight = float(imu.get("accel_tilt_weight", 0.0))
        if not 0.0 <= weight <= 1.0:
            raise UserInputError(
                f"invalid value at {path}.imu.accel_tilt_weight: {weight}; allowed: 0 (gyro "
                "only) .. 1 (accelerometer only)"
            )
        walk = positive(
            imu.get("bias_walk_deg_per_sqrt_s", 0.0), "imu.bias_walk_deg_per_sqrt_s", True
        )
        nl = positive(
            pot.get("nonlinearity_pct_fs", 0.0), "potentiometer.nonlinearity_pct_fs", True
        )
        return cls(
            pot_lsb_m=lsb_v / vpm,
            pot_noise_m=positive(pot["noise_lsb"], "potentiometer.noise_lsb", True) * lsb_v / vpm,
            pot_range_m=(-rng_v / vpm, (rng_v - lsb_v) / vpm),
            pot_offset_m=np.asarray(pot["offset_mm"], dtype=float) * 1e-3,
            pot_gain=1.0 + np.asarray(pot["gain_error_pct"], dtype=float) * 1e-2,
            pot_full_scale_m=rng_v / vpm,
            pot_nonlinearity=nl * 1e-2,
            pot_every=every(pot["rate_ms"], "potentiometer"),
            enc_res_m=positive(enc["resolution_mm"], "height_encoder.resolution_mm", True) * 1e-3,
            enc_noise_m=positive(enc["noise_mm"], "height_encoder.noise_mm", True) * 1e-3,
            enc_every=every(enc["rate_ms"], "height_encoder"),
            imu_noise_rad=sigma_imu,
            imu_bias_rad=np.radians(np.asarray(imu["bias_deg"], dtype=float)),
            imu_walk_rad=bias_walk_sigma(math.radians(walk), imu_t),
            imu_accel_weight=weight,
            imu_alpha=1.0 - math.exp(-2.0 * math.pi * bw * dt),
            imu_every=imu_every,
            dt=float(dt),
        )


class Sensors:
    """The rig's sensors, sampled every physics step (zero-order hold between samples).

    Parameters
    ----------
    config : SensorConfig
    rng : numpy.random.Generator
        Seeded by the scenario; the only source of randomness.
    block : int
        Steps of noise drawn at a time.

    Notes
    -----
    Potentiometer i reports ``q_i^m = Q((g_i q_i + o_i) + n) `` with Q the ADC
    quantiser (one LSB = ``2 range / 2^bits`` volts) and saturation at the
    ADC's range; the controller converts with the nominal scale, so offset
    ``o_i`` and gain ``g_i`` appear as joint-space errors. The encoder reports
    ``round(h / res) res``. The IMU low-pass filters roll and pitch at its
    bandwidth, adds bias and white noise, and updates every ``rate_ms``.
    """

    def __init__(self, config: SensorConfig, rng: np.random.Generator, block: int = 4096):
        self.cfg = config
        self.rng = rng
        self.block = int(block)
        self.q = np.zeros(3)
        self.pose = np.zeros(3)  # roll, pitch, h as measured
        # The state lives in Python floats (three legs are too few for numpy's
        # per-call cost); sample() mirrors it into the arrays above.
        self._q = [0.0] * 3
        self._pose = [0.0] * 3
        self._imu_state = [0.0] * 2
        self._noise_rows: list = []  # the pre-drawn noise block, as lists of 6 floats
        self._k0 = 0
        self._pot = (
            config.pot_gain.tolist(),
            config.pot_offset_m.tolist(),
            config.pot_noise_m,
            config.pot_lsb_m,
            *config.pot_range_m,
        )
        self._imu_bias = config.imu_bias_rad.tolist()
        # the config's scalars as plain attributes (read every step)
        self._every = (config.pot_every, config.enc_every, config.imu_every)
        self._enc = (config.enc_noise_m, config.enc_res_m)
        self._imu = (config.imu_alpha, config.imu_noise_rad)
        # sensor errors (simpro_mj.plant.sensor_errors): the track's bow, the bias's
        # random walk (its own generator, spawned from the scenario's, so the other
        # noise draws stay as they are), the accelerometer's view of the motion
        self._nl = (config.pot_full_scale_m, config.pot_nonlinearity)
        self._walk_sigma = config.imu_walk_rad
        self._walk_rng = rng.spawn(1)[0] if config.imu_walk_rad > 0 else None
        self._walk = [0.0, 0.0]
        self._walk_rows: list = []
        self._walk_j = 0  # next row of the walk block
        self._accel_w = config.imu_accel_weight
        self._hist: list = []  # the IMU site's last two positions (accelerometer)
        self._kb = None
        if kernel_choice() == "numba":  # SIMPRO_KERNEL (simpro_mj.plant.kernels)
            self._init_kernel()

    # -- compiled kernel (sensors_kernel.py) ---------------------------------
    def _init_kernel(self) -> None:
        """The kernel's buffer: configuration, state and the noise block."""
        sk = _sk
        kb = np.zeros(sk.buffer_len(self.block))
        kb[sk.C_GAIN : sk.C_GAIN + 3] = self._pot[0]
        kb[sk.C_OFF : sk.C_OFF + 3] = self._pot[1]
        kb[sk.C_SIGMA], kb[sk.C_LSB], kb[sk.C_LO], kb[sk.C_HI] = self._pot[2:]
        kb[sk.C_POT_EVERY], kb[sk.C_ENC_EVERY], kb[sk.C_IMU_EVERY] = self._every
        kb[sk.C_ENC_NOISE], kb[sk.C_RES] = self._enc
        kb[sk.C_ALPHA], kb[sk.C_SIGMA_IMU] = self._imu
        kb[sk.C_BIAS : sk.C_BIAS + 2] = self._imu_bias
        kb[sk.C_FS], kb[sk.C_NL] = self._nl
        kb[sk.C_WALK], kb[sk.C_ACCW] = self._walk_sigma, self._accel_w
        kb[sk.C_WALK_ON] = 1.0 if self._walk_rng is not None else 0.0
        kb[sk.C_IDT2] = 1.0 / (self.cfg.dt * self.cfg.dt)
        kb[sk.C_WALK_AT] = sk.NOISE + 6 * self.block
        kb[sk.S_WJ] = self.block
        self._kb = kb
        self._k_walk = kb[sk.NOISE + 6 * self.block :].reshape(self.block, 2)  # view
        self._k_noise = kb[sk.NOISE : sk.NOISE + 6 * self.block].reshape(self.block, 6)  # view
        self._k_imu = kb[sk.S_IMU : sk.S_IMU + 2]
        self._k_meas = kb[sk.O_QM : sk.O_PM + 3]  # q_meas, pose_meas
        self._k_rows = 0  # rows of the noise block drawn since the last reset
        self._k_gather, self._k_sample, self._k_sample_in = sk.kernels()

    def _walk_kernel(self, k: int, force: bool) -> None:
        """A new block of the bias walk in the kernel's buffer when step k's IMU
        sample would pass the end of the present one (:meth:`_walk_block`)."""
        kb, sk = self._kb, _sk
        if kb[sk.S_WJ] >= self.block and (force or k % self._every[2] == 0):
            self._k_walk[...] = self._walk_block()
            kb[sk.S_WJ] = 0.0

    def _draw_kernel(self, k: int) -> int:
        """:meth:`_draw` into the kernel's buffer; returns the row of step k."""
        self._k_noise[...] = self.rng.standard_normal((self.block, 6))
        self._k_rows = self.block
        self._k0 = k
        return 0

    def front(self, reader):
        """The loop's state read and sensor step: ``front(k) -> (q, q_dot, pose,
        q_meas, pose_meas, loop_max)``.

        ``reader`` is the run's :class:`~simpro_mj.plant.model.StateReader`.
        One contract, two paths with the same bits: ``reader.read()``,
        :meth:`sample_floats` and ``reader.loop_closure_max()`` of the state
        at step ``k`` (the Python path), or one compiled call
        (``SIMPRO_KERNEL``, :mod:`simpro_mj.plant.sensors_kernel`) when
        MuJoCo's state can be viewed as one buffer. ``q_meas`` and
        ``pose_meas`` may be the sensor's own lists: copy them to keep them.
        """
        fused = self._fused_front(reader)
        if fused is not None:
            return fused
        read, sample, loop_max = reader.read, self.sample_floats, reader.loop_closure_max
        if self._accel_w > 0:  # the accelerometer needs the IMU site's position
            at = reader.p_at

            def front_site(k: int):
                q, qd, pose, xpos = read()
                q_meas, pose_meas = sample(k, q, pose, False, xpos[at : at + 3])
                return q, qd, pose, q_meas, pose_meas, loop_max(xpos)

            return front_site

        def front(k: int):
            q, qd, pose, xpos = read()
            q_meas, pose_meas = sample(k, q, pose)
            return q, qd, pose, q_meas, pose_meas, loop_max(xpos)

        return front

    def _fused_front(self, reader):
        """:meth:`front` as one compiled call, or None (Python path, or no one buffer)."""
        if self._kb is None:
            return None
        bound = reader.buffer_view()
        if bound is None:
            return None
        sk, kb = _sk, self._kb
        view, qpos, qvel, xmat, h, pairs = bound
        if len(pairs) > sk.MAX_PAIRS:
            return None
        kb[sk.R_QPOS : sk.R_QPOS + 3] = qpos
        kb[sk.R_QVEL : sk.R_QVEL + 3] = qvel
        kb[sk.R_XMAT], kb[sk.R_H], kb[sk.R_NPAIR] = xmat, h, len(pairs)
        kb[sk.R_PAIRS : sk.R_PAIRS + 2 * len(pairs)] = [i for p in pairs for i in p]
        gather, sample, atan2 = self._k_gather, self._k_sample, np.arctan2
        num, den = kb[sk.S_ND : sk.S_ND + 2], kb[sk.S_ND + 2 : sk.S_ND + 4]
        ang = kb[sk.O_POSE : sk.O_POSE + 2]  # roll, pitch: numpy's arctan2 (as the reader)
        out = kb[: sk.OUT_LEN]

        walk = self._walk_kernel if self._walk_rng is not None else None

        def front(k: int):
            i = k - self._k0
            if not 0 <= i < self._k_rows:
                i = self._draw_kernel(k)
            if walk is not None:
                walk(k, False)
            gather(view, kb)
            atan2(num, den, out=ang)
            sample(k, i, False, True, kb)
            v = out.tolist()
            return v[0:3], v[3:6], v[6:9], v[9:12], v[12:15], v[15]

        front.reader = reader  # keeps MuJoCo's data (the view's memory) alive
        return front

    def _walk_block(self) -> list:
        """The next ``block`` steps of the bias walk (2 per IMU sample), standard normal."""
        if self._walk_rng is None:
            return [[0.0, 0.0]] * self.block
        return self._walk_rng.standard_normal((self.block, 2)).tolist()

    def _draw(self, k: int) -> list:
        """Noise row for step k: 3 pots, encoder, 2 IMU axes (standard normal floats)."""
        i = k - self._k0
        if i >= len(self._noise_rows) or i < 0:
            self._noise_rows = self.rng.standard_normal((self.block, 6)).tolist()
            self._k0 = k
            i = 0
        return self._noise_rows[i]

    def reset(self, q_true, pose_true) -> None:
        """Initialise the filters at the true state and take a first reading."""
        self._imu_state[:] = [float(pose_true[0]), float(pose_true[1])]
        self._noise_rows = []
        self._k0 = 0
        self._walk[:] = [0.0, 0.0]
        self._walk_rows, self._walk_j = [], 0
        self._hist = []
        if self._kb is not None:
            self._k_imu[:] = self._imu_state
            self._k_rows = 0
            sk = _sk
            self._kb[sk.S_WALK : sk.S_WALK + 2] = 0.0
            self._kb[sk.S_WJ], self._kb[sk.S_HN] = self.block, 0.0
        self.sample(0, q_true, pose_true, force=True)

    def sample(self, k: int, q_true, pose_true, force: bool = False):
        """Update the readings at physics step k; returns (q_meas, pose_meas) views.

        The returned arrays are the sensor's own buffers (copy them to log).
        """
        q, pose = self.sample_floats(k, _floats(q_true), _floats(pose_true), force)
        self.q[:] = q
        self.pose[:] = pose
        return self.q, self.pose

    def sample_floats(self, k: int, q_true, pose_true, force: bool = False, site=None):
        """:meth:`sample` on sequences of 3 floats; returns (q_meas, pose_meas) lists.

        ``site``: the IMU site's world position (3 floats) at this step, whose
        second difference is the acceleration the accelerometer sees
        (``imu.accel_tilt_weight``); None: no acceleration.

        The co-simulation's hot path. The lists are the sensor's own state
        (copy them to keep them). The arithmetic is the array version's,
        operation for operation (``round`` is numpy's round-half-even).
        With the compiled kernel (``SIMPRO_KERNEL``, :mod:`simpro_mj.plant.sensors_kernel`)
        the same arithmetic runs there and the lists are fresh copies.
        """
        if self._kb is not None:
            i = k - self._k0
            if not 0 <= i < self._k_rows:
                i = self._draw_kernel(k)
            if self._walk_rng is not None:
                self._walk_kernel(k, force)
            sx, sy, sz = (0.0, 0.0, 0.0) if site is None else site
            self._k_sample_in(
                k, i, bool(force), q_true[0], q_true[1], q_true[2],
                pose_true[0], pose_true[1], pose_true[2], site is not None, sx, sy, sz,
                self._kb,
            )  # fmt: skip
            v = self._k_meas.tolist()
            return v[:3], v[3:]
        i = k - self._k0
        rows = self._noise_rows
        n = rows[i] if 0 <= i < len(rows) else self._draw(k)  # _draw(k), inline when in the block
        pot_every, enc_every, imu_every = self._every
        # IMU's output filter runs at the physics rate
        imu = self._imu_state
        alpha, sigma_imu = self._imu
        r_in, p_in = pose_true[0], pose_true[1]
        w = self._accel_w
        if w > 0 and site is not None:
            r_in, p_in = self._accel_input(site, r_in, p_in, w)
        imu[0] = imu[0] + alpha * (r_in - imu[0])
        imu[1] = imu[1] + alpha * (p_in - imu[1])
        if force or k % pot_every == 0:
            gain, off, sigma, lsb, lo, hi = self._pot
            fs, nl = self._nl
            q = self._q
            for i in range(3):
                if nl > 0:
                    e = pot_nonlinearity(q_true[i], fs, nl)
                    v = gain[i] * q_true[i] + off[i] + e + sigma * n[i]
                else:
                    v = gain[i] * q_true[i] + off[i] + sigma * n[i]
                try:
                    v = round(v / lsb) * lsb
                except (ValueError, OverflowError):  # NaN or inf: numpy's rint keeps it
                    v = float(np.round(v / lsb) * lsb)
                if v < lo:
                    v = lo
                if v > hi:
                    v = hi
                q[i] = v
        pose = self._pose
        if force or k % enc_every == 0:
            noise, res = self._enc
            h = pose_true[2] + noise * n[3]
            if res > 0:
                try:
                    h = round(h / res) * res
                except (ValueError, OverflowError):
                    h = float(np.round(h / res) * res)
            pose[2] = h
        if force or k % imu_every == 0:
            bias, walk = self._imu_bias, self._walk
            if self._walk_rng is not None:
                if self._walk_j >= len(self._walk_rows):
                    self._walk_rows, self._walk_j = self._walk_block(), 0
                wn = self._walk_rows[self._walk_j]
                self._walk_j += 1
                walk[0] = walk[0] + self._walk_sigma * wn[0]
                walk[1] = walk[1] + self._walk_sigma * wn[1]
            pose[0] = imu[0] + (bias[0] + walk[0]) + sigma_imu * n[4]
            pose[1] = imu[1] + (bias[1] + walk[1]) + sigma_imu * n[5]
        return self._q, pose

    def _accel_input(self, site, roll, pitch, w):
        """The IMU filter's input: the true angles moved by ``w`` times what the
        accelerometer reads from the site's acceleration (second difference)."""
        h = self._hist
        x, y, z = float(site[0]), float(site[1]), float(site[2])
        if len(h) < 2:  # the first two positions of a run: no acceleration yet
            h.insert(0, (x, y, z))
            return roll, pitch
        (x1, y1, z1), (x2, y2, z2) = h
        idt2 = 1.0 / (self.cfg.dt * self.cfg.dt)
        ax = ((x - x2) - 2.0 * (x1 - x2)) * idt2
        ay = ((y - y2) - 2.0 * (y1 - y2)) * idt2
        az = ((z - z2) - 2.0 * (z1 - z2)) * idt2
        h[0], h[1] = (x, y, z), (x1, y1, z1)
        ra, pa = accel_tilt(ax, ay, az, roll, pitch)
        return roll + w * (ra - roll), pitch + w * (pa - pitch)

    def resolution_floor(self) -> dict:
        """Smallest steady-state error the task loop can be asked to remove, SI.

        The loop integrates the *measured* error, so the true pose settles
        within about one quantisation step plus the noise averaged over the
        metric window; we state the floor as the quantisation step plus three
        standard deviations of the sample noise averaged over 1 s of samples.
        """
        c = self.cfg
        n_imu = max(1, int(1.0 / (c.imu_every * c.dt)))
        return {
            "roll": c.imu_noise_rad * 3 / math.sqrt(n_imu) + float(np.abs(c.imu_bias_rad[0])),
            "pitch": c.imu_noise_rad * 3 / math.sqrt(n_imu) + float(np.abs(c.imu_bias_rad[1])),
            "heave": c.enc_res_m + 3 * c.enc_noise_m,
        }


def _floats(x) -> list:
    """A (3,) array or sequence as a list of 3 numbers."""
    if type(x) is np.ndarray:
        return x.tolist()
    return list(x)
