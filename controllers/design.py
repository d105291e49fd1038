"""Joint-loop plants and pole-placement design (paper eqs. 19, 28-29, 34-37).

Plant (eq. 19), identified per actuator (eqs. 34-35)::

    G(s) = b / (s (s^2 + a1 s + a0))

Controller (eq. 28 is lost in our copy; its form is read from eqs. 29 and
36-37)::

    C(s) = k_p (s + k_i) (s^2 + n1 s + n0) / (s (s^2 + c1 s + c0))

with ``(n1, n0) = (a1, a0)`` in the intended design: the controller's
numerator quadratic cancels the plant's poles. The loop is then
``L = C G = k_p b (s + k_i) / (s^2 (s^2 + c1 s + c0))`` (type 2: one
integrator from the cylinder, one from the controller) and the full
characteristic polynomial factors as::

    (s^2 + a1 s + a0) * [s^2 (s^2 + c1 s + c0) + k_p b (s + k_i)]

The bracket is a *4th-order* polynomial with four free coefficients
``(c1, c0, k_p b, k_p b k_i)``: exactly the four poles of eq. (29),
``(s + p1)(s + p2)(s^2 + 2 zeta wn s + wn^2)``. Matching
``s^4 + d3 s^3 + d2 s^2 + d1 s + d0`` gives the unique solution::

    c1 = d3,  c0 = d2,  k_p = d1 / b,  k_i = d0 / d1

so ``1 / k_i = d1 / d0 = 1/p1 + 1/p2 + 2 zeta / wn``: the closed-loop zero
``-k_i`` is always *slower* than every closed-loop pole, and it can never
cancel one of them (that would need ``k_i = 0``). The step response
therefore overshoots more than the 4.6 % of a ``zeta = 0.7`` pair.

The plant's quadratic stays a closed-loop mode (cancelled, so it is not seen
from the reference but it is excited by load disturbances): for actuators 2-3
it is ``zeta = 0.099, wn = 36.7 rad/s``.

Units of eqs. (34)-(37): the paper's reading
--------------------------------------------
The paper prints its plants and controllers without units. Two readings
(:data:`READINGS`, one parameter everywhere eqs. 34-37 are used):

* ``"volts"`` (default): Y is the joint potentiometer's signal in volts, as
  the rig reads it through the MF624 (section 5): 10 V over the 500 mm
  stroke, :data:`POTENTIOMETER_V_PER_M` = 20 V/m. In SI the plant gain is
  ``b / 20`` (m s^-3 V^-1) and the controller gain ``20 k_p`` (V/m).
* ``"metres"``: Y in metres, the numbers used as printed.

``k_p b`` (the reduced loop of eq. 29) is the same under both readings; the
reading matters wherever a paper number meets the SI plant of this
simulation. :data:`PLANTS` and :data:`PRINTED` are the paper's numbers as
printed; :func:`paper_plant` and the ``reading`` argument of the design
functions give them in SI.

Only numpy is imported here.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal, get_args

import numpy as np

from .errors import DesignError

__all__ = [
    "Plant",
    "JointDesign",
    "PLANTS",
    "PRINTED",
    "READINGS",
    "DEFAULT_READING",
    "POTENTIOMETER_V_PER_M",
    "paper_scale",
    "paper_units_info",
    "paper_coefficients",
    "paper_plant",
    "PAPER_SPEC",
    "printed_design",
    "corrected_design",
    "redesigned_design",
    "design_for",
    "place_poles",
    "nondominant_poles_from_denominator",
    "closed_loop_polynomial",
    "reduced_polynomial",
    "closed_loop_poles",
    "closed_loop_tf",
    "damping",
]

ACTUATORS = ("actuator1", "actuator2", "actuator3")
#: The inner loop's design (module docstring).
Variant = Literal["printed", "corrected", "redesigned"]
VARIANTS: tuple[Variant, ...] = get_args(Variant)

#: Readings of the unit of Y in eqs. (34)-(37) (module docstring).
Reading = Literal["volts", "metres"]
READINGS: tuple[Reading, ...] = get_args(Reading)
DEFAULT_READING = "volts"
#: Joint potentiometer: 10 V over the 500 mm stroke of the DNC-125-500 (section 5).
POTENTIOMETER_V_PER_M = 10.0 / 0.5


@dataclass(frozen=True)
class Plant:
    """Identified cylinder model ``b / (s (s^2 + a1 s + a0))`` (eq. 19), m per V."""

    b: float
    a1: float
    a0: float

    @property
    def num(self) -> np.ndarray:
        return np.array([self.b], dtype=float)

    @property
    def den(self) -> np.ndarray:
        return np.array([1.0, self.a1, self.a0, 0.0])


@dataclass(frozen=True)
class JointDesign:
    """``C(s) = k_p (s + k_i)(s^2 + n1 s + n0) / (s (s^2 + c1 s + c0))`` (eq. 28 form)."""

    kp: float
    ki: float
    n1: float
    n0: float
    c1: float
    c0: float

    @property
    def num(self) -> np.ndarray:
        return self.kp * np.polymul([1.0, self.ki], [1.0, self.n1, self.n0])

    @property
    def den(self) -> np.ndarray:
        return np.array([1.0, self.c1, self.c0, 0.0])

    def as_dict(self) -> dict:
        return {k: float(getattr(self, k)) for k in ("kp", "ki", "n1", "n0", "c1", "c0")}


#: Eqs. (34)-(35); eq. (35) prints "s^2 + 7.276 + 1349" (an s is missing).
PLANTS: dict[str, Plant] = {
    "actuator1": Plant(b=245.94, a1=27.72, a0=253.0),
    "actuator2": Plant(b=2008.3, a1=7.276, a0=1349.0),
    "actuator3": Plant(b=2008.3, a1=7.276, a0=1349.0),
}

#: Eqs. (36)-(37) verbatim: the numerator quadratic prints 7.726 for both.
PRINTED: dict[str, JointDesign] = {
    "actuator1": JointDesign(kp=265.0, ki=3.03, n1=7.726, n0=253.0, c1=146.7, c0=6267.0),
    "actuator2": JointDesign(kp=32.0, ki=3.03, n1=7.726, n0=1349.0, c1=146.7, c0=6267.0),
    "actuator3": JointDesign(kp=32.0, ki=3.03, n1=7.726, n0=1349.0, c1=146.7, c0=6267.0),
}

#: The specification of section 5.2.2: dominant zeta = 0.7, wn = 10 rad/s.
PAPER_SPEC = {"zeta": 0.7, "wn": 10.0}


def _check_actuator(actuator: str) -> None:
    if actuator not in PLANTS:
        raise DesignError(f"unknown actuator {actuator!r}; allowed: {list(ACTUATORS)}")


def paper_scale(reading: str = DEFAULT_READING) -> float:
    """Volts of eqs. (34)-(37)'s Y per metre of slide: 20 (``"volts"``) or 1 (``"metres"``)."""
    if reading == "volts":
        return POTENTIOMETER_V_PER_M
    if reading == "metres":
        return 1.0
    raise DesignError(f"unknown units reading {reading!r}; allowed: {list(READINGS)}")


