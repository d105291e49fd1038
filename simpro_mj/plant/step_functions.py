"""The plant's part of one 1 ms step, as plain functions on flat float64 arrays.

The one implementation of the state read, the sensor models and the
actuator models per step (:class:`~simpro_mj.plant.sensors.SensorConfig` and
the actuator classes configure them), in the subset numba compiles:
:mod:`simpro_mj.sim.step` runs them interpreted or compiled. Each stage is a
small named function so that a plant change (a friction law, a sensor
error) is made in one place.
"""

from __future__ import annotations

import math

from simpro_mj.plant.friction import seal_friction
from simpro_mj.plant.sensor_errors import accel_tilt, pot_nonlinearity

__all__ = [
    "slide_states",
    "platform_pose",
    "loop_closure",
    "clip",
    "quantise",
    "imu_input",
    "sample_sensors",
    "nonlinear_step",
    "slide_forces",
    "linear_step",
]

# sensor constants sc: SensorConfig's fields in their order (SensorConfig.step_constants),
# then 1 / dt^2; the sensor errors (simpro_mj.plant.sensor_errors) are the track's full
# scale and linearity, the bias walk's step per IMU sample (0: off), the accelerometer's weight
SC_LSB, SC_SIGMA, SC_LO, SC_HI, SC_OFF, SC_GAIN, SC_FS, SC_NL = 0, 1, 2, 3, 4, 7, 10, 11
SC_POT_EVERY, SC_RES, SC_ENC_NOISE, SC_ENC_EVERY, SC_SIGMA_IMU, SC_BIAS = 12, 13, 14, 15, 16, 17
SC_WALK, SC_ACCW, SC_ALPHA, SC_IMU_EVERY, SC_IDT2, SC_LEN = 19, 20, 21, 22, 24, 25
# the sensors' own state (an array ``ss``): the IMU filter (2), the bias walk (2), the
# IMU site's last two positions (6) and how many are known, the complementary filter's
# low-passed accelerometer tilt error (2)
SS_IMU, SS_WALK, SS_HIST, SS_HN, SS_ACC, SS_LEN = 0, 2, 4, 10, 11, 13

# actuator state ast: chamber pressures p1 (3), p2 (3), spool (3), spool rate (3), each
# ψ-table edge's last cell (12), the supply pressure, the linear model's φ (3), force bounds,
# the chamber gas temperatures (6; the energy model's, 0: the wall's)
A_P, A_SPOOL, A_RATE, A_CELL, A_PS, A_PHI, A_FMIN, A_FMAX, A_T = 0, 6, 9, 12, 24, 25, 28, 29, 30
# the supply's state: the receiver's pressure, this step's draw through the valves'
# supply edges (kg/s), the compressor running (1) or not
A_PR, A_DRAW, A_COMP, A_LEN = 36, 37, 38, 39
# actuator constants ac (the actuator classes' step_constants): both kinds', then the kind's own
AC_KIND, AC_PA, AC_A1, AC_A2, AC_AR = 0, 1, 2, 3, 4
# nonlinear
AC_RTK, AC_EPS, AC_HN, AC_ALPHA, AC_ORDER, AC_NSUB, AC_NTAB = 5, 6, 7, 8, 9, 10, 11
# per leg the seal friction (breakaway, Coulomb, Stribeck velocity, viscous, v_reg: 5 x 3),
# the second-order spool (6), the underlaps (3), per chamber V0, dV/dq, V_min (6 x 3),
# the energy model (TH_*: 7), per chamber the wall
# area's constant and volume terms (6 x 2), the ψ table (grid, values, slopes)
AC_FRIC, AC_AD, AC_DELTA, AC_CH, AC_TH, AC_AW, AC_SUP, AC_TAB = 12, 27, 33, 36, 54, 61, 73, 83
# the energy model's constants: on (1) or polytropic (0), γ, R, k (kg/(s Pa)), the wall's
# temperature (K; the supply's and the atmosphere's too), h_w (W/(m^2 K)), the sub-step (s)
TH_ON, TH_GAMMA, TH_R, TH_K, TH_TW, TH_HW, TH_H = 0, 1, 2, 3, 4, 5, 6
# the supply as built (supply_step): on (1) or an ideal source (0), R T / V of the
# receiver and of the line (Pa/kg), the regulator's conductance (kg/(s Pa)) and set
# point (Pa), the compressor's delivery (kg/s), cut-in and cut-out (Pa), the step (s)
SUP_ON, SUP_RTV_R, SUP_RTV_L, SUP_KREG, SUP_PSET, SUP_QC, SUP_PON, SUP_POFF, SUP_H = range(9)
# linear (eq. 19): b, a0, exp(-a1 dt), its integral, u_hold, F_hold, q_0, M_q, D_q, K_q,
# saturate, the display pressures at rest p10, p20
AC_LB, AC_LA0, AC_EA, AC_IA, AC_UHOLD, AC_FHOLD, AC_Q0 = 5, 8, 11, 14, 17, 20, 23
AC_MQ, AC_DQ, AC_KQ, AC_SAT, AC_P10, AC_P20, AC_LIN_LEN = 26, 35, 44, 53, 54, 57, 60


