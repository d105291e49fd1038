"""The controllers' part of one 1 ms step, as plain functions on flat float64 arrays.

The one implementation of the per-step controller arithmetic (this
package's classes configure it and keep their array APIs on top), in the
subset numba compiles (scalar ``math``, loops, indexing):
:mod:`simpro_mj.sim.step` runs it interpreted or compiled. No MuJoCo here.

Geometry constants (:func:`geometry_constants`), one flat array ``g``::

    g[0:9]    platform points PB_1..PB_3 (row-major, platform frame)
    g[9:12]   guide centre x_c, z_c, radius r
    g[12]     guide side (-1 or +1)
    g[13:16]  bracket offset C1 (eq. 11)
    g[16:25]  base points A_1..A_3 (row-major)
    g[25:28]  retracted lengths L0_i
    g[28]     stroke
"""

from __future__ import annotations

import math

import numpy as np

from .dead_band import dead_band

__all__ = [
    "GEOM_LEN",
    "geometry_constants",
    "ik_pose",
    "ik_lag",
    "segment_limit",
    "filter_step",
    "joint_step",
]

GEOM_LEN = 29

#: ik_pose's results: reachable, outside the workspace, guide circle missed (disc < 0)
IK_OK, IK_OUT, IK_MISS = 1, 0, -1


def geometry_constants(geometry) -> np.ndarray:
    """The flat constants array ``g`` of a :class:`~controllers.geometry.PlatformGeometry`."""
    G = geometry  # in the order of the module docstring's table
    head = [np.ravel(G.platform_points), G.guide_centre, [G.guide_radius, G.guide_side]]
    tail = [G.bracket_c1, np.ravel(G.base_points), G.retracted_length, [G.stroke]]
    return np.concatenate([*head, *tail], dtype=float)


def ik_pose(roll, pitch, h, g, margin, arc_check, q):
    """Inverse kinematics of one pose (eqs. 8, 11-14) into ``q`` (3,); returns a code.

    ``R = Ry(pitch) Rx(roll)``; ``B1 = P + R PB_1`` on the guide circle
    (eq. 14 with the horizontal line ``z = B1z``) fixes ``P_x``; leg 1's
    attachment is ``B1 + C1`` (the bracket translates), legs 2-3 ``P + R PB_k``;
    ``q_i = |X_i - A_i| - L0_i``.

    Returns :data:`IK_OK` when every ``q_i`` lies in ``[margin, stroke - margin]``
    (and, with ``arc_check``, B1 lies within the guide arc), :data:`IK_OUT`
    otherwise (``q`` untouched when the arc test fails first), :data:`IK_MISS`
    when the guide circle does not reach B1's height (``q`` untouched).
    """
    ct, st = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    r00, r01, r02 = cp, sp * st, sp * ct
    r10, r11, r12 = 0.0, ct, -st
    r20, r21, r22 = -sp, cp * st, cp * ct
    xc, zc, r = g[9], g[10], g[11]
    b1x_off = r00 * g[0] + r01 * g[1] + r02 * g[2]
    b1z = h + (r20 * g[0] + r21 * g[1] + r22 * g[2])
    dz = b1z - zc
    if arc_check and not abs(dz) < r:
        return IK_OUT
    qb = -2.0 * xc
    disc = qb * qb - 4.0 * (xc * xc + dz * dz - r * r)
    if disc < 0.0:
        return IK_MISS
    b1x = (-qb + g[12] * math.sqrt(disc)) * 0.5
    px = b1x - b1x_off
    ok = IK_OK
    lo, hi = margin, g[28] - margin
    for k in range(3):
        a, b, c = g[3 * k], g[3 * k + 1], g[3 * k + 2]
        x = r00 * a + r01 * b + r02 * c + px
        y = r10 * a + r11 * b + r12 * c
        z = r20 * a + r21 * b + r22 * c + h
        if k == 0:  # eq. (11): the bracket translates with B1
            x, y, z = x + g[13], y + g[14], z + g[15]
        dx, dy, dz2 = x - g[16 + 3 * k], y - g[17 + 3 * k], z - g[18 + 3 * k]
        qk = math.sqrt(dx * dx + dy * dy + dz2 * dz2) - g[25 + k]
        q[k] = qk
        if not (lo <= qk <= hi):  # False for NaN too
            ok = IK_OUT
    return ok