def paper_units_info(reading: str = DEFAULT_READING) -> dict:
    """What ``reading`` means, for reports: ``{reading, y_per_metre, y_unit}``."""
    scale = paper_scale(reading)
    unit = "V (joint potentiometer, 10 V / 500 mm)" if reading == "volts" else "m"
    return {"reading": reading, "y_per_metre": scale, "y_unit": unit}


def paper_coefficients(reading: str = DEFAULT_READING) -> tuple[list, list, list]:
    """``(b, a1, a0)`` per actuator (lists of 3) of eqs. (34)-(35) in SI under ``reading``."""
    plants = [paper_plant(a, reading) for a in ACTUATORS]
    return [p.b for p in plants], [p.a1 for p in plants], [p.a0 for p in plants]


def paper_plant(actuator: str, reading: str = DEFAULT_READING) -> Plant:
    """Eq. (34) or (35) in SI (m per V) under ``reading``: ``b / paper_scale(reading)``."""
    _check_actuator(actuator)
    p = PLANTS[actuator]
    return replace(p, b=p.b / paper_scale(reading))


def printed_design(actuator: str, reading: str | None = None) -> JointDesign:
    """Eq. (36) (actuator1) or eq. (37) (actuator2, actuator3) exactly as printed.

    ``reading=None`` returns the printed numbers (paired with :data:`PLANTS`);
    a reading returns the controller in SI (V per m): ``k_p paper_scale(reading)``.
    """
    _check_actuator(actuator)
    d = PRINTED[actuator]
    return d if reading is None else replace(d, kp=d.kp * paper_scale(reading))


