"""Optional compiled kernel (numba) for :meth:`NonlinearActuators.step`.

The pure-Python step in :mod:`simpro_mj.plant.pneumatics.nonlinear` is the reference; this
module repeats its float arithmetic operation for operation (same grouping,
no ``fastmath``, so LLVM does not contract ``a * b + c`` into FMA) in one
``@numba.njit(cache=True)`` function. The kernel covers every option of the
nonlinear model (spool order 1 and 2, any number of pressure sub-steps, a
supply pressure changed at run time).

The seal friction is :func:`simpro_mj.plant.friction.seal_friction`, the
one function both paths call (libm's ``exp`` and ``tanh`` in either). One
step is *not* in the kernel and stays in numpy in the dispatcher
(:meth:`NonlinearActuators.step`), because a compiled version rounds
differently: the force product ``Mf @ z`` (BLAS, FMA accumulation). With it
in numpy the kernel's results are bit-identical to the Python path
(``tests/test_pneumatics_kernel.py``).

Selection: ``SIMPRO_KERNEL`` (:mod:`simpro_mj.plant.kernels`), read when an
actuator object is built. The JIT cache (``cache=True``) lives
next to this file in ``__pycache__``; if that directory is not writable
(a read-only site-packages) numba uses ``NUMBA_CACHE_DIR`` when set (else it
silently falls back to a user cache directory, or compiles in every process).
"""

from __future__ import annotations

from simpro_mj.plant.friction import seal_friction

# Layout of the kernel's one float64 buffer (a single array argument: numba's
# call overhead grows by ~70 ns per array argument). The actuator object owns it;
# its z, spool and spool_rate arrays are views of the first ST_LEN entries.
ST_SPOOL, ST_RATE, ST_LEN = 16, 19, 22  # z (16), spool (3), spool rate (3)
KP_PS, KP_PA, KP_HN, KP_RTK, KP_EPS, KP_ALPHA = range(ST_LEN, ST_LEN + 6)
KP_FRIC = ST_LEN + 6  # per leg: breakaway, Coulomb, Stribeck velocity, viscous, v_reg (5 x 3)
KP_AD = KP_FRIC + 15  # ad00, ad01, ad10, ad11, bd0, bd1 (second-order spool)
KP_DELTA = KP_AD + 6  # underlap of legs 1-3
KP_ORDER, KP_NSUB, KP_NTAB = KP_DELTA + 3, KP_DELTA + 4, KP_DELTA + 5  # integers as floats
KP_CH = KP_DELTA + 6  # per chamber: V0, dV/dq, V_min (6 x 3)
KP_CELL = KP_CH + 18  # each edge's last grid cell of the ψ table (12, as floats)
KP_TAB = KP_CELL + 12  # ψ table: xp (n), fp (n), slope (n; the last one unused)


def buffer_len(n_table: int) -> int:
    """Length of the kernel buffer for a ψ table of ``n_table`` points."""
    return KP_TAB + 3 * n_table


_kernel = None  # the compiled step, built on first use (numba's import costs ~0.2 s)


def _psi(r, e, b, n):
    """ψ(r) of edge ``e``: the cached cell, else np.interp's rules and a new cell."""
    xp = KP_TAB
    fp = xp + n
    sl = fp + n
    j = int(b[KP_CELL + e])
    if b[xp + j] <= r < b[xp + j + 1]:
        return b[sl + j] * (r - b[xp + j]) + b[fp + j]
    if r != r:
        return r
    if r < b[xp]:
        return b[fp]
    if r >= b[xp + n - 1]:
        return b[fp + n - 1]
    lo, hi = 0, n  # bisect_right(xp, r) - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if r < b[xp + mid]:
            hi = mid
        else:
            lo = mid + 1
    j = lo - 1
    b[KP_CELL + e] = j
    return b[sl + j] * (r - b[xp + j]) + b[fp + j]