def ik_lag(roll, pitch, h, g, dq0, dq1, dq2, out):
    """``J(x)^-1 dq`` into ``out`` (3,): joint deviations as a pose deviation.

    ``J = dq/dx`` is the analytic IK Jacobian at ``x = (roll, pitch, h)``
    (rows legs, columns roll, pitch, h; :func:`controllers.kinematics.jacobian`),
    solved by Gaussian elimination with partial pivoting.
    """
    ct, st = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    rot = np.array([[cp, sp * st, sp * ct], [0.0, ct, -st], [-sp, cp * st, cp * ct]])
    d_r = np.array([[0.0, sp * ct, -sp * st], [0.0, -st, -ct], [0.0, cp * ct, -cp * st]])
    d_p = np.array([[-sp, cp * st, cp * ct], [0.0, 0.0, 0.0], [-cp, -sp * st, -sp * ct]])
    xc, zc, r, side = g[9], g[10], g[11], g[12]
    # B1's offset R PB_1 and its derivatives (columns roll, pitch, h)
    off = np.zeros(3)
    d_off = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            off[i] += rot[i, j] * g[j]
            d_off[i, 0] += d_r[i, j] * g[j]
            d_off[i, 1] += d_p[i, j] * g[j]
    b1z = h + off[2]
    dz = b1z - zc
    s = math.sqrt(r * r - dz * dz)
    b1x = xc + side * s
    px = b1x - off[0]
    d_b1z = np.array([d_off[2, 0], d_off[2, 1], 1.0])
    d_b1x = np.empty(3)
    d_px = np.empty(3)
    for c in range(3):
        d_b1x[c] = side * (-dz / s) * d_b1z[c]
        d_px[c] = d_b1x[c] - d_off[0, c]
    jac = np.empty((3, 4))  # [J | dq]
    dx = np.empty((3, 3))  # d X_k / d pose (rows x, y, z)
    x = np.empty(3)
    for k in range(3):
        if k == 0:  # X1 = B1 + C1
            x[0], x[1], x[2] = b1x + g[13], g[14], b1z + g[15]
            for c in range(3):
                dx[0, c], dx[1, c], dx[2, c] = d_b1x[c], 0.0, d_b1z[c]
        else:  # X_k = P + R PB_k
            p0, p1, p2 = g[3 * k], g[3 * k + 1], g[3 * k + 2]
            for i in range(3):
                x[i] = rot[i, 0] * p0 + rot[i, 1] * p1 + rot[i, 2] * p2
                dx[i, 0] = d_r[i, 0] * p0 + d_r[i, 1] * p1 + d_r[i, 2] * p2
                dx[i, 1] = d_p[i, 0] * p0 + d_p[i, 1] * p1 + d_p[i, 2] * p2
                dx[i, 2] = 0.0
            x[0] += px
            x[2] += h
            for c in range(3):
                dx[0, c] += d_px[c]
            dx[2, 2] += 1.0
        u0, u1, u2 = x[0] - g[16 + 3 * k], x[1] - g[17 + 3 * k], x[2] - g[18 + 3 * k]
        n = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        for c in range(3):
            jac[k, c] = (u0 * dx[0, c] + u1 * dx[1, c] + u2 * dx[2, c]) / n
    jac[0, 3], jac[1, 3], jac[2, 3] = dq0, dq1, dq2
    for col in range(3):  # Gaussian elimination, partial pivoting
        piv = col
        for i in range(col + 1, 3):
            if abs(jac[i, col]) > abs(jac[piv, col]):
                piv = i
        if piv != col:
            for j in range(4):
                jac[col, j], jac[piv, j] = jac[piv, j], jac[col, j]
        for i in range(col + 1, 3):
            f = jac[i, col] / jac[col, col]
            for j in range(col, 4):
                jac[i, j] -= f * jac[col, j]
    for i in range(2, -1, -1):
        v = jac[i, 3]
        for j in range(i + 1, 3):
            v -= jac[i, j] * out[j]
        out[i] = v / jac[i, i]


