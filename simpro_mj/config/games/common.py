"""What the packet modules share: the error a receiver counts, the checks, gravity in V."""

from __future__ import annotations

import math

from controllers.frames import GRAVITY

#: Largest accepted specific force component (m/s^2): 10 g, beyond any car's.
MAX_SPECIFIC_FORCE = 10.0 * GRAVITY
#: Largest accepted angular rate component (rad/s): a car spinning at 3 turns/s.
MAX_RATE = 6.0 * math.pi


class DatagramError(ValueError):
    """A datagram that is not a sample; ``kind`` says why.

    ``short``, ``oversized``, ``malformed`` (garbage, counted in ``bad``), or
    ``idle``: a well-formed packet saying the game is not driving (Forza's
    ``IsRaceOn = 0`` in menus), skipped so that the input goes stale and fades
    to rest.
    """

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind


def check(t, f, w) -> tuple:
    """``(t, f, w)`` if finite and plausible, else :class:`DatagramError` ``malformed``."""
    vals = (*f, *w) if t is None else (t, *f, *w)
    if not all(map(math.isfinite, vals)):
        raise DatagramError("malformed", "a value is not finite")
    if t is not None and t < 0:
        raise DatagramError("malformed", f"time {t:g} s < 0")
    if max(abs(v) for v in f) > MAX_SPECIFIC_FORCE or max(abs(v) for v in w) > MAX_RATE:
        raise DatagramError(
            "malformed",
            f"f={f}, w={w}: allowed |f| <= {MAX_SPECIFIC_FORCE:g} m/s^2, |w| <= {MAX_RATE:g} rad/s",
        )
    return t, tuple(f), tuple(w)


def gravity_v(roll: float, pitch: float) -> tuple[float, float, float]:
    """Gravity's part of the specific force in V for ISO roll ``phi`` (right side down > 0)
    and pitch ``theta`` (nose down > 0): ``g (-sin theta, sin phi cos theta, cos phi cos theta)``,
    the world's up seen from the car times g (nose up by p at rest: ``fx = +g sin p``)."""
    ct = math.cos(pitch)
    return (
        -GRAVITY * math.sin(pitch),
        GRAVITY * math.sin(roll) * ct,
        GRAVITY * math.cos(roll) * ct,
    )


def tilt_v(up) -> tuple[float, float]:
    """ISO ``(roll, pitch)`` of a car that sees the world's up as the unit vector ``up`` (V):
    the inverse of :func:`gravity_v` (for the packers)."""
    pitch = -math.asin(max(-1.0, min(1.0, up[0])))
    return math.atan2(up[1], up[2]), pitch
