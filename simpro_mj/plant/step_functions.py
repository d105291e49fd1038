"""The plant's part of one 1 ms step, as plain functions on flat float64 arrays.

The one implementation of the state read, the sensor models and the
actuator models per step (:class:`~simpro_mj.plant.sensors.SensorConfig` and
the actuator classes configure them), in the subset numba compiles:
:mod:`simpro_mj.sim.step` runs them interpreted or compiled. Each stage is a
small named function so that a plant change (a friction law, a sensor
error) is made in one place; each array it reads has a declared layout
(:func:`controllers.layout.layout`, below), so a function reads
``ast[ACT.spool + i]`` and a class packs its block by field name.
"""

from __future__ import annotations

import math

from controllers.layout import layout
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

# Each block's layout (controllers.layout.layout), declared once: the offsets the
# functions below read and the packing of the classes that build the blocks.

#: the sensor constants ``sc`` (SensorConfig.step_constants, packed by name): the
#: potentiometers' LSB, noise, range, offsets and gains (3 each), the track's full scale
#: and linearity, their period (steps); the height encoder's resolution, noise, period;
#: the IMU's noise, bias (roll, pitch), the bias walk's step per sample (0: off), the
#: complementary filter's accelerometer weight, the output filter's coefficient, the
#: period; 1 / dt^2 (simpro_mj.plant.sensor_errors: the track's errors, the tilt)
SC = layout(
    "SensorConstants", lsb=1, sigma=1, lo=1, hi=1, off=3, gain=3, fs=1, nl=1, pot_every=1,
    res=1, enc_noise=1, enc_every=1, sigma_imu=1, bias=2, walk=1, accw=1, alpha=1,
    imu_every=1, idt2=1,
)  # fmt: skip
#: the sensors' own state ``ss``: the IMU filter (roll, pitch), the bias walk, the IMU
#: site's last two positions and how many are known, the complementary filter's
#: low-passed accelerometer tilt error
SS = layout("SensorState", imu=2, walk=2, back1=3, back2=3, hn=1, acc=2)

#: the actuators' state ``ast``: chamber pressures p1 (3) then p2 (3), spool, spool rate,
#: each ψ-table edge's last cell (6 supply, 6 exhaust edges), the supply pressure at the
#: valves, the linear model's φ, its force bounds, the chamber gas temperatures (the
#: energy model's; 0: the wall's), the receiver's pressure, this step's draw through the
#: valves' supply edges (kg/s), the compressor running (1) or not
ACT = layout(
    "ActuatorState", p=6, spool=3, rate=3, cell=12, ps=1, phi=3, fmin=1, fmax=1, t=6, pr=1,
    draw=1, comp=1,
)  # fmt: skip

#: one leg's seal friction (seal_friction's arguments): breakaway, Coulomb, Stribeck
#: velocity, viscous, v_reg (0: the stick model)
FRIC = layout("SealFriction", breakaway=1, coulomb=1, v_stribeck=1, viscous=1, v_reg=1)
#: the second-order spool's exact ZOH (spool, rate) <- (spool, rate, command)
SPOOL = layout("SpoolZoh", s_s=1, s_r=1, r_s=1, r_r=1, s_c=1, r_c=1)
#: one chamber's volume ``V = V0 + dV/dq q``, kept above V_min; its wall area
#: ``A_w = A_0 + A_V V`` (the energy model's)
CH = layout("Chamber", v0=1, dvdq=1, vmin=1, a0=1, av=1)
#: the energy model's constants: on (1) or polytropic (0), γ, R, k (kg/(s Pa)), the
#: wall's temperature (K; the supply's and the atmosphere's too), h_w (W/(m^2 K)), the
#: sub-step (s)
TH = layout("Thermal", on=1, gamma=1, r=1, k=1, tw=1, hw=1, h=1)
#: the supply as built (supply_step): on (1) or an ideal source (0), R T / V of the
#: receiver and of the line (Pa/kg), the regulator's conductance (kg/(s Pa)) and set
#: point (Pa), the compressor's delivery (kg/s), cut-in and cut-out (Pa), the step (s)
SUP = layout("Supply", on=1, rtv_r=1, rtv_l=1, kreg=1, pset=1, qc=1, pon=1, poff=1, h=1)