def segment_limit(x0, x1, x2, d0, d1, d2, g, margin, q):
    """Largest ``s`` in [0, 1] with ``x + s' d`` reachable for every ``s' <= s``.

    33 points per round, two rounds (resolution 1/32^2); ``x`` must be
    reachable. ``q`` (3,) is scratch.
    """
    lo, hi = 0.0, 1.0
    for _ in range(2):
        first_bad = -1
        for i in range(33):
            s = lo + (hi - lo) * (i / 32.0)
            if ik_pose(x0 + s * d0, x1 + s * d1, x2 + s * d2, g, margin, True, q) != IK_OK:
                first_bad = i
                break
        if first_bad < 0:
            return hi
        if first_bad == 0:
            return lo
        step = (hi - lo) / 32.0
        lo, hi = lo + step * (first_bad - 1), lo + step * first_bad
    return lo


# The set-point filter's constants ``fc``: kind (0 none, 1 first order, 2 ramp), then per
# leg n, a, b; its state ``fs``: per leg y, the running sum, the ring's head
FC_N, FC_A, FC_B, FC_LEN = 1, 4, 7, 10
FS_Y, FS_SUM, FS_HEAD, FS_LEN = 0, 3, 6, 9


def filter_step(fc, q0, q1, q2, fs, ring, out):
    """Fig. 13's set-point filter for one joint-loop step: q_d -> q_ref in ``out`` (3,).

    Kind 1: first order ``y = a y + b q_d`` per leg; 2: the ramp, the mean of
    the last ``n`` samples, kept as a running sum over a ring of ``ring``
    (3, n_max) whose oldest entry of leg i is at its head.
    """
    kind = fc[0]
    if kind == 0:
        out[0], out[1], out[2] = q0, q1, q2
        return
    for i in range(3):
        qi = q0 if i == 0 else (q1 if i == 1 else q2)
        if kind == 1:
            fs[FS_Y + i] = fc[FC_A + i] * fs[FS_Y + i] + fc[FC_B + i] * qi
            out[i] = fs[FS_Y + i]
        else:
            ni = int(fc[FC_N + i])
            j = int(fs[FS_HEAD + i])
            fs[FS_SUM + i] += qi - ring[i, j]
            ring[i, j] = qi
            fs[FS_HEAD + i] = (j + 1) % ni
            out[i] = fs[FS_SUM + i] / ni


# The joint controllers' constants ``jc``: u_offset, u_min, u_max, the anti-windup kind
# (0 back-calculation, 1 conditional, 2 none), T / T_t; per leg r0 T of the integrator
# and its dead band (m; 0: none); per leg [[A, B], [C, D]] (4 x 4, row-major)
J_GAIN, J_BAND, J_M, J_LEN = 5, 8, 11, 59


def joint_step(x, jc, e0, e1, e2, f0, f1, f2, v_out):
    """The three joint controllers (eq. 28) for one step; valve volts into ``v_out``.

    ``x`` (9,): states of legs 1-3 (two of the remainder, the integrator
    last), updated in place; ``jc`` their constants (:data:`J_M` ...). An
    integrator with a dead band ``w`` takes ``e -+ w`` outside ``[-w, w]``
    and holds inside (:func:`controllers.dead_band.dead_band`). ``f`` is the
    velocity feed-forward added before saturation.
    """
    off, lo, hi, kind, aw = jc[0], jc[1], jc[2], jc[3], jc[4]
    for i in range(3):
        e = e0 if i == 0 else (e1 if i == 1 else e2)
        f = f0 if i == 0 else (f1 if i == 1 else f2)
        a, b, c = x[3 * i], x[3 * i + 1], x[3 * i + 2]
        m = J_M + 16 * i
        n0 = jc[m] * a + jc[m + 1] * b + jc[m + 2] * c + jc[m + 3] * e
        n1 = jc[m + 4] * a + jc[m + 5] * b + jc[m + 6] * c + jc[m + 7] * e
        n2 = jc[m + 8] * a + jc[m + 9] * b + jc[m + 10] * c + jc[m + 11] * e
        u = jc[m + 12] * a + jc[m + 13] * b + jc[m + 14] * c + jc[m + 15] * e
        gain, band = jc[J_GAIN + i], jc[J_BAND + i]
        if band > 0.0:  # the integrator takes the error beyond its band only
            n2 = n2 - gain * (e - dead_band(e, band))
        v = u + off + f
        vs = v
        if vs < lo:  # comparisons: a NaN passes through
            vs = lo
        if vs > hi:
            vs = hi
        if kind == 0.0:
            n2 = n2 + (vs - v) * aw
        elif kind == 1.0:
            push = gain * e
            if (v > hi and push > 0.0) or (v < lo and push < 0.0):
                n2 = n2 - push
        x[3 * i], x[3 * i + 1], x[3 * i + 2] = n0, n1, n2
        v_out[i] = vs


