"""Errors a rig's sensors have beyond noise and quantisation: plain scalar functions.

Each function works on floats with :mod:`math` only, so the sensor step
(:func:`simpro_mj.plant.step_functions.sample_sensors`) calls them
interpreted and compiled alike. All are off
(zero) on the ``paper`` preset; ``heavy_cabin`` sets a MEMS unit's values
(``docs/paper-notes.md``, sensor errors, has them and the pose each leaves).

* :func:`accel_tilt`: the roll and pitch a MEMS accelerometer reads from the
  specific force when the platform itself accelerates (a tilt estimate that
  leans on the accelerometer sees its own linear acceleration as tilt);
* :func:`bias_walk_sigma`: the step of the IMU bias's random walk per sample;
* :func:`noise_sigma`: a noise density as the RMS of one sample;
* :func:`pot_nonlinearity`: a potentiometer's deviation from its straight line.
"""

from __future__ import annotations

import math

__all__ = ["G", "accel_tilt", "bias_walk_sigma", "noise_sigma", "pot_nonlinearity"]

#: Standard gravity (m/s^2), ISO 80000-3.
G = 9.80665


def accel_tilt(ax, ay, az, roll, pitch):
    """Roll and pitch (rad) a 3-axis accelerometer reads on the moving platform.

    ``ax, ay, az`` is the sensor's linear acceleration in the world frame
    (m/s², z up); ``roll, pitch`` its true attitude, R = Ry(pitch) Rx(roll)
    (eq. 8). The accelerometer measures the specific force
    :math:`f_b = R^T (a - g)`, g = (0, 0, -G), and a tilt estimate reads
    roll = atan2(f_y, f_z), pitch = atan2(-f_x, sqrt(f_y² + f_z²)); at rest
    (a = 0) these are the true angles.

    Returns
    -------
    (float, float)
        The accelerometer's roll and pitch, rad.
    """
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    fz_w = az + G
    fx = cp * ax - sp * fz_w
    fy = (sp * sr) * ax + cr * ay + (cp * sr) * fz_w
    fz = (sp * cr) * ax - sr * ay + (cp * cr) * fz_w
    return math.atan2(fy, fz), math.atan2(-fx, math.sqrt(fy * fy + fz * fz))


def bias_walk_sigma(walk_per_sqrt_s, period_s):
    """Standard deviation of one step of a random walk sampled every ``period_s``.

    A bias random walk of ``walk_per_sqrt_s`` (rad/√s) grows as
    :math:`σ_b(t) = w \\sqrt{t}`; per sample of period T it takes a step of
    :math:`w \\sqrt{T}`.
    """
    return walk_per_sqrt_s * math.sqrt(period_s)


def noise_sigma(density_per_sqrt_hz, period_s):
    """RMS of one sample of white noise of one-sided density ``density_per_sqrt_hz``
    sampled every ``period_s``: the density over the Nyquist band,
    :math:`σ = d \\sqrt{f_s / 2}`."""
    return density_per_sqrt_hz * math.sqrt(0.5 / period_s)


def pot_nonlinearity(q, full_scale, fraction):
    """Deviation (m) of a linear potentiometer's reading from its straight line.

    A bow over the track, :math:`e(x) = ν F (8 x (1 - x) - 1)` with
    :math:`x = q / F`: its independent linearity (the largest deviation from
    the best straight line, which for a parabola is the mid-level one) is the
    datasheet's ``fraction`` ν of the full scale F; +ν F at mid-stroke,
    -ν F at both ends.
    """
    x = q / full_scale
    return (fraction * full_scale) * (8.0 * x * (1.0 - x) - 1.0)