def _step(u0, u1, u2, q0, q1, q2, qd0, qd1, qd2, b):
    """One step of the nonlinear actuators on the buffer ``b`` (in place).

    Leaves p1, p2 (b[0:6]), qdot (b[6:9]) and the seal friction (b[9:12])
    for the dispatcher's ``Mf @ z``.
    """
    u = (float(u0), float(u1), float(u2))  # ints (tests) as the Python path's u * 0.2
    q = (float(q0), float(q1), float(q2))
    qd = (float(qd0), float(qd1), float(qd2))
    if b[KP_ORDER] == 1.0:
        alpha = b[KP_ALPHA]
        for i in range(3):
            c = u[i] * 0.2 - 1.0
            if c < -1.0:
                c = -1.0
            if c > 1.0:
                c = 1.0
            sp = b[ST_SPOOL + i]
            b[ST_SPOOL + i] = sp + (c - sp) * alpha
    else:
        ad00, ad01, ad10, ad11 = b[KP_AD], b[KP_AD + 1], b[KP_AD + 2], b[KP_AD + 3]
        bd0, bd1 = b[KP_AD + 4], b[KP_AD + 5]
        for i in range(3):
            c = u[i] * 0.2 - 1.0
            if c < -1.0:
                c = -1.0
            if c > 1.0:
                c = 1.0
            sp = b[ST_SPOOL + i]
            sr = b[ST_RATE + i]
            rate = ad10 * sp + ad11 * sr + bd1 * c
            b[ST_SPOOL + i] = sp * ad00 + (ad01 * sr + bd0 * c)
            b[ST_RATE + i] = rate
    eps = b[KP_EPS]
    ps, pa, hn, rtk = b[KP_PS], b[KP_PA], b[KP_HN], b[KP_RTK]
    ips = 1.0 / ps
    nsub = int(b[KP_NSUB])
    n = int(b[KP_NTAB])
    for c in range(6):
        i = c % 3
        # metering-edge openings (Rubio 2009): a_P1 = a_2R = clip(δ + s),
        # a_1R = a_P2 = clip(δ - s), both in [ε, 1]
        sp = b[ST_SPOOL + i]
        d = b[KP_DELTA + i]
        ap = sp + d
        am = d - sp
        if ap < eps:
            ap = eps
        if ap > 1.0:
            ap = 1.0
        if am < eps:
            am = eps
        if am > 1.0:
            am = 1.0
        if c < 3:  # cap side: supply edge P->1, exhaust edge 1->R
            a_s, a_e = ap, am
        else:  # rod side: P->2, 2->R
            a_s, a_e = am, ap
        v0 = b[KP_CH + 3 * c]
        dv = b[KP_CH + 3 * c + 1]
        vmin = b[KP_CH + 3 * c + 2]
        V = v0 + dv * q[i]
        if V < vmin:
            V = vmin
        hnV = hn / V
        den0 = (dv * qd[i]) * hnV + 1.0
        hc = hnV * rtk
        pc = b[c]
        for _ in range(nsub):
            # pressure ratio downstream/upstream of each edge: a chamber above the
            # supply flows back through the supply edge, one below the atmosphere
            # draws air through the exhaust edge (no clipping, see pneumatics.py)
            psi_s = _psi(pc * ips if pc <= ps else ps / pc, c, b, n)
            psi_e = _psi(pa / pc if pc >= pa else pc / pa, c + 6, b, n)
            g_s = a_s * psi_s
            g_e = a_e * psi_e
            den = (g_s + g_e) * hc + den0
            if den < 0.5:
                den = 0.5
            pc = ((g_s * ps + g_e * pa) * hc + pc) / den
        b[c] = pc
    for i in range(3):
        b[6 + i] = qd[i]
        f = KP_FRIC + 5 * i
        b[9 + i] = seal_friction(qd[i], b[f], b[f + 1], b[f + 2], b[f + 3], b[f + 4])


def step_kernel():
    """The compiled :func:`_step` (``@numba.njit(cache=True)``), compiled or
    loaded from the on-disk cache on the first call in a process."""
    global _kernel
    if _kernel is None:
        import numba  # the optional extra simpro-sim[fast]: imported on first use

        try:
            psi = numba.njit(cache=True, inline="always")(_psi)
            fric = numba.njit(cache=True, inline="always")(seal_friction)
            kernel = numba.njit(cache=True)(_step)
        except RuntimeError:  # no writable cache location: compile in each process
            psi = numba.njit(inline="always")(_psi)
            fric = numba.njit(inline="always")(seal_friction)
            kernel = numba.njit(_step)
        # the globals the compiled body of _step resolves and calls
        globals()["_psi"] = psi
        globals()["seal_friction"] = fric
        _kernel = kernel
    return _kernel