def corrected_design(actuator: str, plant: Plant | None = None) -> JointDesign:
    """Eqs. (36)-(37) with the numerator quadratic set to ``plant``'s (7.726 -> a1).

    The paper's design is a pole placement on the cancelled loop, which
    depends on ``k_p b`` only (eq. 29). On a plant other than the printed one
    the gain is rescaled to keep the printed product: ``k_p = 265 x 245.94 / b``
    (actuator 1), ``32 x 2008.3 / b`` (2-3). On :func:`paper_plant` under a
    reading this is the printed ``k_p`` in that reading's units (``20 k_p``
    V/m for ``"volts"``); on an identified plant it keeps the printed design's
    closed-loop poles.
    """
    _check_actuator(actuator)
    p = PLANTS[actuator] if plant is None else plant
    if not (np.isfinite(p.b) and p.b > 0):
        raise DesignError(f"corrected design: plant gain b = {p.b} must be a positive number")
    pr = PRINTED[actuator]
    kp = pr.kp * PLANTS[actuator].b / p.b
    return replace(pr, kp=float(kp), n1=p.a1, n0=p.a0)


def nondominant_poles_from_denominator(
    c1: float, c0: float, zeta: float, wn: float
) -> tuple[float, float]:
    """(p1, p2) such that ``d3 = c1`` and ``d2 = c0`` for the given dominant pair.

    With ``(s + p1)(s + p2) = s^2 + sigma s + pi``:
    ``c1 = sigma + 2 zeta wn`` and ``c0 = pi + 2 zeta wn sigma + wn^2``.
    Applied to the printed denominator ``s^2 + 146.7 s + 6267`` and the
    paper's spec this gives ``p1, p2 = 76.0, 56.7`` exactly: the printed
    denominators are consistent with eq. (29); the printed k_p, k_i are not.
    """
    sigma = c1 - 2.0 * zeta * wn
    prod = c0 - 2.0 * zeta * wn * sigma - wn**2
    disc = sigma**2 - 4.0 * prod
    if disc < 0 or prod <= 0 or sigma <= 0:
        raise DesignError(
            f"denominator s^2 + {c1} s + {c0} admits no real non-dominant poles for "
            f"zeta={zeta}, wn={wn} (sigma={sigma:.4g}, product={prod:.4g})"
        )
    r = np.sqrt(disc)
    return float((sigma + r) / 2.0), float((sigma - r) / 2.0)


def place_poles(
    plant: Plant,
    zeta: float,
    wn: float,
    p1: float,
    p2: float,
    rtol: float = 1e-8,
) -> JointDesign:
    """Pole placement for the eq. (28) controller so that eq. (29) holds.

    Solves ``s^2 (s^2 + c1 s + c0) + k_p b (s + k_i) =
    (s + p1)(s + p2)(s^2 + 2 zeta wn s + wn^2) = s^4 + d3 s^3 + d2 s^2 + d1 s + d0``::

        c1 = d3,   c0 = d2,   k_p = d1 / b,   k_i = d0 / d1

    and cancels the plant quadratic (``n1, n0 = a1, a0``).

    Parameters
    ----------
    plant : Plant
        ``b / (s (s^2 + a1 s + a0))``; its quadratic must be Hurwitz
        (``a1 > 0, a0 > 0``) since it becomes a closed-loop mode.
    zeta, wn : float
        Dominant pair, ``zeta > 0``, ``wn > 0`` (rad/s).
    p1, p2 : float
        Non-dominant real poles at ``-p1, -p2`` (rad/s), positive.
    rtol : float
        Relative tolerance of the numerical pole check.

    Returns
    -------
    JointDesign

    Raises
    ------
    DesignError
        Infeasible specification (non-positive poles or gain, a plant whose
        cancelled quadratic is not stable, ``b = 0``) or poles not reproduced
        numerically.
    """
    vals = {"b": plant.b, "a1": plant.a1, "a0": plant.a0, "zeta": zeta, "wn": wn}
    vals.update(p1=p1, p2=p2)
    for k, v in vals.items():
        if not np.isfinite(v):
            raise DesignError(f"pole placement: {k} = {v} is not finite")
    if plant.b == 0:
        raise DesignError("pole placement: plant gain b = 0 (uncontrollable)")
    if plant.a1 <= 0 or plant.a0 <= 0:
        raise DesignError(
            f"pole placement: plant quadratic s^2 + {plant.a1} s + {plant.a0} is not "
            "Hurwitz; cancelling it would leave an unstable closed-loop mode"
        )
    if zeta <= 0 or wn <= 0:
        raise DesignError(f"pole placement: need zeta > 0 and wn > 0, got {zeta}, {wn}")
    if p1 <= 0 or p2 <= 0:
        raise DesignError(f"pole placement: non-dominant poles must be > 0, got {p1}, {p2}")
    d = np.polymul(np.polymul([1.0, p1], [1.0, p2]), [1.0, 2.0 * zeta * wn, wn**2])
    _, d3, d2, d1, d0 = d
    design = JointDesign(
        kp=float(d1 / plant.b), ki=float(d0 / d1), n1=plant.a1, n0=plant.a0, c1=d3, c0=d2
    )
    # verify: reduced characteristic polynomial roots == requested poles
    want = np.sort_complex(np.roots(d))
    got = np.sort_complex(np.roots(reduced_polynomial(design, plant)))
    scale = max(abs(want).max(), 1.0)
    if np.max(np.abs(want - got)) > max(rtol * scale, 1e-6 * scale):
        raise DesignError(f"pole placement: poles {got} do not match the spec {want}")
    return design