# ---------------------------------------------------------------- the outer loop
# State of the outer loop, a flat array ``ts`` (TaskSpaceController's state):
T_XC, T_QXC, T_QXC_OK, T_QD, T_EPREV, T_CORR = 0, 3, 6, 7, 10, 13
T_PEND, T_PEND_OK, T_MODEL, T_ACC, T_NACC, T_REFCMD, T_SAT = 16, 19, 20, 23, 35, 36, 39
T_SCR, T_LEN = 40, 49  # scratch: the checked set-point, an IK result, the error
# Its constants ``tc``: mode (0 joint-only, 1 I, 2 PI, 3 feed-forward), the
# feed-forward correction's law (1 I, 2 PI), clamp, lag "joints", average,
# model_tau (s), the model's beta, the PI zero c, T K K_I (3), margin, home (3), the
# dead band of the integrated task error (3: rad, rad, m; 0: none)
TC_MODE, TC_LAW, TC_CLAMP, TC_LAGJ, TC_AVG, TC_TAU, TC_BETA, TC_PIZ = 0, 1, 2, 3, 4, 5, 6, 7
TC_TG, TC_MARGIN, TC_HOME, TC_DB, TC_LEN = 8, 11, 12, 15, 18
MODE_JOINT, MODE_I, MODE_PI, MODE_FF = 0, 1, 2, 3

#: Error codes of the step (0: none); :mod:`simpro_mj.sim.step` turns them into exceptions.
ERR_SETPOINT_NONFINITE, ERR_SETPOINT_UNREACHABLE, ERR_MEAS_NONFINITE, ERR_GUIDE = 1, 2, 3, 4


def outer_setpoint(r0, r1, r2, tc, g, q, out):
    """The set-point checked (or clamped along the segment from home) into ``out`` (3,)."""
    if not (math.isfinite(r0) and math.isfinite(r1) and math.isfinite(r2)):
        return ERR_SETPOINT_NONFINITE
    margin = tc[TC_MARGIN]
    out[0], out[1], out[2] = r0, r1, r2
    if ik_pose(r0, r1, r2, g, margin, True, q) == IK_OK:
        return 0
    if tc[TC_CLAMP] == 0.0:
        return ERR_SETPOINT_UNREACHABLE
    h0, h1, h2 = tc[TC_HOME], tc[TC_HOME + 1], tc[TC_HOME + 2]
    d0, d1, d2 = r0 - h0, r1 - h1, r2 - h2
    s = segment_limit(h0, h1, h2, d0, d1, d2, g, margin, q)
    out[0], out[1], out[2] = h0 + s * d0, h1 + s * d1, h2 + s * d2
    return 0


def _ik_xc(ts, g):
    """``IK(x_c)`` into ``ts[T_QD]``, the one the integration found when it is known."""
    if ts[T_QXC_OK] == 1.0:
        ts[T_QD : T_QD + 3] = ts[T_QXC : T_QXC + 3]
        return 0
    q = ts[T_QD : T_QD + 3]
    if ik_pose(ts[T_XC], ts[T_XC + 1], ts[T_XC + 2], g, 0.0, False, q) == IK_MISS:
        return ERR_GUIDE
    return 0


def _integrate(s0, s1, s2, ts, tc, g):
    """``x_c += step``, shortened to the farthest reachable point (conditional integration)."""
    x0, x1, x2 = ts[T_XC], ts[T_XC + 1], ts[T_XC + 2]
    q = ts[T_QXC : T_QXC + 3]
    margin = tc[TC_MARGIN]
    if ik_pose(x0 + s0, x1 + s1, x2 + s2, g, margin, True, q) == IK_OK:
        ts[T_XC], ts[T_XC + 1], ts[T_XC + 2] = x0 + s0, x1 + s1, x2 + s2
        ts[T_QXC_OK] = 1.0
        return
    s = segment_limit(x0, x1, x2, s0, s1, s2, g, margin, q)
    ts[T_XC], ts[T_XC + 1], ts[T_XC + 2] = x0 + s * s0, x1 + s * s1, x2 + s * s2
    ts[T_QXC_OK] = 0.0