def slide_states(qpos, qvel, iq, iv, q, qd):
    """The three slides' positions and speeds from MuJoCo's state into ``q``, ``qd``."""
    for i in range(3):
        q[i] = qpos[int(iq[i])]
        qd[i] = qvel[int(iv[i])]


def platform_pose(xmat, xpos, i_mat, i_h, pose):
    """Roll, pitch (``R = Ry(pitch) Rx(roll)``) and height of the platform site into ``pose``."""
    r = int(i_mat)
    pose[0] = math.atan2(xmat[r + 7], xmat[r + 8])
    pose[1] = math.atan2(-xmat[r + 6], xmat[r])
    pose[2] = xpos[int(i_h)]


def loop_closure(xpos, pairs, npair):
    """Largest distance between the two sites of each closed loop (m); NaN passed on."""
    worst = 0.0
    for p in range(int(npair)):
        a = int(pairs[2 * p])
        c = int(pairs[2 * p + 1])
        dx, dy, dz = xpos[a] - xpos[c], xpos[a + 1] - xpos[c + 1], xpos[a + 2] - xpos[c + 2]
        e = dx * dx + dy * dy + dz * dz
        if e > worst:
            worst = e
        elif e != e:
            return e
    return math.sqrt(worst)


def clip(v, lo, hi):
    """``v`` within ``[lo, hi]``; NaN passed on (the comparisons are false)."""
    if v < lo:
        v = lo
    if v > hi:
        v = hi
    return v


def quantise(v, step):
    """``v`` rounded to a multiple of ``step``, half to even (an ADC's code); NaN, inf kept."""
    x = v / step
    if not math.isfinite(x):
        return x * step
    r = float(math.floor(x))
    d = x - r
    if d > 0.5 or (d == 0.5 and r % 2.0 != 0.0):
        r += 1.0
    return r * step


def imu_input(roll, pitch, site, sc, ss):
    """The IMU filter's input: the true angles plus what a complementary filter lets
    through of the accelerometer's tilt error.

    The accelerometer reads the tilt of the specific force at the IMU site (its
    acceleration from the second difference of its last three positions,
    :func:`simpro_mj.plant.sensor_errors.accel_tilt`); a complementary filter
    trusts it below its crossover f_c and the gyro above, so the attitude it
    gives is the true one plus the accelerometer's error low-passed at f_c
    (``sc[SC_ACCW]`` = 1 - exp(-2 π f_c dt); 0: the gyro alone). A 7 Hz cycle
    passes 1.4 % of its acceleration's tilt at f_c = 0.1 Hz, a sustained tilt
    error all of it.
    """
    w = sc[SC_ACCW]
    if not w > 0.0:
        return roll, pitch
    x, y, z = site[0], site[1], site[2]
    h = SS_HIST
    x1, y1, z1 = ss[h], ss[h + 1], ss[h + 2]
    x2, y2, z2 = ss[h + 3], ss[h + 4], ss[h + 5]
    ss[h + 3], ss[h + 4], ss[h + 5] = x1, y1, z1
    ss[h], ss[h + 1], ss[h + 2] = x, y, z
    if ss[SS_HN] < 2.0:  # the first two positions of a run: no acceleration yet
        ss[SS_HN] += 1.0
        return roll, pitch
    idt2 = sc[SC_IDT2]
    ax = ((x - x2) - 2.0 * (x1 - x2)) * idt2
    ay = ((y - y2) - 2.0 * (y1 - y2)) * idt2
    az = ((z - z2) - 2.0 * (z1 - z2)) * idt2
    ra, pa = accel_tilt(ax, ay, az, roll, pitch)
    ss[SS_ACC] += w * ((ra - roll) - ss[SS_ACC])
    ss[SS_ACC + 1] += w * ((pa - pitch) - ss[SS_ACC + 1])
    return roll + ss[SS_ACC], pitch + ss[SS_ACC + 1]


