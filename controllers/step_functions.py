"""The controllers' part of one 1 ms step, as plain functions on flat float64 arrays.

The one implementation of the per-step controller arithmetic (this
package's classes configure it and keep their array APIs on top), in the
subset numba compiles (scalar ``math``, loops, indexing):
:mod:`simpro_mj.sim.step` runs it interpreted or compiled. No MuJoCo here.

Each block's layout (:func:`controllers.layout.layout`) is declared once
below: :data:`GEOM` (the geometry), :data:`FC`, :data:`FS` (the set-point
filter), :data:`JC` (the joint loops), :data:`TS`, :data:`TC` (the outer loop).
"""

from __future__ import annotations

import math

import numpy as np

from .dead_band import dead_band, gap, held
from .layout import layout

__all__ = [
    "GEOM",
    "geometry_constants",
    "ik_pose",
    "ik_lag",
    "segment_limit",
    "filter_step",
    "joint_step",
]

#: the geometry constants ``g`` (:func:`geometry_constants`): platform points PB_1..PB_3
#: (row-major, platform frame), the guide's centre x_c, z_c, radius r and side (-1 or
#: +1), the bracket offset C1 (eq. 11), base points A_1..A_3 (row-major), retracted
#: lengths L0_i, the stroke
GEOM = layout("Geometry", pb=9, xc=1, zc=1, r=1, side=1, c1=3, base=9, l0=3, stroke=1)

#: ik_pose's results: reachable, outside the workspace, guide circle missed (disc < 0)
IK_OK, IK_OUT, IK_MISS = 1, 0, -1


def geometry_constants(geometry) -> np.ndarray:
    """The flat constants array ``g`` of a :class:`~controllers.geometry.PlatformGeometry`."""
    G = geometry
    return GEOM.pack(
        pb=G.platform_points, xc=G.guide_centre[0], zc=G.guide_centre[1], r=G.guide_radius,
        side=G.guide_side, c1=G.bracket_c1, base=G.base_points, l0=G.retracted_length,
        stroke=G.stroke,
    )  # fmt: skip


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
    xc, zc, r = g[GEOM.xc], g[GEOM.zc], g[GEOM.r]
    pb = GEOM.pb
    b1x_off = r00 * g[pb] + r01 * g[pb + 1] + r02 * g[pb + 2]
    b1z = h + (r20 * g[pb] + r21 * g[pb + 1] + r22 * g[pb + 2])
    dz = b1z - zc
    if arc_check and not abs(dz) < r:
        return IK_OUT
    qb = -2.0 * xc
    disc = qb * qb - 4.0 * (xc * xc + dz * dz - r * r)
    if disc < 0.0:
        return IK_MISS
    b1x = (-qb + g[GEOM.side] * math.sqrt(disc)) * 0.5
    px = b1x - b1x_off
    ok = IK_OK
    lo, hi = margin, g[GEOM.stroke] - margin
    for k in range(3):
        a, b, c = g[pb + 3 * k], g[pb + 3 * k + 1], g[pb + 3 * k + 2]
        x = r00 * a + r01 * b + r02 * c + px
        y = r10 * a + r11 * b + r12 * c
        z = r20 * a + r21 * b + r22 * c + h
        if k == 0:  # eq. (11): the bracket translates with B1
            x, y, z = x + g[GEOM.c1], y + g[GEOM.c1 + 1], z + g[GEOM.c1 + 2]
        ia = GEOM.base + 3 * k
        dx, dy, dz2 = x - g[ia], y - g[ia + 1], z - g[ia + 2]
        qk = math.sqrt(dx * dx + dy * dy + dz2 * dz2) - g[GEOM.l0 + k]
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
    xc, zc, r, side = g[GEOM.xc], g[GEOM.zc], g[GEOM.r], g[GEOM.side]
    # B1's offset R PB_1 and its derivatives (columns roll, pitch, h)
    off = np.zeros(3)
    d_off = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            off[i] += rot[i, j] * g[GEOM.pb + j]
            d_off[i, 0] += d_r[i, j] * g[GEOM.pb + j]
            d_off[i, 1] += d_p[i, j] * g[GEOM.pb + j]
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
            x[0], x[1], x[2] = b1x + g[GEOM.c1], g[GEOM.c1 + 1], b1z + g[GEOM.c1 + 2]
            for c in range(3):
                dx[0, c], dx[1, c], dx[2, c] = d_b1x[c], 0.0, d_b1z[c]
        else:  # X_k = P + R PB_k
            ib = GEOM.pb + 3 * k
            p0, p1, p2 = g[ib], g[ib + 1], g[ib + 2]
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
        ia = GEOM.base + 3 * k
        u0, u1, u2 = x[0] - g[ia], x[1] - g[ia + 1], x[2] - g[ia + 2]
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
FC = layout("FilterConstants", kind=1, n=3, a=3, b=3)
FS = layout("FilterState", y=3, sum=3, head=3)