def _accumulate(y0, y1, y2, with_q, qm0, qm1, qm2, ts):
    """Add this step's measurements and the last step's command to the period's sums."""
    a = T_ACC
    ts[a : a + 3] += ts[T_REFCMD : T_REFCMD + 3]
    ts[a + 3] += y0
    ts[a + 4] += y1
    ts[a + 5] += y2
    if with_q:
        ts[a + 6 : a + 9] += ts[T_QD : T_QD + 3]
        ts[a + 9] += qm0
        ts[a + 10] += qm1
        ts[a + 11] += qm2
    ts[T_NACC] += 1.0


def _ff_error(y0, y1, y2, qm0, qm1, qm2, ts, tc, g, e):
    """The error the feed-forward correction integrates (controllers.task_space)."""
    joints = tc[TC_LAGJ] != 0.0
    if tc[TC_AVG] != 0.0:
        _accumulate(y0, y1, y2, joints, qm0, qm1, qm2, ts)
        k = 1.0 / ts[T_NACC]
        a = T_ACC
        r0, r1, r2 = ts[a] * k, ts[a + 1] * k, ts[a + 2] * k
        y0, y1, y2 = ts[a + 3] * k, ts[a + 4] * k, ts[a + 5] * k
        d0, d1, d2 = ts[a + 6] * k, ts[a + 7] * k, ts[a + 8] * k
        qm0, qm1, qm2 = ts[a + 9] * k, ts[a + 10] * k, ts[a + 11] * k
        ts[a : a + 12] = 0.0
        ts[T_NACC] = 0.0
    else:
        r0, r1, r2 = ts[T_REFCMD], ts[T_REFCMD + 1], ts[T_REFCMD + 2]
        d0, d1, d2 = ts[T_QD], ts[T_QD + 1], ts[T_QD + 2]
    e[0], e[1], e[2] = r0 - y0, r1 - y1, r2 - y2
    if joints:  # the joint loops' lag, in task coordinates at the commanded pose
        lag = np.empty(3)
        ik_lag(ts[T_XC], ts[T_XC + 1], ts[T_XC + 2], g, d0 - qm0, d1 - qm1, d2 - qm2, lag)
        e[0], e[1], e[2] = e[0] - lag[0], e[1] - lag[1], e[2] - lag[2]


def _correct(ref, e, hold, ts, tc, g, q):
    """One outer step of the feed-forward correction ``c`` (I law: applied one period late)."""
    if ts[T_PEND_OK] == 1.0:
        ts[T_CORR : T_CORR + 3] = ts[T_PEND : T_PEND + 3]
        ts[T_PEND_OK] = 0.0
    if hold:
        return
    pi = tc[TC_LAW] == 2.0
    new = np.empty(3)
    for i in range(3):
        if pi:
            step = tc[TC_TG + i] * (e[i] + tc[TC_PIZ] * ts[T_EPREV + i])
            ts[T_EPREV + i] = e[i]
        else:
            step = tc[TC_TG + i] * e[i]
        new[i] = ts[T_CORR + i] + step
    p0, p1, p2 = ref[0] + new[0], ref[1] + new[1], ref[2] + new[2]
    if ik_pose(p0, p1, p2, g, tc[TC_MARGIN], True, q) == IK_OK:
        if pi:
            ts[T_CORR : T_CORR + 3] = new
        else:
            ts[T_PEND : T_PEND + 3] = new
            ts[T_PEND_OK] = 1.0


def ff_step(ref, ts, tc, g):
    """This inner step's ``q_d = IK(y_d + c)`` into ``ts[T_QD]``, the reference model advanced."""
    b = tc[TC_BETA]
    if b < 1.0:  # the reference model sees this step's set-point
        for i in range(3):
            m = ts[T_MODEL + i]
            ts[T_MODEL + i] = m + b * (ref[i] - m)
    p0, p1, p2 = ref[0] + ts[T_CORR], ref[1] + ts[T_CORR + 1], ref[2] + ts[T_CORR + 2]
    q = ts[T_QD : T_QD + 3]
    if ik_pose(p0, p1, p2, g, tc[TC_MARGIN], True, q) != IK_OK:
        # the correction pushes past the workspace: the set-point alone
        if ik_pose(ref[0], ref[1], ref[2], g, 0.0, False, q) == IK_MISS:
            return ERR_GUIDE
        p0, p1, p2 = ref[0], ref[1], ref[2]
    ts[T_XC], ts[T_XC + 1], ts[T_XC + 2] = p0, p1, p2
    src = T_MODEL if tc[TC_LAGJ] == 0.0 else -1
    for i in range(3):
        ts[T_REFCMD + i] = ref[i] if src < 0 else ts[T_MODEL + i]
    return 0