def sample_sensors(k, force, q, pose, site, noise, walk, sc, ss, qm, pm):
    """The sensors at step ``k`` (section 5): potentiometers, height encoder, IMU.

    ``noise`` (6,): this step's standard normal draws (3 potentiometers, the
    encoder, 2 IMU axes); ``walk`` (2,): the bias walk's draws for this step's
    IMU sample. The IMU's first-order output filter (``ss``) runs every step
    on :func:`imu_input` (``site``: the IMU site's position, or None); each
    sensor updates its reading (``qm``, ``pm``) at its own rate (zero-order
    hold between), all of them when ``force``, as
    :class:`~simpro_mj.plant.sensors.SensorConfig` states. Returns 1 when the
    IMU sampled (a walk row used), else 0.
    """
    alpha = sc[SC_ALPHA]
    r_in, p_in = pose[0], pose[1]
    if site is not None:
        r_in, p_in = imu_input(r_in, p_in, site, sc, ss)
    ss[SS_IMU] = ss[SS_IMU] + alpha * (r_in - ss[SS_IMU])
    ss[SS_IMU + 1] = ss[SS_IMU + 1] + alpha * (p_in - ss[SS_IMU + 1])
    if force or k % int(sc[SC_POT_EVERY]) == 0:
        sigma, lsb, lo, hi = sc[SC_SIGMA], sc[SC_LSB], sc[SC_LO], sc[SC_HI]
        fs, nl = sc[SC_FS], sc[SC_NL]
        for j in range(3):
            if nl > 0.0:
                e = pot_nonlinearity(q[j], fs, nl)
                v = sc[SC_GAIN + j] * q[j] + sc[SC_OFF + j] + e + sigma * noise[j]
            else:
                v = sc[SC_GAIN + j] * q[j] + sc[SC_OFF + j] + sigma * noise[j]
            qm[j] = clip(quantise(v, lsb), lo, hi)
    if force or k % int(sc[SC_ENC_EVERY]) == 0:
        h = pose[2] + sc[SC_ENC_NOISE] * noise[3]
        if sc[SC_RES] > 0.0:
            h = quantise(h, sc[SC_RES])
        pm[2] = h
    if force or k % int(sc[SC_IMU_EVERY]) == 0:
        s = sc[SC_SIGMA_IMU]
        used = 0
        if sc[SC_WALK] > 0.0:
            ss[SS_WALK] = ss[SS_WALK] + sc[SC_WALK] * walk[0]
            ss[SS_WALK + 1] = ss[SS_WALK + 1] + sc[SC_WALK] * walk[1]
            used = 1
        pm[0] = ss[SS_IMU] + (sc[SC_BIAS] + ss[SS_WALK]) + s * noise[4]
        pm[1] = ss[SS_IMU + 1] + (sc[SC_BIAS + 1] + ss[SS_WALK + 1]) + s * noise[5]
        return used
    return 0


def _psi(r, e, ast, ac, n):
    """ψ(r) of edge ``e`` by linear interpolation in the table, the edge's last cell first."""
    xp = AC_TAB
    fp = xp + n
    sl = fp + n
    j = int(ast[A_CELL + e])
    if ac[xp + j] <= r < ac[xp + j + 1]:
        return ac[sl + j] * (r - ac[xp + j]) + ac[fp + j]
    if r != r:
        return r
    if r < ac[xp]:
        return ac[fp]
    if r >= ac[xp + n - 1]:
        return ac[fp + n - 1]
    lo, hi = 0, n  # the cell holding r: bisection
    while lo < hi:
        mid = (lo + hi) // 2
        if r < ac[xp + mid]:
            hi = mid
        else:
            lo = mid + 1
    j = lo - 1
    ast[A_CELL + e] = j
    return ac[sl + j] * (r - ac[xp + j]) + ac[fp + j]