def filter_step(fc, q0, q1, q2, fs, ring, out):
    """Fig. 13's set-point filter for one joint-loop step: q_d -> q_ref in ``out`` (3,).

    Kind 1: first order ``y = a y + b q_d`` per leg; 2: the ramp, the mean of
    the last ``n`` samples, kept as a running sum over a ring of ``ring``
    (3 rows of n_max, flat, row-major: the step keeps it at the end of its
    state) whose oldest entry of leg i is at its head.
    """
    kind = fc[FC.kind]
    if kind == 0:
        out[0], out[1], out[2] = q0, q1, q2
        return
    row = ring.shape[0] // 3
    for i in range(3):
        qi = q0 if i == 0 else (q1 if i == 1 else q2)
        if kind == 1:
            fs[FS.y + i] = fc[FC.a + i] * fs[FS.y + i] + fc[FC.b + i] * qi
            out[i] = fs[FS.y + i]
        else:
            ni = int(fc[FC.n + i])
            j = int(fs[FS.head + i])
            fs[FS.sum + i] += qi - ring[i * row + j]
            ring[i * row + j] = qi
            fs[FS.head + i] = (j + 1) % ni
            out[i] = fs[FS.sum + i] / ni


# One leg's joint controller state (``x`` holds the three legs'): two states of the
# remainder C_r, the integrator last
JX = layout("JointLegState", r1=1, r2=1, i=1)
#: one leg's [[A, B], [C, D]] (the state and the error in, the state and the volts out)
JM = (JX.LEN + 1) ** 2
# The joint controllers' state: the three legs' JX, then per leg whether its dead band
# holds the integrator (the band's release)
JS = layout("JointState", x=3 * JX.LEN, held=3)
# The joint controllers' constants ``jc``: u_offset, u_min, u_max, the anti-windup kind
# (0 back-calculation, 1 conditional, 2 none), T / T_t; per leg r0 T of the integrator
# and its dead band (m; 0: none); the band's release (the error that ends a hold, in
# band widths; 1: none); per leg [[A, B], [C, D]] (JM entries, row-major)
JC = layout("JointConstants", off=1, lo=1, hi=1, kind=1, aw=1, gain=3, band=3, rel=1, m=3 * JM)


def _row(jc, k, a, b, c, e):
    """A row of a leg's ``[[A, B], [C, D]]`` (from ``jc[k]``) times its states and error."""
    return jc[k + JX.r1] * a + jc[k + JX.r2] * b + jc[k + JX.i] * c + jc[k + JX.LEN] * e


