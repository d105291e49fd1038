"""Leg velocity feed-forward from the set-point trajectory (beyond the paper).

The joint loops (eqs. 36-37) produce the valve voltage that moves a leg from
the position error alone; a leg that has to move at ``q̇`` needs, in steady
motion, the voltage ``u = q̇ / (b / a0)``, ``b / a0`` the velocity gain of the
identified plant ``b / (s (s^2 + a1 s + a0))`` (eq. 19: at a constant voltage
the leg settles to the speed ``(b / a0) u``). The feed-forward adds that voltage
to each joint controller's output, from the set-point's rate through the IK's
Jacobian::

    q̇_d[k] = J(y_d[k]) (y_d[k] - y_d[k-1]) / dt,   u_ff,i[k] = (a0_i / b_i) q̇_d,i[k]

so the joint controller only has to supply what the model misses. A step in
the set-point would give one sample of ``Δ / dt``: with Fig. 13's set-point
filter in front of the joint loops the rate goes through the same filter (a
linear filter commutes with the difference), which turns a step into the ramp
the filtered reference follows.

Numbers only (no MuJoCo); :class:`controllers.frequency.LoopModel`'s
``velocity_ff`` is the same term in the linear prediction.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .design import Plant
from .geometry import PlatformGeometry, nominal_geometry
from .kinematics import jacobian


def velocity_gains(plants: Sequence[Plant]) -> np.ndarray:
    """``a0 / b`` per leg (V per m/s): the inverse of each plant's velocity gain.

    Raises
    ------
    ValueError
        Not three plants, or a plant with ``b <= 0`` or ``a0 <= 0`` (no finite
        velocity gain: a pure double integrator).
    """
    plants = list(plants)
    if len(plants) != 3:
        raise ValueError(f"need 3 plants (one per leg), got {len(plants)}")
    out = np.empty(3)
    for i, p in enumerate(plants):
        if not (np.isfinite(p.b) and p.b > 0 and np.isfinite(p.a0) and p.a0 > 0):
            raise ValueError(
                f"leg {i + 1}: plant b = {p.b!r}, a0 = {p.a0!r}; allowed: b > 0 and a0 > 0 "
                "(a finite velocity gain b / a0)"
            )
        out[i] = p.a0 / p.b
    return out


def leg_rates(ref, dt: float, geometry: PlatformGeometry | None = None) -> np.ndarray:
    """Leg rates ``J(y_d[k]) (y_d[k] - y_d[k-1]) / dt`` (m/s), (n, 3); row 0 is zero.

    Parameters
    ----------
    ref : array_like, (n, 3)
        The set-point at every inner step (roll rad, pitch rad, heave m).
    dt : float
        Inner step (s).
    """
    ref = np.asarray(ref, dtype=float)
    if ref.ndim != 2 or ref.shape[1] != 3:
        raise ValueError(f"ref must have shape (n, 3), got {ref.shape}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be > 0 s, got {dt!r}")
    rate = np.zeros_like(ref)
    rate[1:] = np.diff(ref, axis=0) / dt
    jac = jacobian(ref, nominal_geometry() if geometry is None else geometry)
    return np.einsum("kij,kj->ki", jac, rate)


def leg_velocity_feedforward(
    ref,
    dt: float,
    plants: Sequence[Plant],
    geometry: PlatformGeometry | None = None,
    u_limit: float | None = None,
    setpoint_filter=None,
) -> np.ndarray:
    """The feed-forward voltages ``(a0_i / b_i) q̇_d,i`` (V), (n, 3).

    ``setpoint_filter`` (optional, a fresh :class:`controllers.setpoint_filter.SetpointFilter`)
    filters the leg rates as Fig. 13's filter filters ``q_d`` (reset to zero
    rates, then one update per step), so the voltage goes with the filtered
    reference the joint loops follow: the ramp filter turns a step's one sample
    of ``Δ / dt`` into ``Δ / T_f`` over ``T_f``.

    ``u_limit`` (V, optional) clips them to ``[-u_limit, u_limit]``: the valve's
    span around its closed centre (5 V on the MPYE-5). A set-point step has a
    one-sample rate ``Δ / dt`` (3° of pitch: about 180 V); clipped, it is one
    millisecond of a fully open valve instead of a kick that the joint
    controller's anti-windup would feel. Measured on the 3° ``step_pitch`` in
    the feed-forward mode: unclipped overshoot 1.8 % and pitch RMS error
    0.95° against 0.43 % and 0.59° without the feed-forward; clipped 0.40 %
    and 0.59°.
    """
    rates = leg_rates(ref, dt, geometry)
    if setpoint_filter is not None:
        setpoint_filter.reset([0.0, 0.0, 0.0])
        update = setpoint_filter.update
        rates = np.array([update(r) for r in rates.tolist()]).reshape(-1, 3)
    u = rates * velocity_gains(plants)
    if u_limit is not None:
        if not (np.isfinite(u_limit) and u_limit > 0):
            raise ValueError(f"u_limit must be > 0 V, got {u_limit!r}")
        np.clip(u, -u_limit, u_limit, out=u)
    return u