#: the fields both actuator kinds' constants start with (actuate reads ``kind``):
#: kind (0 nonlinear, 1 linear), p_a, A1, A2, A_r
_COMMON = dict(kind=1, pa=1, a1=1, a2=1, ar=1)
#: the nonlinear actuators' constants ``ac`` (NonlinearActuators.step_constants): R T k,
#: the leakage ε, h n, the first-order spool's coefficient, the spool's order, the
#: sub-steps, the ψ table's length; per leg the seal friction, the second-order spool,
#: the underlaps, per chamber (0-2 cap sides, 3-5 rod sides) its volume and wall, the
#: energy model, the supply; the ψ table (grid, values, slopes: 3 x its length)
AC = layout(
    "NonlinearConstants", **_COMMON, rtk=1, eps=1, hn=1, alpha=1, order=1, nsub=1, ntab=1,
    fric=3 * FRIC.LEN, spool=SPOOL.LEN, delta=3, ch=6 * CH.LEN, th=TH.LEN, sup=SUP.LEN,
    tab=None,
)  # fmt: skip
#: the linear actuators' constants (eq. 19; LinearActuators.step_constants): b, a0,
#: exp(-a1 dt), its integral, u_hold, F_hold, q_0, M_q, D_q, K_q (3 x 3, row-major),
#: saturate, the display pressures at rest p10, p20
ACL = layout(
    "LinearConstants", **_COMMON, b=3, a0=3, ea=3, ia=3, uhold=3, fhold=3, q0=3, mq=9, dq=9,
    kq=9, sat=1, p10=3, p20=3,
)  # fmt: skip


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
    (``sc[SC.accw]`` = 1 - exp(-2 π f_c dt); 0: the gyro alone). A 7 Hz cycle
    passes 1.4 % of its acceleration's tilt at f_c = 0.1 Hz, a sustained tilt
    error all of it.
    """
    w = sc[SC.accw]
    if not w > 0.0:
        return roll, pitch
    x, y, z = site[0], site[1], site[2]
    b1, b2 = SS.back1, SS.back2  # the site's position one and two steps back
    x1, y1, z1 = ss[b1], ss[b1 + 1], ss[b1 + 2]
    x2, y2, z2 = ss[b2], ss[b2 + 1], ss[b2 + 2]
    ss[b2], ss[b2 + 1], ss[b2 + 2] = x1, y1, z1
    ss[b1], ss[b1 + 1], ss[b1 + 2] = x, y, z
    if ss[SS.hn] < 2.0:  # the first two positions of a run: no acceleration yet
        ss[SS.hn] += 1.0
        return roll, pitch
    idt2 = sc[SC.idt2]
    ax = ((x - x2) - 2.0 * (x1 - x2)) * idt2
    ay = ((y - y2) - 2.0 * (y1 - y2)) * idt2
    az = ((z - z2) - 2.0 * (z1 - z2)) * idt2
    ra, pa = accel_tilt(ax, ay, az, roll, pitch)
    ss[SS.acc] += w * ((ra - roll) - ss[SS.acc])
    ss[SS.acc + 1] += w * ((pa - pitch) - ss[SS.acc + 1])
    return roll + ss[SS.acc], pitch + ss[SS.acc + 1]


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
    alpha = sc[SC.alpha]
    r_in, p_in = pose[0], pose[1]
    if site is not None:
        r_in, p_in = imu_input(r_in, p_in, site, sc, ss)
    ss[SS.imu] = ss[SS.imu] + alpha * (r_in - ss[SS.imu])
    ss[SS.imu + 1] = ss[SS.imu + 1] + alpha * (p_in - ss[SS.imu + 1])
    if force or k % int(sc[SC.pot_every]) == 0:
        sigma, lsb, lo, hi = sc[SC.sigma], sc[SC.lsb], sc[SC.lo], sc[SC.hi]
        fs, nl = sc[SC.fs], sc[SC.nl]
        for j in range(3):
            if nl > 0.0:
                e = pot_nonlinearity(q[j], fs, nl)
                v = sc[SC.gain + j] * q[j] + sc[SC.off + j] + e + sigma * noise[j]
            else:
                v = sc[SC.gain + j] * q[j] + sc[SC.off + j] + sigma * noise[j]
            qm[j] = clip(quantise(v, lsb), lo, hi)
    if force or k % int(sc[SC.enc_every]) == 0:
        h = pose[2] + sc[SC.enc_noise] * noise[3]
        if sc[SC.res] > 0.0:
            h = quantise(h, sc[SC.res])
        pm[2] = h
    if force or k % int(sc[SC.imu_every]) == 0:
        s = sc[SC.sigma_imu]
        used = 0
        if sc[SC.walk] > 0.0:
            ss[SS.walk] = ss[SS.walk] + sc[SC.walk] * walk[0]
            ss[SS.walk + 1] = ss[SS.walk + 1] + sc[SC.walk] * walk[1]
            used = 1
        pm[0] = ss[SS.imu] + (sc[SC.bias] + ss[SS.walk]) + s * noise[4]
        pm[1] = ss[SS.imu + 1] + (sc[SC.bias + 1] + ss[SS.walk + 1]) + s * noise[5]
        return used
    return 0


def _psi(r, e, ast, ac, n):
    """ψ(r) of edge ``e`` by linear interpolation in the table, the edge's last cell first."""
    xp = AC.tab
    fp = xp + n
    sl = fp + n
    j = int(ast[ACT.cell + e])
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
    ast[ACT.cell + e] = j
    return ac[sl + j] * (r - ac[xp + j]) + ac[fp + j]