def valve_spool(u, ast, ac):
    """The spool of each valve over the step for the held commands ``u`` (3,) V.

    Command ``c = clip((u - 5 V) / 5 V, -1, 1)``; a first-order lag (exact,
    ``alpha = 1 - e^(-w dt)``) or the exact ZOH of a second-order one.
    """
    for i in range(3):
        c = clip(u[i] * 0.2 - 1.0, -1.0, 1.0)
        sp = ast[A_SPOOL + i]
        if ac[AC_ORDER] == 1.0:
            ast[A_SPOOL + i] = sp + (c - sp) * ac[AC_ALPHA]
        else:
            a = AC_AD
            sr = ast[A_RATE + i]
            rate = ac[a + 2] * sp + ac[a + 3] * sr + ac[a + 5] * c
            ast[A_SPOOL + i] = sp * ac[a] + (ac[a + 1] * sr + ac[a + 4] * c)
            ast[A_RATE + i] = rate


def _chamber(c, q, ast, ac):
    """Chamber ``c`` (0-2 cap sides, 3-5 rod sides) now: its supply and exhaust
    edges' openings, its volume ``V`` (m^3) and ``dV/dq``.

    Metering edges (Rubio 2009): ``a_P1 = a_2R = clip(δ + s, ε, 1)``,
    ``a_1R = a_P2 = clip(δ - s, ε, 1)``; ``V = V0 + dV/dq q``, kept above
    ``V_min`` (overtravel must not empty a chamber).
    """
    i = c % 3
    sp = ast[A_SPOOL + i]
    d = ac[AC_DELTA + i]
    eps = ac[AC_EPS]
    ap, am = clip(sp + d, eps, 1.0), clip(d - sp, eps, 1.0)
    if c < 3:  # cap side: supply edge P->1, exhaust edge 1->R
        a_s, a_e = ap, am
    else:  # rod side: P->2, 2->R
        a_s, a_e = am, ap
    dv = ac[AC_CH + 3 * c + 1]
    V = ac[AC_CH + 3 * c] + dv * q[i]
    if V < ac[AC_CH + 3 * c + 2]:
        V = ac[AC_CH + 3 * c + 2]
    return a_s, a_e, V, dv


def chamber_pressures(q, qd, ast, ac):
    """The six chamber pressures over the step (linearly implicit Euler, frozen conductances).

    Metering edges (Rubio 2009): ``a_P1 = a_2R = clip(δ + s, ε, 1)``,
    ``a_1R = a_P2 = clip(δ - s, ε, 1)``; per chamber with ``G = a ψ(r)``,
    ``c = n R T k / V``:
    ``p+ = (p + h c (G_P p_s + G_R p_a)) / (1 + h c (G_P + G_R) + h n V̇ / V)``
    (denominator kept >= 0.5); ψ of the ratio downstream/upstream of each edge
    (a chamber above the supply flows back to it, one below the atmosphere
    draws air in).
    """
    draw = 0.0
    ps, pa, hn, rtk = ast[A_PS], ac[AC_PA], ac[AC_HN], ac[AC_RTK]
    ips = 1.0 / ps
    nsub = int(ac[AC_NSUB])
    n = int(ac[AC_NTAB])
    for c in range(6):
        i = c % 3
        a_s, a_e, V, dv = _chamber(c, q, ast, ac)
        hnV = hn / V
        den0 = (dv * qd[i]) * hnV + 1.0
        hc = hnV * rtk
        pc = ast[A_P + c]
        for _ in range(nsub):
            psi_s = _psi(pc * ips if pc <= ps else ps / pc, c, ast, ac, n)
            psi_e = _psi(pa / pc if pc >= pa else pc / pa, c + 6, ast, ac, n)
            g_s = a_s * psi_s
            g_e = a_e * psi_e
            den = (g_s + g_e) * hc + den0
            if den < 0.5:
                den = 0.5
            pc = ((g_s * ps + g_e * pa) * hc + pc) / den
            draw += g_s * (ps - pc)
        ast[A_P + c] = pc
    ast[A_DRAW] = draw * ac[AC_TH + TH_K] / nsub


