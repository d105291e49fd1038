r"""Orifice mass flow of ISO 6358 with a laminar end (ISO 6358-3).

.. math::
    \dot m = a\,C\,ρ_0 \sqrt{T_0/T}\, p_u\, φ(r), \qquad r = p_d/p_u,

    φ(r) = \begin{cases} 1 & r \le b \ \text{(choked)}\\
      \sqrt{1 - ((r - b)/(1 - b))^2} & b < r \le r_\ell \ \text{(subsonic)}\\
      φ(r_\ell)\,(1 - r)/(1 - r_\ell) & r_\ell < r \le 1 \ \text{(laminar)}
    \end{cases}

(continuous, finite slope at r = 1: no infinite gain near zero pressure drop).
The nonlinear actuators use its conductance form ψ(r) = φ(r)/(1 - r) from a
table (:func:`psi_table`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["RHO_REF", "T_REF", "iso6358_phi", "iso6358_mass_flow", "psi_table"]

#: ISO 8778 standard reference atmosphere of ISO 6358 (ANR): 100 kPa, 20 °C, 65 % RH.
RHO_REF = 1.185  # kg/m^3
T_REF = 293.15  # K


def iso6358_phi(r, b: float, r_lam: float):
    """Flow function φ(r) of ISO 6358 with a laminar end (r = p_down/p_up).

    Choked (r <= b): 1; subsonic: sqrt(1 - ((r - b)/(1 - b))^2); laminar
    (r > r_lam): linear to 0 at r = 1, continuous at r_lam. r is clipped to [0, 1].
    """
    r = np.clip(np.asarray(r, dtype=float), 0.0, 1.0)
    t_lam = (r_lam - b) / (1.0 - b)
    phi_lam = math.sqrt(1.0 - t_lam * t_lam)
    t = np.clip((r - b) / (1.0 - b), 0.0, t_lam)
    return np.minimum(np.sqrt(1.0 - t * t), phi_lam * (1.0 - r) / (1.0 - r_lam))


def iso6358_mass_flow(conductance, p_up, p_down, temperature, b: float, r_lam: float):
    """Mass flow (kg/s) through an orifice of sonic conductance C (m^3/(s Pa)).

    :math:`\\dot m = C ρ_0 \\sqrt{T_0/T}\\, p_u φ(p_d/p_u)` (ISO 6358), signed:
    positive from ``p_up`` to ``p_down``; a reverse pressure drop gives a
    negative flow with the roles of the ports exchanged.
    """
    p_up, p_down = np.asarray(p_up, float), np.asarray(p_down, float)
    hi, lo = np.maximum(p_up, p_down), np.minimum(p_up, p_down)
    sign = np.where(p_up >= p_down, 1.0, -1.0)
    k = np.asarray(conductance) * RHO_REF * np.sqrt(T_REF / temperature)
    return sign * k * hi * iso6358_phi(lo / hi, b, r_lam)


def psi_table(b: float, r_lam: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid and values of the conductance form ψ(r) = φ(r) / (1 - r).

    With it the orifice flow reads :math:`\\dot m = a C ρ_0 \\sqrt{T_0/T}\\,ψ(r)(p_u - p_d)`
    (finite at r = 1: ψ = φ(r_ℓ)/(1 - r_ℓ) in the laminar region). The grid is
    geometric towards r = 1 and holds the branch points b and r_ℓ exactly, so
    the piecewise-linear interpolant is within 2e-5 (relative) of the formula.
    """
    x = np.concatenate(
        [
            np.linspace(0.0, b, 16),
            1.0 - np.geomspace(1.0 - b, 1.0 - r_lam, 600),
            [1.0],
        ]
    )
    x = np.unique(x)
    phi = iso6358_phi(x, b, r_lam)
    with np.errstate(divide="ignore", invalid="ignore"):
        psi = phi / (1.0 - x)
    psi[-1] = math.sqrt(1.0 - ((r_lam - b) / (1.0 - b)) ** 2) / (1.0 - r_lam)
    return x, psi