def joint_step(x, jc, e0, e1, e2, f0, f1, f2, v_out):
    """The three joint controllers (eq. 28) for one step; valve volts into ``v_out``.

    ``x`` (:data:`JS`): states of legs 1-3 (each a :data:`JX`: two of the
    remainder, the integrator last) and their bands' holds, updated in place;
    ``jc`` their constants (:data:`JC`). An integrator with a dead band ``w``
    takes ``e -+ w`` outside ``[-w, w]`` and holds inside
    (:func:`controllers.dead_band.dead_band`); with a release ``r > 1`` it holds
    from the step the error enters ``[-w, w]`` until it leaves ``[-r w, r w]``
    (:func:`controllers.dead_band.held`): a leg that passed its set-point and
    stopped within ``r w`` beyond it is not pushed back through its seals. ``f``
    is the velocity feed-forward added before saturation.
    """
    off, lo, hi, kind, aw = jc[JC.off], jc[JC.lo], jc[JC.hi], jc[JC.kind], jc[JC.aw]
    for i in range(3):
        e = e0 if i == 0 else (e1 if i == 1 else e2)
        f = f0 if i == 0 else (f1 if i == 1 else f2)
        o = JS.x + JX.LEN * i
        a, b, c = x[o + JX.r1], x[o + JX.r2], x[o + JX.i]
        m, w = JC.m + JM * i, JX.LEN + 1  # the leg's matrix, its row length
        n0 = _row(jc, m + w * JX.r1, a, b, c, e)
        n1 = _row(jc, m + w * JX.r2, a, b, c, e)
        n2 = _row(jc, m + w * JX.i, a, b, c, e)
        u = _row(jc, m + w * JX.LEN, a, b, c, e)  # the output row: C and D
        gain, band = jc[JC.gain + i], jc[JC.band + i]
        if band > 0.0:  # the integrator takes the error beyond its band only
            db = 0.0 if held(e, band, jc[JC.rel], x, JS.held + i) else dead_band(e, band)
            n2 = n2 - gain * (e - db)
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
        x[o + JX.r1], x[o + JX.r2], x[o + JX.i] = n0, n1, n2
        v_out[i] = vs


# ---------------------------------------------------------------- the outer loop
# State of the outer loop, a flat array ``ts`` (TaskSpaceController's state): the pose
# command x_c, IK(x_c) and whether it is known, q_d, the last error (PI), the correction
# c, the pending one (I law) and whether it is, the reference model, the outer period's
# sums (of the command, the pose, q_d, the joints) and their count, the last command, a
# valve at its rail, per axis whether the dead band holds the law (its release);
# scratch: the checked set-point, an IK result, the error
TS = layout(
    "TaskState", xc=3, qxc=3, qxc_ok=1, qd=3, eprev=3, corr=3, pend=3, pend_ok=1, model=3,
    acc_ref=3, acc_y=3, acc_qd=3, acc_qm=3, nacc=1, refcmd=3, sat=1, held=3, scr_ref=3,
    scr_q=3, scr_e=3,
)  # fmt: skip
# Its constants ``tc``: mode (0 joint-only, 1 I, 2 PI, 3 feed-forward), the
# feed-forward correction's law (1 I, 2 PI), clamp, lag "joints", average,
# model_tau (s), the model's beta, the PI zero c, T K K_I (3), margin, home (3), the
# dead band of the integrated task error (3: rad, rad, m; 0: none), its kind (0
# subtract, 1 gap) and its release (the error that ends a hold, in band widths; 1:
# none); the I/PI law's joint lag (0 none, 1 joints) and the joint dead bands it
# leaves in the error (3, m)
TC = layout(
    "TaskConstants", mode=1, law=1, clamp=1, lagj=1, avg=1, tau=1, beta=1, piz=1, tg=3,
    margin=1, home=3, db=3, dbgap=1, dbrel=1, jlag=1, jband=3,
)  # fmt: skip
MODE_JOINT, MODE_I, MODE_PI, MODE_FF = 0, 1, 2, 3

#: Error codes of the step (0: none); :mod:`simpro_mj.sim.step` turns them into exceptions.
ERR_SETPOINT_NONFINITE, ERR_SETPOINT_UNREACHABLE, ERR_MEAS_NONFINITE, ERR_GUIDE = 1, 2, 3, 4


def outer_setpoint(r0, r1, r2, tc, g, q, out):
    """The set-point checked (or clamped along the segment from home) into ``out`` (3,)."""
    if not (math.isfinite(r0) and math.isfinite(r1) and math.isfinite(r2)):
        return ERR_SETPOINT_NONFINITE
    margin = tc[TC.margin]
    out[0], out[1], out[2] = r0, r1, r2
    if ik_pose(r0, r1, r2, g, margin, True, q) == IK_OK:
        return 0
    if tc[TC.clamp] == 0.0:
        return ERR_SETPOINT_UNREACHABLE
    h0, h1, h2 = tc[TC.home], tc[TC.home + 1], tc[TC.home + 2]
    d0, d1, d2 = r0 - h0, r1 - h1, r2 - h2
    s = segment_limit(h0, h1, h2, d0, d1, d2, g, margin, q)
    out[0], out[1], out[2] = h0 + s * d0, h1 + s * d1, h2 + s * d2
    return 0