def valve_spool(u, ast, ac):
    """The spool of each valve over the step for the held commands ``u`` (3,) V.

    Command ``c = clip((u - 5 V) / 5 V, -1, 1)``; a first-order lag (exact,
    ``alpha = 1 - e^(-w dt)``) or the exact ZOH of a second-order one.
    """
    for i in range(3):
        c = clip(u[i] * 0.2 - 1.0, -1.0, 1.0)
        sp = ast[ACT.spool + i]
        if ac[AC.order] == 1.0:
            ast[ACT.spool + i] = sp + (c - sp) * ac[AC.alpha]
        else:
            a = AC.spool
            sr = ast[ACT.rate + i]
            rate = ac[a + SPOOL.r_s] * sp + ac[a + SPOOL.r_r] * sr + ac[a + SPOOL.r_c] * c
            ast[ACT.spool + i] = sp * ac[a + SPOOL.s_s] + (
                ac[a + SPOOL.s_r] * sr + ac[a + SPOOL.s_c] * c
            )
            ast[ACT.rate + i] = rate


def _chamber(c, q, ast, ac):
    """Chamber ``c`` (0-2 cap sides, 3-5 rod sides) now: its supply and exhaust
    edges' openings, its volume ``V`` (m^3) and ``dV/dq``.

    Metering edges (Rubio 2009): ``a_P1 = a_2R = clip(δ + s, ε, 1)``,
    ``a_1R = a_P2 = clip(δ - s, ε, 1)``; ``V = V0 + dV/dq q``, kept above
    ``V_min`` (overtravel must not empty a chamber).
    """
    i = c % 3
    sp = ast[ACT.spool + i]
    d = ac[AC.delta + i]
    eps = ac[AC.eps]
    ap, am = clip(sp + d, eps, 1.0), clip(d - sp, eps, 1.0)
    if c < 3:  # cap side: supply edge P->1, exhaust edge 1->R
        a_s, a_e = ap, am
    else:  # rod side: P->2, 2->R
        a_s, a_e = am, ap
    ch = AC.ch + CH.LEN * c
    dv = ac[ch + CH.dvdq]
    V = ac[ch + CH.v0] + dv * q[i]
    if V < ac[ch + CH.vmin]:
        V = ac[ch + CH.vmin]
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
    ps, pa, hn, rtk = ast[ACT.ps], ac[AC.pa], ac[AC.hn], ac[AC.rtk]
    ips = 1.0 / ps
    nsub = int(ac[AC.nsub])
    n = int(ac[AC.ntab])
    for c in range(6):
        i = c % 3
        a_s, a_e, V, dv = _chamber(c, q, ast, ac)
        hnV = hn / V
        den0 = (dv * qd[i]) * hnV + 1.0
        hc = hnV * rtk
        pc = ast[ACT.p + c]
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
        ast[ACT.p + c] = pc
    ast[ACT.draw] = draw * ac[AC.th + TH.k] / nsub


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
    ps, pa = ast[ACT.ps], ac[AC.pa]
    ips = 1.0 / ps
    nsub = int(ac[AC.nsub])
    n = int(ac[AC.ntab])
    th = AC.th
    gam, rg, kk = ac[th + TH.gamma], ac[th + TH.r], ac[th + TH.k]
    tw, hw = ac[th + TH.tw], ac[th + TH.hw]
    h = ac[th + TH.h]
    for c in range(6):
        i = c % 3
        a_s, a_e, V, dv = _chamber(c, q, ast, ac)
        vdot = dv * qd[i]
        ch = AC.ch + CH.LEN * c
        aw = ac[ch + CH.a0] + ac[ch + CH.av] * V
        pc = ast[ACT.p + c]
        tc = ast[ACT.t + c]
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
        ast[ACT.p + c] = pc
        ast[ACT.t + c] = tc
    ast[ACT.draw] = draw / nsub


