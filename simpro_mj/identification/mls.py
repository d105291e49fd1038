"""The experiment's maximum-length sequence, without importing ``scipy.signal``.

The identification's excitation (:func:`simpro_mj.identification.identify._prbs`) is
one period of the maximum-length sequence of a ``bits``-stage shift register, as
``scipy.signal.max_len_seq(bits)`` makes it: the register starts at all ones and
uses scipy's default taps (:data:`TAPS`, the first option listed for each length by
New Wave Instruments). ``scipy.signal`` is the only module of a batch worker's run
that would need it, and importing it costs 0.6-1.2 s of CPU per process
(``python -X importtime``: it loads ``scipy.stats``, ``scipy.interpolate`` and
``scipy.optimize`` too), several times the whole identification of a new cabin
under ``identify: reduced``.

The register's output obeys the linear recurrence over GF(2) of its taps,
:math:`s_{k+n} = s_k \\oplus \\bigoplus_t s_{k+t}`, and, since squaring a polynomial
over GF(2) doubles its exponents, every recurrence spread ``d = 2^j`` times wider,
:math:`s_{k+dn} = s_k \\oplus \\bigoplus_t s_{k+dt}`. :func:`max_len_seq` fills
the sequence a block at a time with the widest such recurrence whose block depends
only on what is already filled: a few hundred numpy operations, 0.05 s of CPU for
``n = 24`` (16.8 million bits), where a bit-by-bit loop in Python would take seconds.
``tests/test_reduced_experiment.py`` holds it equal to scipy's, bit for bit, for every
length the scenario allows.
"""

from __future__ import annotations

import functools

import numpy as np

#: Taps of an n-stage register (``scipy.signal.max_len_seq``'s defaults).
TAPS = {2: (1,), 3: (2,), 4: (3,), 5: (3,), 6: (5,), 7: (6,), 8: (7, 6, 1), 9: (5,),
        10: (7,), 11: (9,), 12: (11, 10, 4), 13: (12, 11, 8), 14: (13, 12, 2), 15: (14,),
        16: (15, 13, 4), 17: (14,), 18: (11,), 19: (18, 17, 14), 20: (17,), 21: (19,),
        22: (21,), 23: (18,), 24: (23, 22, 17)}  # fmt: skip


@functools.lru_cache(maxsize=8)
def max_len_seq(bits: int) -> np.ndarray:
    """One period (``2**bits - 1`` values) of the register's output, 0 or 1 (int8),
    as ``scipy.signal.max_len_seq(bits)[0]``; read-only (cached).

    Raises
    ------
    ValueError
        ``bits`` without taps in :data:`TAPS`.
    """
    if bits not in TAPS:
        raise ValueError(f"invalid bits: {bits!r}; allowed: {min(TAPS)} to {max(TAPS)}")
    n, taps = int(bits), TAPS[bits]
    length = (1 << n) - 1
    seq = np.empty(length, dtype=np.int8)
    seq[:n] = 1  # the register's starting state, read out first
    filled, lag = n, n - max(taps)  # s[k] for k < filled; each block's reach back
    while filled < length:
        d = 1 << ((filled // n).bit_length() - 1)  # the widest spread with d n <= filled
        block = min(d * lag, length - filled)
        start = filled - d * n
        new = seq[start : start + block].copy()
        for t in taps:
            new ^= seq[start + d * t : start + d * t + block]
        seq[filled : filled + block] = new
        filled += block
    seq.flags.writeable = False
    return seq