def chamber_energy(q, qd, ast, ac):
    """The six chambers over the step with the energy equation and wall heat transfer.

    Per chamber of volume ``V`` and gas temperature ``T`` (Richer & Hurmuzlu 2000,
    eq. 9 with its heat term; Carneiro & de Almeida 2006):
    ``V ṗ = γ R (T_in ṁ_in - T ṁ_out) - γ p V̇ + (γ - 1) h_w A_w (T_w - T)``,
    ``ṁ = k G (p_up - p_down)`` through each edge (``G = a ψ(r)``, as
    :func:`chamber_pressures`), air entering at the supply's (or the
    atmosphere's) temperature, leaving at the chamber's; the wall area
    ``A_w = A_0 + A_V V`` (both ends and the barrel wetted over the chamber's
    length). Linearly implicit in ``p`` like :func:`chamber_pressures`; the
    chamber's mass ``m = p V / (R T)`` then takes the step's flows and gives
    the new ``T = p V⁺ / (R m)``. Charging is near adiabatic, discharging
    cools the gas and the wall warms it back: the polytropic index of the
    other model emerges instead of being chosen.
    """
    draw = 0.0
    ps, pa = ast[A_PS], ac[AC_PA]
    ips = 1.0 / ps
    nsub = int(ac[AC_NSUB])
    n = int(ac[AC_NTAB])
    th = AC_TH
    gam, rg, kk = ac[th + TH_GAMMA], ac[th + TH_R], ac[th + TH_K]
    tw, hw = ac[th + TH_TW], ac[th + TH_HW]
    h = ac[th + TH_H]
    for c in range(6):
        i = c % 3
        a_s, a_e, V, dv = _chamber(c, q, ast, ac)
        vdot = dv * qd[i]
        aw = ac[AC_AW + 2 * c] + ac[AC_AW + 2 * c + 1] * V
        pc = ast[A_P + c]
        tc = ast[A_T + c]
        if not tc > 0.0:
            tc = tw
        for _ in range(nsub):
            psi_s = _psi(pc * ips if pc <= ps else ps / pc, c, ast, ac, n)
            psi_e = _psi(pa / pc if pc >= pa else pc / pa, c + 6, ast, ac, n)
            g_s = a_s * psi_s * kk
            g_e = a_e * psi_e * kk
            t_s = tw if pc <= ps else tc  # the supply is at the wall's temperature
            t_e = tc if pc >= pa else tw
            c_s = h * gam * rg * t_s * g_s / V
            c_e = h * gam * rg * t_e * g_e / V
            heat = h * (gam - 1.0) * hw * aw * (tw - tc) / V
            den = 1.0 + c_s + c_e + h * gam * vdot / V
            if den < 0.5:
                den = 0.5
            p_new = (pc + c_s * ps + c_e * pa + heat) / den
            m = pc * V / (rg * tc) + h * (g_s * (ps - p_new) + g_e * (pa - p_new))
            draw += g_s * (ps - p_new)
            V = V + h * vdot
            pc = p_new
            tc = pc * V / (rg * m) if m > 0.0 else tw
        ast[A_P + c] = pc
        ast[A_T + c] = tc
    ast[A_DRAW] = draw / nsub


