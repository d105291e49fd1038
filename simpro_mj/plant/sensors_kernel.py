"""Optional compiled kernels (numba) for the sensors and the state read.

The pure-Python :meth:`Sensors.sample_floats <simpro_mj.plant.sensors.Sensors.sample_floats>`
and :meth:`StateReader.read <simpro_mj.plant.model.StateReader.read>` /
:meth:`~simpro_mj.plant.model.StateReader.loop_closure_max` are the reference;
this module repeats their float arithmetic operation for operation (same
grouping, no ``fastmath``) in two ``@numba.njit(cache=True)`` functions on
one float64 buffer owned by the :class:`~simpro_mj.plant.sensors.Sensors` object:

* :func:`_gather` copies ``q``, ``q_dot``, the platform height, the four
  rotation-matrix entries of the pose and the worst squared loop-closure
  distance (``sqrt`` taken once, IEEE, as the Python path) from one view of
  MuJoCo's data buffer into the sensor buffer;
* ``np.arctan2`` of roll and pitch stays numpy's (its SIMD kernel is not
  libm's ``atan2``, which numba would call), on contiguous slices of the
  buffer, between the two calls;
* :func:`_sample` runs the sensor models (IMU filter, potentiometer ADC,
  encoder, IMU output) on the pre-drawn noise block kept in the buffer.

Rounding: the Python path's ``round(x) * lsb`` is round-half-even to an
``int`` and back; ``np.rint`` is the same IEEE round-to-nearest-even, except
that it keeps the sign of a zero (``rint(-0.3) = -0.0``, ``round(-0.3) = 0``),
so the kernel turns a zero result into ``+0.0``. NaN and inf pass through
``rint`` as through the Python path's ``np.round`` fallback.

Selection: the same ``SIMPRO_KERNEL`` switch as the pneumatics kernel
(:func:`simpro_mj.plant.kernels.kernel_choice`), read when a
:class:`~simpro_mj.plant.sensors.Sensors` object is built.
"""

from __future__ import annotations

import numpy as np

from simpro_mj.plant.sensor_errors import accel_tilt, pot_nonlinearity

# Layout of the sensor kernel's float64 buffer. The first OUT_LEN entries are
# what one step hands to the loop, in one tolist(): q, q_dot, pose (true),
# q_meas, pose_meas, the loop-closure maximum.
O_Q, O_QD, O_POSE, O_QM, O_PM, O_LOOP, OUT_LEN = 0, 3, 6, 9, 12, 15, 16
S_IMU = 16  # IMU filter state (roll, pitch)
S_ND = 18  # arctan2 arguments: num (R21, -R20), den (R22, R00)
C_GAIN, C_OFF = 22, 25  # potentiometer gain and offset (3 each)
C_SIGMA, C_LSB, C_LO, C_HI, C_POT_EVERY = 28, 29, 30, 31, 32
C_ENC_NOISE, C_RES, C_ENC_EVERY = 33, 34, 35
C_ALPHA, C_SIGMA_IMU, C_BIAS, C_IMU_EVERY = 36, 37, 38, 40  # bias: 2 entries
# the state read: element offsets into the view of MuJoCo's data buffer
R_QPOS, R_QVEL, R_XMAT, R_H, R_NPAIR, R_PAIRS = 41, 44, 47, 48, 49, 50  # pairs: 2 per loop
MAX_PAIRS = 8
# sensor errors (simpro_mj.plant.sensor_errors): potentiometer full scale and linearity,
# the bias walk's step, its state (2), on/off, the next row of its block and where the
# block starts, the accelerometer's weight, 1/dt^2, the site's last two positions (6)
# and how many are known, the site's position at this step (3)
C_FS, C_NL, C_WALK, S_WALK, C_WALK_ON, S_WJ, C_WALK_AT = 66, 67, 68, 69, 71, 72, 73
C_ACCW, C_IDT2, S_HIST, S_HN, O_SITE = 74, 75, 76, 82, 83
NOISE = O_SITE + 3  # pre-drawn noise block (block x 6), row-major; then the walk's (block x 2)


def buffer_len(block: int) -> int:
    """Length of the buffer for noise blocks of ``block`` rows."""
    return NOISE + 8 * block


def _quantise(v, step):
    """``round(v / step) * step`` as Python's ``int`` round: half-even, +0.0 for zero."""
    r = np.rint(v / step)
    if r == 0.0:
        r = 0.0
    return r * step