def _ik_xc(ts, g):
    """``IK(x_c)`` into ``ts[TS.qd]``, the one the integration found when it is known."""
    if ts[TS.qxc_ok] == 1.0:
        ts[TS.qd : TS.qd + 3] = ts[TS.qxc : TS.qxc + 3]
        return 0
    q = ts[TS.qd : TS.qd + 3]
    if ik_pose(ts[TS.xc], ts[TS.xc + 1], ts[TS.xc + 2], g, 0.0, False, q) == IK_MISS:
        return ERR_GUIDE
    return 0


def _integrate(s0, s1, s2, ts, tc, g):
    """``x_c += step``, shortened to the farthest reachable point (conditional integration)."""
    x0, x1, x2 = ts[TS.xc], ts[TS.xc + 1], ts[TS.xc + 2]
    q = ts[TS.qxc : TS.qxc + 3]
    margin = tc[TC.margin]
    if ik_pose(x0 + s0, x1 + s1, x2 + s2, g, margin, True, q) == IK_OK:
        ts[TS.xc], ts[TS.xc + 1], ts[TS.xc + 2] = x0 + s0, x1 + s1, x2 + s2
        ts[TS.qxc_ok] = 1.0
        return
    s = segment_limit(x0, x1, x2, s0, s1, s2, g, margin, q)
    ts[TS.xc], ts[TS.xc + 1], ts[TS.xc + 2] = x0 + s * s0, x1 + s * s1, x2 + s * s2
    ts[TS.qxc_ok] = 0.0


def _accumulate(y0, y1, y2, with_q, qm0, qm1, qm2, ts):
    """Add this step's measurements and the last step's command to the period's sums."""
    ts[TS.acc_ref : TS.acc_ref + 3] += ts[TS.refcmd : TS.refcmd + 3]
    ts[TS.acc_y] += y0
    ts[TS.acc_y + 1] += y1
    ts[TS.acc_y + 2] += y2
    if with_q:
        ts[TS.acc_qd : TS.acc_qd + 3] += ts[TS.qd : TS.qd + 3]
        ts[TS.acc_qm] += qm0
        ts[TS.acc_qm + 1] += qm1
        ts[TS.acc_qm + 2] += qm2
    ts[TS.nacc] += 1.0


def _ff_error(y0, y1, y2, qm0, qm1, qm2, ts, tc, g, e):
    """The error the feed-forward correction integrates (controllers.task_space)."""
    joints = tc[TC.lagj] != 0.0
    if tc[TC.avg] != 0.0:
        _accumulate(y0, y1, y2, joints, qm0, qm1, qm2, ts)
        k = 1.0 / ts[TS.nacc]
        a, b, c, d = TS.acc_ref, TS.acc_y, TS.acc_qd, TS.acc_qm
        r0, r1, r2 = ts[a] * k, ts[a + 1] * k, ts[a + 2] * k
        y0, y1, y2 = ts[b] * k, ts[b + 1] * k, ts[b + 2] * k
        d0, d1, d2 = ts[c] * k, ts[c + 1] * k, ts[c + 2] * k
        qm0, qm1, qm2 = ts[d] * k, ts[d + 1] * k, ts[d + 2] * k
        ts[TS.acc_ref : TS.acc_qm + 3] = 0.0  # the four sums
        ts[TS.nacc] = 0.0
    else:
        r0, r1, r2 = ts[TS.refcmd], ts[TS.refcmd + 1], ts[TS.refcmd + 2]
        d0, d1, d2 = ts[TS.qd], ts[TS.qd + 1], ts[TS.qd + 2]
    e[0], e[1], e[2] = r0 - y0, r1 - y1, r2 - y2
    if joints:  # the joint loops' lag, in task coordinates at the commanded pose
        _less_lag(d0 - qm0, d1 - qm1, d2 - qm2, ts, g, e)