def supply_step(ast, ac):
    """The supply as built over the step: compressor, receiver, regulator, line.

    The valves draw ``ast[ACT.draw]`` (kg/s) from the line at the supply pressure
    ``p_s``; a regulator refills it from the receiver towards its set point,
    ``ṁ_reg = k_reg (min(p_set, p_r) - p_s)`` (a linear droop, no back-flow);
    a compressor delivers its free-air flow into the receiver while its
    pressure switch is on (on below cut-in, off above cut-out). Each volume is
    isothermal at the supply's temperature: ``ṗ = (R T / V) Σ ṁ`` (explicit:
    ``h R T k_reg / V_line`` is about 0.03 with the defaults). Nothing moves
    with the ideal source (``SUP.on`` 0).
    """
    sup = AC.sup
    if ac[sup + SUP.on] == 0.0:
        return
    h, ps, pr = ac[sup + SUP.h], ast[ACT.ps], ast[ACT.pr]
    preg = pr if pr < ac[sup + SUP.pset] else ac[sup + SUP.pset]
    m_reg = ac[sup + SUP.kreg] * (preg - ps)
    if m_reg < 0.0:
        m_reg = 0.0
    if pr < ac[sup + SUP.pon]:
        ast[ACT.comp] = 1.0
    elif pr > ac[sup + SUP.poff]:
        ast[ACT.comp] = 0.0
    ps = ps + h * ac[sup + SUP.rtv_l] * (m_reg - ast[ACT.draw])
    if ps < ac[AC.pa]:
        ps = ac[AC.pa]
    ast[ACT.ps] = ps
    ast[ACT.pr] = pr + h * ac[sup + SUP.rtv_r] * (ast[ACT.comp] * ac[sup + SUP.qc] - m_reg)


def nonlinear_step(u, q, qd, ast, ac, f):
    """Valves, chambers and the net slide forces ``f`` (3,) N for one step.

    ``F = p1 A1 - p2 A2 - p_a A_r - F_f(q̇)``, the seal friction ``F_f`` of
    :func:`simpro_mj.plant.friction.seal_friction`; the chambers polytropic
    (:func:`chamber_pressures`) or with the energy equation (:func:`chamber_energy`).
    """
    valve_spool(u, ast, ac)
    if ac[AC.th + TH.on] != 0.0:
        chamber_energy(q, qd, ast, ac)
    else:
        chamber_pressures(q, qd, ast, ac)
    supply_step(ast, ac)
    slide_forces(qd, ast, ac, f)


def slide_forces(qd, ast, ac, f):
    """Net force on each slide ``f`` (3,) N of the present pressures at speeds ``qd``."""
    a1, a2, par = ac[AC.a1], ac[AC.a2], ac[AC.pa] * ac[AC.ar]
    for i in range(3):
        c = AC.fric + FRIC.LEN * i
        fr = seal_friction(
            qd[i], ac[c + FRIC.breakaway], ac[c + FRIC.coulomb], ac[c + FRIC.v_stribeck],
            ac[c + FRIC.viscous], ac[c + FRIC.v_reg],
        )  # fmt: skip
        f[i] = a1 * ast[ACT.p + i] - a2 * ast[ACT.p + 3 + i] - par - fr


def linear_step(u, q, qd, ast, ac, f):
    """The paper's eq. (19) on every slide for one step; forces into ``f`` (3,) N.

    ``φ' = b (u - u_h) - a0 q̇ - a1 φ`` (exact for the held input),
    ``F = F_h + M_q φ + D_q q̇ + K_q (q - q_0)``, optionally clipped to the
    force range; display pressures share the force deviation equally.
    """
    for i in range(3):
        ui = clip(u[i], 0.0, 10.0)
        ast[ACT.spool + i] = (ui - 5.0) / 5.0
        drive = ac[ACL.b + i] * (ui - ac[ACL.uhold + i]) - ac[ACL.a0 + i] * qd[i]
        ast[ACT.phi + i] = ast[ACT.phi + i] * ac[ACL.ea + i] + ac[ACL.ia + i] * drive
    for i in range(3):
        df = dd = dk = 0.0
        for j in range(3):
            df += ac[ACL.mq + 3 * i + j] * ast[ACT.phi + j]
            dd += ac[ACL.dq + 3 * i + j] * qd[j]
            dk += ac[ACL.kq + 3 * i + j] * (q[j] - ac[ACL.q0 + j])
        fi = ac[ACL.fhold + i] + (df + dd + dk)
        if ac[ACL.sat] != 0.0:
            fi = clip(fi, ast[ACT.fmin], ast[ACT.fmax])
        f[i] = fi
        dfi = fi - ac[ACL.fhold + i]
        ast[ACT.p + i] = ac[ACL.p10 + i] + 0.5 * dfi / ac[ACL.a1]
        ast[ACT.p + 3 + i] = ac[ACL.p20 + i] - 0.5 * dfi / ac[ACL.a2]