def supply_step(ast, ac):
    """The supply as built over the step: compressor, receiver, regulator, line.

    The valves draw ``ast[A_DRAW]`` (kg/s) from the line at the supply pressure
    ``p_s``; a regulator refills it from the receiver towards its set point,
    ``ṁ_reg = k_reg (min(p_set, p_r) - p_s)`` (a linear droop, no back-flow);
    a compressor delivers its free-air flow into the receiver while its
    pressure switch is on (on below cut-in, off above cut-out). Each volume is
    isothermal at the supply's temperature: ``ṗ = (R T / V) Σ ṁ`` (explicit:
    ``h R T k_reg / V_line`` is about 0.03 with the defaults). Nothing moves
    with the ideal source (``SUP_ON`` 0).
    """
    sup = AC_SUP
    if ac[sup + SUP_ON] == 0.0:
        return
    h, ps, pr = ac[sup + SUP_H], ast[A_PS], ast[A_PR]
    preg = pr if pr < ac[sup + SUP_PSET] else ac[sup + SUP_PSET]
    m_reg = ac[sup + SUP_KREG] * (preg - ps)
    if m_reg < 0.0:
        m_reg = 0.0
    if pr < ac[sup + SUP_PON]:
        ast[A_COMP] = 1.0
    elif pr > ac[sup + SUP_POFF]:
        ast[A_COMP] = 0.0
    ps = ps + h * ac[sup + SUP_RTV_L] * (m_reg - ast[A_DRAW])
    if ps < ac[AC_PA]:
        ps = ac[AC_PA]
    ast[A_PS] = ps
    ast[A_PR] = pr + h * ac[sup + SUP_RTV_R] * (ast[A_COMP] * ac[sup + SUP_QC] - m_reg)


def nonlinear_step(u, q, qd, ast, ac, f):
    """Valves, chambers and the net slide forces ``f`` (3,) N for one step.

    ``F = p1 A1 - p2 A2 - p_a A_r - F_f(q̇)``, the seal friction ``F_f`` of
    :func:`simpro_mj.plant.friction.seal_friction`; the chambers polytropic
    (:func:`chamber_pressures`) or with the energy equation (:func:`chamber_energy`).
    """
    valve_spool(u, ast, ac)
    if ac[AC_TH + TH_ON] != 0.0:
        chamber_energy(q, qd, ast, ac)
    else:
        chamber_pressures(q, qd, ast, ac)
    supply_step(ast, ac)
    slide_forces(qd, ast, ac, f)


def slide_forces(qd, ast, ac, f):
    """Net force on each slide ``f`` (3,) N of the present pressures at speeds ``qd``."""
    a1, a2, par = ac[AC_A1], ac[AC_A2], ac[AC_PA] * ac[AC_AR]
    for i in range(3):
        c = AC_FRIC + 5 * i
        fr = seal_friction(qd[i], ac[c], ac[c + 1], ac[c + 2], ac[c + 3], ac[c + 4])
        f[i] = a1 * ast[A_P + i] - a2 * ast[A_P + 3 + i] - par - fr


def linear_step(u, q, qd, ast, ac, f):
    """The paper's eq. (19) on every slide for one step; forces into ``f`` (3,) N.

    ``φ' = b (u - u_h) - a0 q̇ - a1 φ`` (exact for the held input),
    ``F = F_h + M_q φ + D_q q̇ + K_q (q - q_0)``, optionally clipped to the
    force range; display pressures share the force deviation equally.
    """
    for i in range(3):
        ui = clip(u[i], 0.0, 10.0)
        ast[A_SPOOL + i] = (ui - 5.0) / 5.0
        drive = ac[AC_LB + i] * (ui - ac[AC_UHOLD + i]) - ac[AC_LA0 + i] * qd[i]
        ast[A_PHI + i] = ast[A_PHI + i] * ac[AC_EA + i] + ac[AC_IA + i] * drive
    for i in range(3):
        df = dd = dk = 0.0
        for j in range(3):
            df += ac[AC_MQ + 3 * i + j] * ast[A_PHI + j]
            dd += ac[AC_DQ + 3 * i + j] * qd[j]
            dk += ac[AC_KQ + 3 * i + j] * (q[j] - ac[AC_Q0 + j])
        fi = ac[AC_FHOLD + i] + (df + dd + dk)
        if ac[AC_SAT] != 0.0:
            fi = clip(fi, ast[A_FMIN], ast[A_FMAX])
        f[i] = fi
        dfi = fi - ac[AC_FHOLD + i]
        ast[A_P + i] = ac[AC_P10 + i] + 0.5 * dfi / ac[AC_A1]
        ast[A_P + 3 + i] = ac[AC_P20 + i] - 0.5 * dfi / ac[AC_A2]