def _correct(ref, e, hold, ts, tc, g, q):
    """One outer step of the feed-forward correction ``c`` (I law: applied one period late)."""
    if ts[TS.pend_ok] == 1.0:
        ts[TS.corr : TS.corr + 3] = ts[TS.pend : TS.pend + 3]
        ts[TS.pend_ok] = 0.0
    if hold:
        return
    pi = tc[TC.law] == 2.0
    new = np.empty(3)
    for i in range(3):
        if pi:
            step = tc[TC.tg + i] * (e[i] + tc[TC.piz] * ts[TS.eprev + i])
            ts[TS.eprev + i] = e[i]
        else:
            step = tc[TC.tg + i] * e[i]
        new[i] = ts[TS.corr + i] + step
    p0, p1, p2 = ref[0] + new[0], ref[1] + new[1], ref[2] + new[2]
    if ik_pose(p0, p1, p2, g, tc[TC.margin], True, q) == IK_OK:
        if pi:
            ts[TS.corr : TS.corr + 3] = new
        else:
            ts[TS.pend : TS.pend + 3] = new
            ts[TS.pend_ok] = 1.0


def _less_lag(dq0, dq1, dq2, ts, g, e):
    """``e -= J(x_c)^-1 dq``: the joint deviations ``dq`` taken out of the task error."""
    lag = np.empty(3)
    ik_lag(ts[TS.xc], ts[TS.xc + 1], ts[TS.xc + 2], g, dq0, dq1, dq2, lag)
    e[0], e[1], e[2] = e[0] - lag[0], e[1] - lag[1], e[2] - lag[2]


def _less_joint_lag(qm0, qm1, qm2, ts, tc, g, e):
    """``e -= J(x_c)^-1 db(q_d - q_meas)``: the task error less what the joint loops
    are still delivering (the I/PI law's ``joint_lag: joints``).

    ``q_d = IK(x_c)`` is the joint set-point the legs have been given, ``db`` each
    leg's dead band (``TC.jband``): a leg that its seals hold within its band is not
    catching up, and its error stays in ``e`` for the law to remove.
    """
    d0 = dead_band(ts[TS.qd] - qm0, tc[TC.jband])
    d1 = dead_band(ts[TS.qd + 1] - qm1, tc[TC.jband + 1])
    d2 = dead_band(ts[TS.qd + 2] - qm2, tc[TC.jband + 2])
    _less_lag(d0, d1, d2, ts, g, e)


def ff_step(ref, ts, tc, g):
    """This inner step's ``q_d = IK(y_d + c)`` into ``ts[TS.qd]``, the reference model advanced."""
    b = tc[TC.beta]
    if b < 1.0:  # the reference model sees this step's set-point
        for i in range(3):
            m = ts[TS.model + i]
            ts[TS.model + i] = m + b * (ref[i] - m)
    p0, p1, p2 = ref[0] + ts[TS.corr], ref[1] + ts[TS.corr + 1], ref[2] + ts[TS.corr + 2]
    q = ts[TS.qd : TS.qd + 3]
    if ik_pose(p0, p1, p2, g, tc[TC.margin], True, q) != IK_OK:
        # the correction pushes past the workspace: the set-point alone
        if ik_pose(ref[0], ref[1], ref[2], g, 0.0, False, q) == IK_MISS:
            return ERR_GUIDE
        p0, p1, p2 = ref[0], ref[1], ref[2]
    ts[TS.xc], ts[TS.xc + 1], ts[TS.xc + 2] = p0, p1, p2
    src = TS.model if tc[TC.lagj] == 0.0 else -1
    for i in range(3):
        ts[TS.refcmd + i] = ref[i] if src < 0 else ts[TS.model + i]
    return 0


def _banded(e, w, j, ts, tc):
    """Axis ``j``'s error as the law integrates it, through its dead band ``w``.

    Without a release (``TC.dbrel`` 1) :func:`~controllers.dead_band.dead_band` or
    :func:`~controllers.dead_band.gap` of ``e``. With a release ``r > 1`` the band
    holds the law from the step the error enters ``[-w, w]`` until it leaves
    ``[-r w, r w]`` (:func:`~controllers.dead_band.held`, ``TS.held``).
    """
    if held(e, w, tc[TC.dbrel], ts, TS.held + j):
        return 0.0
    return gap(e, w) if tc[TC.dbgap] else dead_band(e, w)