def redesigned_design(
    actuator: str,
    zeta: float = PAPER_SPEC["zeta"],
    wn: float = PAPER_SPEC["wn"],
    p1: float | None = None,
    p2: float | None = None,
    plant: Plant | None = None,
) -> JointDesign:
    """Pole placement meeting the paper's spec.

    Default non-dominant poles: those implied by the printed denominator
    (``p1, p2 = 76.0, 56.7`` rad/s, see :func:`nondominant_poles_from_denominator`),
    so the redesign keeps eqs. (36)-(37)'s denominator and only changes
    ``k_p`` and ``k_i``.
    """
    _check_actuator(actuator)
    p = PLANTS[actuator] if plant is None else plant
    if p1 is None or p2 is None:
        pr = PRINTED[actuator]
        q1, q2 = nondominant_poles_from_denominator(pr.c1, pr.c0, zeta, wn)
        p1 = q1 if p1 is None else p1
        p2 = q2 if p2 is None else p2
    return place_poles(p, zeta, wn, p1, p2)


def design_for(
    actuator: str, variant: str, plant: Plant | None = None, reading: str | None = None, **spec
) -> JointDesign:
    """The controller of ``variant`` in {'printed', 'corrected', 'redesigned'}.

    ``plant`` is the design plant (default: eq. 34/35 as printed, or in SI
    under ``reading``); ``reading`` also sets the units of the printed
    controller (``None``: as printed, paired with :data:`PLANTS`).
    """
    if plant is None and reading is not None:
        plant = paper_plant(actuator, reading)
    if variant == "printed":
        return printed_design(actuator, reading)
    if variant == "corrected":
        return corrected_design(actuator, plant)
    if variant == "redesigned":
        return redesigned_design(actuator, plant=plant, **spec)
    raise DesignError(f"unknown controller variant {variant!r}; allowed: {list(VARIANTS)}")


def reduced_polynomial(design: JointDesign, plant: Plant) -> np.ndarray:
    """``s^2 (s^2 + c1 s + c0) + k_p b (s + k_i)``: valid when the quadratic cancels."""
    return np.polyadd(
        [1.0, design.c1, design.c0, 0.0, 0.0], design.kp * plant.b * np.array([1.0, design.ki])
    )


def closed_loop_polynomial(design: JointDesign, plant: Plant) -> np.ndarray:
    """Full characteristic polynomial ``den_C den_G + num_C num_G`` (6th order)."""
    return np.polyadd(np.polymul(design.den, plant.den), np.polymul(design.num, plant.num))


def closed_loop_poles(design: JointDesign, plant: Plant) -> np.ndarray:
    """All six closed-loop poles, cancelled plant modes included, sorted by |p|.

    When the numerator quadratic equals the plant's (to 1e-12), the poles are
    computed from the two factors separately (better conditioned than the
    6th-order polynomial).
    """
    if np.isclose(design.n1, plant.a1, rtol=1e-12) and np.isclose(design.n0, plant.a0, rtol=1e-12):
        poles = np.concatenate(
            [np.roots(reduced_polynomial(design, plant)), np.roots([1.0, plant.a1, plant.a0])]
        )
    else:
        poles = np.roots(closed_loop_polynomial(design, plant))
    return poles[np.lexsort((poles.imag, np.abs(poles)))]


def closed_loop_tf(design: JointDesign, plant: Plant) -> tuple[np.ndarray, np.ndarray]:
    """Reference-to-position closed loop ``CG / (1 + CG)`` as (num, den), full order."""
    return np.polymul(design.num, plant.num), closed_loop_polynomial(design, plant)


def damping(poles) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequency |p| (rad/s) and damping ratio -Re(p)/|p| of s-plane poles."""
    poles = np.asarray(poles, dtype=complex)
    wn = np.abs(poles)
    with np.errstate(invalid="ignore", divide="ignore"):
        zeta = np.where(wn > 0, -poles.real / wn, 1.0)
    return wn, zeta
