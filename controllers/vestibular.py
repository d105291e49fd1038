"""Vestibular perception: otoliths and semicircular canals as transfer functions.

Both sides of a cueing comparison, the vehicle and the simulator, go through
the same model, so the cue that matters is compared: what the driver would
perceive, not what the platform does.

Otoliths (specific force, per axis x, y, z; Young & Meiry 1968, as tabulated
by Reid & Nahon 1986)::

    f_hat / f = K (tau_a s + 1) / ((tau_l s + 1)(tau_s s + 1))
    K = 0.4, tau_a = 13.2 s, tau_l = 5.33 s, tau_s = 0.66 s

The mid-band gain ``K tau_a / tau_l = 0.99`` is close to 1 (between 0.19 and
1.5 rad/s the sensation follows the stimulus); a sustained stimulus adapts to
``K = 0.4`` of itself. Thresholds 0.17 m/s^2 (x, y) and 0.28 m/s^2 (z)
(Zacharias 1978, as tabulated by Reid & Nahon 1986). The z channel is fed
``f_z - g``: the model is linear, so this only removes the constant 0.4 g of
rest from the output, and the threshold then applies to the change.

Semicircular canals (angular velocity, per axis roll, pitch, yaw; Zacharias
1978's torsion-pendulum model with adaptation and neural lead, as used by
Reid & Nahon 1986)::

    w_hat / w = tau_a tau_l s^2 (tau_n s + 1) / ((tau_a s + 1)(tau_l s + 1)(tau_s s + 1))
    tau_a = 80 s, tau_l = 5.73 s, tau_s = 0.005 s, tau_n = 0.06 s

Mid-band gain 1; after a step in angular velocity the sensation decays with
``tau_l`` (5.73 s: the post-rotatory decay) and reverses with ``tau_a``.
Thresholds 3.0 (roll), 3.6 (pitch), 2.6 (yaw) deg/s (Reid & Nahon 1986 after
Zacharias 1978). ``tau_l`` may be given per axis (roll, pitch, yaw).

Sources checked (public texts)
-----------------------------------------------------------------
Telban & Cardullo 2005 (NASA CR-2005-213747, "Motion cueing algorithm
development: human-centered linear and nonlinear approaches") itself could
not be read: none of the pages, documentation or code the search returned
(queries on the report, its number, its authors and the parameter values)
held its tables. What was found, and what follows for these defaults:

* Its abstract (indexed at https://synapsesocial.com/papers/W26554544) says
  the optimal algorithm was tested "incorporating a new otolith model". So
  the report's otolith model is **not** Young & Meiry's unchanged: the
  earlier docstring's "as used by ... Telban & Cardullo 2005" was wrong and
  is withdrawn. The new model's parameters could not be read; Young &
  Meiry's set stays the default, attributed to Reid & Nahon 1986 only.
* Young & Meiry's otolith set (K 0.4, tau_a 13.2 s, tau_l 5.33 s, tau_s
  0.66 s) is the one public cueing code reproduces
  (github.com/ZiGaMi/StewardPlatformEvaluation, ``simulation/human_perception.py``,
  after Murgovski's Chalmers thesis "Vehicle modelling and washout filter
  tuning for the Chalmers Vehicle Simulator"): confirmed as a published set,
  not as Telban & Cardullo's.
* Canals: tau_l 5.7 s and tau_a 80 s are the canal time constant and
  adaptation of the observer model in Rader, Oman & Merfeld 2009
  (J. Neurophysiol. 102:2232, Table 4, https://pmc.ncbi.nlm.nih.gov/articles/PMC2775380):
  our 5.73 s and 80 s agree. tau_s 0.005 s and tau_n 0.06 s: not confirmed
  by any source found.
* The per-axis canal set tau_l = 6.1 (roll), 5.3 (pitch), 10.2 s (yaw) with
  tau_s 0.1 s, tau_a 30 s and no lead, usually attributed to Telban &
  Cardullo, is in the same ZiGaMi code (after Murgovski's thesis); its
  attribution to the 2005 report could not be checked. It is selectable,
  :data:`CANAL_PER_AXIS_ALTERNATIVE` (``tau_l`` per axis: the earlier
  docstring called it selectable when ``tau_l`` was one number).
* Thresholds (0.17, 0.17, 0.28 m/s^2; 3.0, 3.6, 2.6 deg/s): not confirmed by
  any source found here; kept as Reid & Nahon 1986's after Zacharias 1978.

No value changed: no source showed a different set for a parameter we use;
one attribution is corrected. ``docs/paper-notes.md`` ("Vestibular models")
keeps the same record.

A sensation counts as perceived where its magnitude exceeds the channel's
threshold (:meth:`Perception.above`); the thresholds are those of the
sensation, not of the stimulus.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .filters import DiscreteFilter
from .frames import GRAVITY

#: Otolith thresholds (m/s^2): x, y, z (Zacharias 1978; Reid & Nahon 1986).
OTOLITH_THRESHOLDS = (0.17, 0.17, 0.28)
#: Canal thresholds (rad/s): roll 3.0, pitch 3.6, yaw 2.6 deg/s (Reid & Nahon 1986).
CANAL_THRESHOLDS = tuple(math.radians(v) for v in (3.0, 3.6, 2.6))
#: The per-axis canal set usually attributed to Telban & Cardullo (attribution not
#: checked, see the module docstring): ``CanalModel(**CANAL_PER_AXIS_ALTERNATIVE)``.
CANAL_PER_AXIS_ALTERNATIVE = {"tau_l": (6.1, 5.3, 10.2), "tau_s": 0.1, "tau_a": 30.0, "tau_n": 0.0}


def _positive(name: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
        raise ValueError(f"vestibular parameter {name}={v!r}: allowed a finite number > 0")
    return float(v)


def _check_thresholds(organ: str, axes: str, values) -> None:
    """Three positive thresholds, one per axis (the message names ``organ`` and ``axes``)."""
    if len(values) != 3:
        raise ValueError(f"{organ} thresholds: 3 values ({axes}), got {values!r}")
    for v in values:
        _positive(f"{organ} threshold", v)


@dataclass(frozen=True)
class OtolithModel:
    """Otolith transfer function ``K (tau_a s + 1) / ((tau_l s + 1)(tau_s s + 1))``.

    Defaults: Young & Meiry (1968), K = 0.4, tau_a = 13.2 s, tau_l = 5.33 s,
    tau_s = 0.66 s; thresholds (x, y, z) in m/s^2.
    """

    gain: float = 0.4
    tau_a: float = 13.2
    tau_l: float = 5.33
    tau_s: float = 0.66
    thresholds: tuple = OTOLITH_THRESHOLDS

    def __post_init__(self):
        for name in ("gain", "tau_a", "tau_l", "tau_s"):
            _positive(name, getattr(self, name))
        _check_thresholds("otolith", "x, y, z", self.thresholds)

    def tf(self) -> tuple[list, list]:
        """(num, den) in descending powers of s."""
        return (
            [self.gain * self.tau_a, self.gain],
            list(np.polymul([self.tau_l, 1.0], [self.tau_s, 1.0])),
        )


@dataclass(frozen=True)
class CanalModel:
    """Canal transfer function
    ``tau_a tau_l s^2 (tau_n s + 1) / ((tau_a s + 1)(tau_l s + 1)(tau_s s + 1))``.

    Defaults: Zacharias (1978) as used by Reid & Nahon (1986): tau_a = 80 s,
    tau_l = 5.73 s, tau_s = 0.005 s, tau_n = 0.06 s; thresholds (roll, pitch,
    yaw) in rad/s. ``tau_n = 0`` drops the neural lead. ``tau_l`` is one number
    or three (roll, pitch, yaw).
    """

    tau_a: float = 80.0
    tau_l: float | tuple = 5.73
    tau_s: float = 0.005
    tau_n: float = 0.06
    thresholds: tuple = CANAL_THRESHOLDS

    def __post_init__(self):
        for name in ("tau_a", "tau_s"):
            _positive(name, getattr(self, name))
        if isinstance(self.tau_l, (tuple, list)):
            if len(self.tau_l) != 3:
                raise ValueError(
                    f"vestibular parameter tau_l={self.tau_l!r}: allowed one number or three "
                    "(roll, pitch, yaw)"
                )
            for v in self.tau_l:
                _positive("tau_l", v)
            object.__setattr__(self, "tau_l", tuple(float(v) for v in self.tau_l))
        else:
            _positive("tau_l", self.tau_l)
        if not (math.isfinite(self.tau_n) and self.tau_n >= 0):
            raise ValueError(f"vestibular parameter tau_n={self.tau_n!r}: allowed a number >= 0")
        _check_thresholds("canal", "roll, pitch, yaw", self.thresholds)

    def tf(self, axis: int = 0) -> tuple[list, list]:
        """(num, den) in descending powers of s, of ``axis`` (0 roll, 1 pitch, 2 yaw)."""
        tau_l = self.tau_l[axis] if isinstance(self.tau_l, tuple) else self.tau_l
        k = self.tau_a * tau_l
        num = list(np.polymul([k, 0.0, 0.0], [self.tau_n, 1.0]))
        den = np.polymul(np.polymul([self.tau_a, 1.0], [tau_l, 1.0]), [self.tau_s, 1.0])
        return num, list(den)


@dataclass
class Perception:
    """Sensations over time: ``f`` (n, 3) m/s^2 (z: change from 1 g), ``w`` (n, 3) rad/s.

    ``f_threshold`` and ``w_threshold`` are the channels' thresholds.
    """

    f: np.ndarray
    w: np.ndarray
    f_threshold: np.ndarray
    w_threshold: np.ndarray

    def above(self) -> tuple[np.ndarray, np.ndarray]:
        """Boolean masks (n, 3) where the sensation exceeds its threshold."""
        return np.abs(self.f) > self.f_threshold, np.abs(self.w) > self.w_threshold


@dataclass
class VestibularModel:
    """Otoliths and canals of one observer.

    Parameters
    ----------
    otolith : OtolithModel
    canal : CanalModel
    gravity : float
        Subtracted from ``f_z`` before the z otolith (m/s^2).
    """

    otolith: OtolithModel = field(default_factory=OtolithModel)
    canal: CanalModel = field(default_factory=CanalModel)
    gravity: float = GRAVITY

    def perceive(self, f, w, dt: float) -> Perception:
        """Sensations of a motion sampled at ``dt``: ``f``, ``w`` (n, 3) in V.

        The observer starts adapted to the first sample (each filter at its
        steady state for it): a run that starts at rest, or turning at a
        constant rate, starts with no rotation sensation and the otoliths'
        adapted 0.4 of the first specific force.
        """
        f = np.asarray(f, dtype=float)
        w = np.asarray(w, dtype=float)
        if f.ndim != 2 or f.shape[1] != 3 or w.shape != f.shape:
            raise ValueError(f"f and w must both be (n, 3), got {f.shape} and {w.shape}")
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(w))):
            raise ValueError("motion to perceive is not finite")
        fz = f - np.array([0.0, 0.0, self.gravity])
        f_hat = np.empty_like(f)
        w_hat = np.empty_like(w)
        onum, oden = self.otolith.tf()
        for k in range(3):
            cnum, cden = self.canal.tf(k)
            oto = DiscreteFilter(onum, oden, dt)
            if fz.shape[0]:
                oto.reset(fz[0, k])
            f_hat[:, k] = oto.run(fz[:, k])
            scc = DiscreteFilter(cnum, cden, dt)
            if w.shape[0]:
                scc.reset(w[0, k])  # adapted: a constant rate is not felt (DC gain 0)
            w_hat[:, k] = scc.run(w[:, k])
        return Perception(
            f=f_hat,
            w=w_hat,
            f_threshold=np.asarray(self.otolith.thresholds, float),
            w_threshold=np.asarray(self.canal.thresholds, float),
        )