def outer_update(r0, r1, r2, y0, y1, y2, qm0, qm1, qm2, hold, ts, tc, g):
    """One outer step (eqs. 21-27): set-point and measured pose -> ``q_d`` in ``ts[TS.qd]``.

    Joint-only: ``IK(y_d)``. Mode I (eq. 22, Fig. 7): output ``IK(x_c[k])``,
    then integrate ``T K K_I e[k]``; PI (section 4): integrate
    ``T K K_I (e[k] + c e[k-1])`` first; feed-forward: integrate the correction
    (held while ``hold``) and output ``IK(y_d + c)``. With ``TC.jlag`` the I and
    PI laws integrate ``e`` less the joint loops' lag (:func:`_less_joint_lag`).
    Returns an error code (0: none).
    """
    ref, q = ts[TS.scr_ref : TS.scr_ref + 3], ts[TS.scr_q : TS.scr_q + 3]
    e = ts[TS.scr_e : TS.scr_e + 3]
    err = outer_setpoint(r0, r1, r2, tc, g, q, ref)
    if err:
        return err
    mode = tc[TC.mode]
    if mode == MODE_JOINT:  # no feedback (the class's; the step's IK(y_d) is computed ahead)
        ts[TS.xc], ts[TS.xc + 1], ts[TS.xc + 2] = ref[0], ref[1], ref[2]
        ts[TS.qxc_ok] = 0.0
        return _ik_xc(ts, g)
    if not (math.isfinite(y0) and math.isfinite(y1) and math.isfinite(y2)):
        return ERR_MEAS_NONFINITE
    e[0], e[1], e[2] = ref[0] - y0, ref[1] - y1, ref[2] - y2
    if mode == MODE_FF:  # the error the correction integrates
        if tc[TC.avg] != 0.0 or tc[TC.lagj] != 0.0:
            _ff_error(y0, y1, y2, qm0, qm1, qm2, ts, tc, g, e)
        elif tc[TC.tau] > 0.0:
            e[0], e[1], e[2] = ts[TS.model] - y0, ts[TS.model + 1] - y1, ts[TS.model + 2] - y2
    if mode != MODE_FF and tc[TC.jlag] != 0.0:
        _less_joint_lag(qm0, qm1, qm2, ts, tc, g, e)
    for j in range(3):  # the dead band: within it the integrated pose holds
        if tc[TC.db + j] > 0.0:
            e[j] = _banded(e[j], tc[TC.db + j], j, ts, tc)
    if mode == MODE_FF:
        _correct(ref, e, hold, ts, tc, g, q)
        return ff_step(ref, ts, tc, g)
    if mode == MODE_I:
        err = _ik_xc(ts, g)
        _integrate(tc[TC.tg] * e[0], tc[TC.tg + 1] * e[1], tc[TC.tg + 2] * e[2], ts, tc, g)
        return err
    c = tc[TC.piz]
    s0 = tc[TC.tg] * (e[0] + c * ts[TS.eprev])
    s1 = tc[TC.tg + 1] * (e[1] + c * ts[TS.eprev + 1])
    s2 = tc[TC.tg + 2] * (e[2] + c * ts[TS.eprev + 2])
    _integrate(s0, s1, s2, ts, tc, g)
    ts[TS.eprev], ts[TS.eprev + 1], ts[TS.eprev + 2] = e[0], e[1], e[2]
    return _ik_xc(ts, g)


def ff_inner(r0, r1, r2, y0, y1, y2, qm0, qm1, qm2, acc, ts, tc, g):
    """A feed-forward inner step between outer steps: ``q_d = IK(y_d + c)``.

    With ``average`` the step's measurements go into the outer period's sums:
    ``acc`` 1 the pose, 2 the pose and the joints, 0 none.
    """
    ref, q = ts[TS.scr_ref : TS.scr_ref + 3], ts[TS.scr_q : TS.scr_q + 3]
    err = outer_setpoint(r0, r1, r2, tc, g, q, ref)
    if err:
        return err
    if tc[TC.avg] != 0.0 and acc > 0:
        _accumulate(y0, y1, y2, acc == 2, qm0, qm1, qm2, ts)
    return ff_step(ref, ts, tc, g)