def outer_update(r0, r1, r2, y0, y1, y2, qm0, qm1, qm2, hold, ts, tc, g):
    """One outer step (eqs. 21-27): set-point and measured pose -> ``q_d`` in ``ts[T_QD]``.

    Joint-only: ``IK(y_d)``. Mode I (eq. 22, Fig. 7): output ``IK(x_c[k])``,
    then integrate ``T K K_I e[k]``; PI (section 4): integrate
    ``T K K_I (e[k] + c e[k-1])`` first; feed-forward: integrate the correction
    (held while ``hold``) and output ``IK(y_d + c)``.
    Returns an error code (0: none).
    """
    ref, q, e = ts[T_SCR : T_SCR + 3], ts[T_SCR + 3 : T_SCR + 6], ts[T_SCR + 6 : T_SCR + 9]
    err = outer_setpoint(r0, r1, r2, tc, g, q, ref)
    if err:
        return err
    mode = tc[TC_MODE]
    if mode == MODE_JOINT:  # no feedback (the class's; the step's IK(y_d) is computed ahead)
        ts[T_XC], ts[T_XC + 1], ts[T_XC + 2] = ref[0], ref[1], ref[2]
        ts[T_QXC_OK] = 0.0
        return _ik_xc(ts, g)
    if not (math.isfinite(y0) and math.isfinite(y1) and math.isfinite(y2)):
        return ERR_MEAS_NONFINITE
    e[0], e[1], e[2] = ref[0] - y0, ref[1] - y1, ref[2] - y2
    if mode == MODE_FF:  # the error the correction integrates
        if tc[TC_AVG] != 0.0 or tc[TC_LAGJ] != 0.0:
            _ff_error(y0, y1, y2, qm0, qm1, qm2, ts, tc, g, e)
        elif tc[TC_TAU] > 0.0:
            e[0], e[1], e[2] = ts[T_MODEL] - y0, ts[T_MODEL + 1] - y1, ts[T_MODEL + 2] - y2
    for j in range(3):  # the dead band: within it the integrated pose holds
        if tc[TC_DB + j] > 0.0:
            e[j] = dead_band(e[j], tc[TC_DB + j])
    if mode == MODE_FF:
        _correct(ref, e, hold, ts, tc, g, q)
        return ff_step(ref, ts, tc, g)
    if mode == MODE_I:
        err = _ik_xc(ts, g)
        _integrate(tc[TC_TG] * e[0], tc[TC_TG + 1] * e[1], tc[TC_TG + 2] * e[2], ts, tc, g)
        return err
    c = tc[TC_PIZ]
    s0 = tc[TC_TG] * (e[0] + c * ts[T_EPREV])
    s1 = tc[TC_TG + 1] * (e[1] + c * ts[T_EPREV + 1])
    s2 = tc[TC_TG + 2] * (e[2] + c * ts[T_EPREV + 2])
    _integrate(s0, s1, s2, ts, tc, g)
    ts[T_EPREV], ts[T_EPREV + 1], ts[T_EPREV + 2] = e[0], e[1], e[2]
    return _ik_xc(ts, g)


def ff_inner(r0, r1, r2, y0, y1, y2, qm0, qm1, qm2, acc, ts, tc, g):
    """A feed-forward inner step between outer steps: ``q_d = IK(y_d + c)``.

    With ``average`` the step's measurements go into the outer period's sums:
    ``acc`` 1 the pose, 2 the pose and the joints, 0 none.
    """
    ref, q = ts[T_SCR : T_SCR + 3], ts[T_SCR + 3 : T_SCR + 6]
    err = outer_setpoint(r0, r1, r2, tc, g, q, ref)
    if err:
        return err
    if tc[TC_AVG] != 0.0 and acc > 0:
        _accumulate(y0, y1, y2, acc == 2, qm0, qm1, qm2, ts)
    return ff_step(ref, ts, tc, g)
