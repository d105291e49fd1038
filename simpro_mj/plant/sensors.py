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
        "rate_ms": 1,
    },
    "height_encoder": {
        "resolution_mm": 0.01,  # linear encoder, 10 um (assumption)
        "noise_mm": 0.0,
        "rate_ms": 1,
    },
    "imu": {
        "noise_deg": 0.005,  # RMS per sample (assumption: MEMS AHRS class)
        "bias_deg": [0.0, 0.0],  # roll, pitch
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
    pot_every: int
    enc_res_m: float
    enc_noise_m: float
    enc_every: int
    imu_noise_rad: float
    imu_bias_rad: np.ndarray
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
        return cls(
            pot_lsb_m=lsb_v / vpm,
            pot_noise_m=positive(pot["noise_lsb"], "potentiometer.noise_lsb", True) * lsb_v / vpm,
            pot_range_m=(-rng_v / vpm, (rng_v - lsb_v) / vpm),
            pot_offset_m=np.asarray(pot["offset_mm"], dtype=float) * 1e-3,
            pot_gain=1.0 + np.asarray(pot["gain_error_pct"], dtype=float) * 1e-2,
            pot_every=every(pot["rate_ms"], "potentiometer"),
            enc_res_m=positive(enc["resolution_mm"], "height_encoder.resolution_mm", True) * 1e-3,
            enc_noise_m=positive(enc["noise_mm"], "height_encoder.noise_mm", True) * 1e-3,
            enc_every=every(enc["rate_ms"], "height_encoder"),
            imu_noise_rad=math.radians(positive(imu["noise_deg"], "imu.noise_deg", True)),
            imu_bias_rad=np.radians(np.asarray(imu["bias_deg"], dtype=float)),
            imu_alpha=1.0 - math.exp(-2.0 * math.pi * bw * dt),
            imu_every=every(imu["rate_ms"], "imu"),
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
        self._kb = kb
        self._k_noise = kb[sk.NOISE :].reshape(self.block, 6)  # view
        self._k_imu = kb[sk.S_IMU : sk.S_IMU + 2]
        self._k_meas = kb[sk.O_QM : sk.O_PM + 3]  # q_meas, pose_meas
        self._k_rows = 0  # rows of the noise block drawn since the last reset
        self._k_gather, self._k_sample, self._k_sample_in = sk.kernels()

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

        def front(k: int):
            i = k - self._k0
            if not 0 <= i < self._k_rows:
                i = self._draw_kernel(k)
            gather(view, kb)
            atan2(num, den, out=ang)
            sample(k, i, False, kb)
            v = out.tolist()
            return v[0:3], v[3:6], v[6:9], v[9:12], v[12:15], v[15]

        front.reader = reader  # keeps MuJoCo's data (the view's memory) alive
        return front

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
        if self._kb is not None:
            self._k_imu[:] = self._imu_state
            self._k_rows = 0
        self.sample(0, q_true, pose_true, force=True)

    def sample(self, k: int, q_true, pose_true, force: bool = False):
        """Update the readings at physics step k; returns (q_meas, pose_meas) views.

        The returned arrays are the sensor's own buffers (copy them to log).
        """
        q, pose = self.sample_floats(k, _floats(q_true), _floats(pose_true), force)
        self.q[:] = q
        self.pose[:] = pose
        return self.q, self.pose

    def sample_floats(self, k: int, q_true, pose_true, force: bool = False):
        """:meth:`sample` on sequences of 3 floats; returns (q_meas, pose_meas) lists.

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
            self._k_sample_in(
                k, i, bool(force), q_true[0], q_true[1], q_true[2],
                pose_true[0], pose_true[1], pose_true[2], self._kb,
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
        imu[0] = imu[0] + alpha * (pose_true[0] - imu[0])
        imu[1] = imu[1] + alpha * (pose_true[1] - imu[1])
        if force or k % pot_every == 0:
            gain, off, sigma, lsb, lo, hi = self._pot
            q = self._q
            for i in range(3):
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
            bias = self._imu_bias
            pose[0] = imu[0] + bias[0] + sigma_imu * n[4]
            pose[1] = imu[1] + bias[1] + sigma_imu * n[5]
        return self._q, pose

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
