"""How much payload the cylinders can hold: the plant's statics.

Holding forces are affine in the payload mass at a fixed pose (gravity is
linear in the masses, the constraint geometry does not depend on them), so
two static solves give the largest payload within a cylinder's force range.
Used by :mod:`simpro_mj.analysis.preflight` (before a run) and
:mod:`simpro_mj.identification.identify` (before Fig. 12's experiment); apart from both so
that imports run one way (``preflight -> autoident -> identify -> payload``).
"""

from __future__ import annotations

import math

import numpy as np


def holding_force_model(model, data, index, probe_kg: float = 1.0):
    """Static slide forces at the present (assembled) pose as ``f_empty + slope m``.

    Returns ``(f_empty, slope)`` (N and N/kg, (3,)) for a payload of mass m:
    holding forces are affine in the payload mass at a fixed pose. The
    model's payload mass is changed for the two static solves and restored.
    """
    # MuJoCo (statics, the plant model) on use: every command imports the preflight,
    # which imports this module, and refuses a mistake within a second without it
    from simpro_mj.plant.pneumatics.statics import holding_forces

    body = model.body("payload").id
    saved = float(model.body_mass[body])
    try:
        model.body_mass[body] = probe_kg
        f_probe = holding_forces(model, data, index)
        model.body_mass[body] = 1e-6  # MuJoCo needs a mass; load_model uses the same
        f_empty = holding_forces(model, data, index)
    finally:
        model.body_mass[body] = saved
    return f_empty, (f_probe - f_empty) / probe_kg


def max_payload(f_empty, slope, force_range) -> float:
    """Largest payload (kg) whose holding forces stay within ``force_range`` (N)."""
    f_min, f_max = force_range
    m_max = math.inf
    for f0, k in zip(np.ravel(f_empty), np.ravel(slope), strict=True):
        if k > 0:
            m_max = min(m_max, (f_max - f0) / k)
        elif k < 0:
            m_max = min(m_max, (f_min - f0) / k)
    return m_max