def _sample(k, i, force, has_site, b):
    """:meth:`Sensors.sample_floats` at step ``k`` with noise row ``i`` of the block.

    Reads the true q (``b[O_Q:]``), pose (``b[O_POSE:]``) and, with
    ``has_site``, the IMU site's position (``b[O_SITE:]``); writes the IMU
    state, q_meas and pose_meas in place.
    """
    n = NOISE + 6 * i
    alpha = b[C_ALPHA]
    r_in, p_in = b[O_POSE], b[O_POSE + 1]
    w = b[C_ACCW]
    if w > 0 and has_site:  # Sensors._accel_input
        x, y, z = b[O_SITE], b[O_SITE + 1], b[O_SITE + 2]
        if b[S_HN] < 2:
            b[S_HIST + 3], b[S_HIST + 4], b[S_HIST + 5] = b[S_HIST], b[S_HIST + 1], b[S_HIST + 2]
            b[S_HIST], b[S_HIST + 1], b[S_HIST + 2] = x, y, z
            b[S_HN] = b[S_HN] + 1.0
        else:
            x1, y1, z1 = b[S_HIST], b[S_HIST + 1], b[S_HIST + 2]
            x2, y2, z2 = b[S_HIST + 3], b[S_HIST + 4], b[S_HIST + 5]
            idt2 = b[C_IDT2]
            ax = ((x - x2) - 2.0 * (x1 - x2)) * idt2
            ay = ((y - y2) - 2.0 * (y1 - y2)) * idt2
            az = ((z - z2) - 2.0 * (z1 - z2)) * idt2
            b[S_HIST + 3], b[S_HIST + 4], b[S_HIST + 5] = x1, y1, z1
            b[S_HIST], b[S_HIST + 1], b[S_HIST + 2] = x, y, z
            ra, pa = accel_tilt(ax, ay, az, r_in, p_in)
            r_in, p_in = r_in + w * (ra - r_in), p_in + w * (pa - p_in)
    b[S_IMU] = b[S_IMU] + alpha * (r_in - b[S_IMU])
    b[S_IMU + 1] = b[S_IMU + 1] + alpha * (p_in - b[S_IMU + 1])
    if force or k % int(b[C_POT_EVERY]) == 0:
        sigma, lsb, lo, hi = b[C_SIGMA], b[C_LSB], b[C_LO], b[C_HI]
        fs, nl = b[C_FS], b[C_NL]
        for j in range(3):
            if nl > 0:
                e = pot_nonlinearity(b[O_Q + j], fs, nl)
                v = b[C_GAIN + j] * b[O_Q + j] + b[C_OFF + j] + e + sigma * b[n + j]
            else:
                v = b[C_GAIN + j] * b[O_Q + j] + b[C_OFF + j] + sigma * b[n + j]
            v = _quantise(v, lsb)
            if v < lo:
                v = lo
            if v > hi:
                v = hi
            b[O_QM + j] = v
    if force or k % int(b[C_ENC_EVERY]) == 0:
        h = b[O_POSE + 2] + b[C_ENC_NOISE] * b[n + 3]
        res = b[C_RES]
        if res > 0:
            h = _quantise(h, res)
        b[O_PM + 2] = h
    if force or k % int(b[C_IMU_EVERY]) == 0:
        s = b[C_SIGMA_IMU]
        if b[C_WALK_ON] > 0:  # the caller drew a new walk block when this one ran out
            wr = int(b[C_WALK_AT]) + 2 * int(b[S_WJ])
            b[S_WJ] = b[S_WJ] + 1.0
            b[S_WALK] = b[S_WALK] + b[C_WALK] * b[wr]
            b[S_WALK + 1] = b[S_WALK + 1] + b[C_WALK] * b[wr + 1]
        b[O_PM] = b[S_IMU] + (b[C_BIAS] + b[S_WALK]) + s * b[n + 4]
        b[O_PM + 1] = b[S_IMU + 1] + (b[C_BIAS + 1] + b[S_WALK + 1]) + s * b[n + 5]


def _sample_in(k, i, force, q0, q1, q2, roll, pitch, h, has_site, sx, sy, sz, b):
    """:func:`_sample` on a true state given as numbers (written to the buffer)."""
    b[O_Q], b[O_Q + 1], b[O_Q + 2] = float(q0), float(q1), float(q2)
    b[O_POSE], b[O_POSE + 1], b[O_POSE + 2] = float(roll), float(pitch), float(h)
    b[O_SITE], b[O_SITE + 1], b[O_SITE + 2] = float(sx), float(sy), float(sz)
    _sample(k, i, force, has_site, b)


def _gather(x, b):
    """The state read after ``mj_step1``: ``x`` is a view of MuJoCo's data buffer.

    Writes q, q_dot, the height, the arctan2 arguments and the loop-closure
    maximum (:meth:`StateReader.loop_closure_max`: squared distances
    ``(dx² + dy²) + dz²``, one ``sqrt`` of the largest, NaN passed on).
    """
    for j in range(3):
        b[O_Q + j] = x[int(b[R_QPOS + j])]
        b[O_QD + j] = x[int(b[R_QVEL + j])]
    r = int(b[R_XMAT])
    b[S_ND] = x[r + 7]
    b[S_ND + 1] = -x[r + 6]
    b[S_ND + 2] = x[r + 8]
    b[S_ND + 3] = x[r]
    hp = int(b[R_H])
    b[O_POSE + 2] = x[hp]
    b[O_SITE], b[O_SITE + 1], b[O_SITE + 2] = x[hp - 2], x[hp - 1], x[hp]
    worst = 0.0
    for p in range(int(b[R_NPAIR])):
        a = int(b[R_PAIRS + 2 * p])
        c = int(b[R_PAIRS + 2 * p + 1])
        dx, dy, dz = x[a] - x[c], x[a + 1] - x[c + 1], x[a + 2] - x[c + 2]
        e = dx * dx + dy * dy + dz * dz
        if e > worst:
            worst = e
        elif e != e:
            worst = e
            break
    b[O_LOOP] = np.sqrt(worst)


_kernels = None  # (gather, sample, sample_in), built on first use


def _jit(numba, f, **kw):
    try:
        return numba.njit(cache=True, **kw)(f)
    except RuntimeError:  # no writable cache location: compile in each process
        return numba.njit(**kw)(f)


def kernels():
    """The compiled ``(_gather, _sample, _sample_in)`` (``@numba.njit(cache=True)``),
    compiled or loaded from the on-disk cache on the first call in a process."""
    global _kernels
    if _kernels is None:
        import numba  # the optional extra simpro-sim[fast]: imported on first use

        # the callers' compiled bodies resolve these globals: replace them first
        globals()["_quantise"] = _jit(numba, _quantise, inline="always")
        globals()["accel_tilt"] = _jit(numba, accel_tilt, inline="always")
        globals()["pot_nonlinearity"] = _jit(numba, pot_nonlinearity, inline="always")
        globals()["_sample"] = _jit(numba, _sample)
        _kernels = (_jit(numba, _gather), _sample, _jit(numba, _sample_in))
    return _kernels
