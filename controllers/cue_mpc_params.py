"""Parameters of the model-predictive cueing law (:mod:`controllers.mpc_cueing`).

One frozen record, SI (rad, s, m), each field checked against its range when made: a
value out of range raises :class:`MpcParamError` naming the field and what it allows.
The scenario's YAML keys (degrees, millimetres, named units) map onto these fields in
:data:`simpro_mj.config.cueing.MPC_PARAMETER_KEYS`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .geometry import HEAD_HEIGHT_PITCH, HEAD_HEIGHT_ROLL
from .law_params import LawParams, ranged


class MpcParamError(ValueError):
    """An MPC cueing parameter out of its allowed range; the message names the field."""


@dataclass(frozen=True)
class MpcParams(LawParams):
    """Parameters of :class:`~controllers.mpc_cueing.ModelPredictiveCueing`, SI (rad, s, m).

    Attributes
    ----------
    period : float
        Solve period (s), 0.06: the outer loop's period of the shipped scenarios.
    horizon : int
        Prediction horizon in periods, 20 (1.2 s: longer than the otoliths' 0.66 s
        and the 0.28 s of the head-offset zero, shorter than the adaptation).
    gain_x, gain_y, gain_z, gain_rot : float
        Scale of the vehicle's specific force (x, y, z) and rotation rates that the
        platform is asked to reproduce.
    weight_f, weight_raw, weight_w, weight_tilt, weight_jerk : float
        Cost weights (dimensionless: each error in units of its threshold, the
        tilt in units of its limit, the jerk in units of ``accel_max / period``).
    tilt_rate_max, tilt_accel_max : float
        The platform's tilt rate (rad/s) and acceleration (rad/s^2) limits: 15 deg/s
        and 30 deg/s^2, inside what the feed-forward loop follows (about 2.9 Hz,
        docs/feedforward.md).
    heave_rate_max, heave_accel_max : float
        Heave rate (m/s) and acceleration (m/s^2) limits.
    head_height, head_height_pitch : float
        The head above the roll axis (m), 0.75 (the MJCF ``head`` site), and above
        the pitch motion's axis, 1.21 (measured): :data:`controllers.geometry.HEAD_HEIGHT_ROLL`
        and ``HEAD_HEIGHT_PITCH``.
    preview : float
        Look-ahead into the vehicle input (s), 0: none (the vehicle input is held).
    heave_fraction, stroke_margin : float
        As :class:`controllers.washout.WashoutParams`: the workspace box.
    box_fraction : float
        Share of the box's half-range the tilt and heave may use, 0.95.
    rotation_limit, rotation_limit_pitch : float
        The head's felt roll (pitch) (canal model) may exceed the vehicle's by at
        most this many canal thresholds, 0.7 (0.8) (a constraint; 0 turns it off):
        the tilt that makes a specific force is not felt as a rotation.
    lead : float
        The specific-force cue is planned ``lead`` (s) ahead of the recording, as far
        as ``preview`` reaches (0 without preview); the car's rotation stays on time.
        It makes up for the otoliths' lag behind a scaled cue.
    lead_x : float
        The surge cue's lead (s), at least ``lead``: 0 (the default) leaves it at
        ``lead``. A sustained surge is carried by a pitch tilt that may come only as
        fast as the canals do not feel it; planning it earlier than the sway (whose
        quick reversals a larger lead spoils: docs/cueing.md) lets a car that does not
        pitch when it brakes be cued within the lag floor.
    loop_omega, loop_zeta, loop_zero, loop_delay : float
        The platform loop from set-point to pose, ``(T_z s + 1) w^2 / (s^2 + 2 zeta
        w s + w^2) e^(-s T_d)``: 5.0 rad/s, 0.72, 0.31 s, 0.03 s, fitted on the
        shipped feed-forward loop's runs (docs/cueing.md); the set-point is the plan
        through its inverse (:meth:`controllers.mpc_cueing.ModelPredictiveCueing._loop_inverse`).
        ``loop_omega`` 0: the plan itself.
    loop_filter : float
        A lag (s), 0.05, bounding the inverse's gain above the loop's bandwidth.
    knee : float
        Surge and sway scaled by ``gain f + (1 - gain) knee tanh(f / knee)``
        (m/s^2): a weak cue at full size. 0 (the default): ``gain f``.
    jolt_limit : float
        Where the car's surge or sway specific force is past the otoliths'
        threshold, the planned head's may not point the other way by more than this
        (m/s^2), 0.01 (a constraint; 0 turns it off).
    heave_washout : float
        Corner (rad/s) of the first-order high-pass on the heave target, 0.5 (a 2 s
        time constant; 0 turns it off): a constant offset of ``f_z`` (a biased
        accelerometer: 9.6 instead of 9.81 m/s^2) fades from the target instead of
        holding the platform off home, or drifting it when the offset ends.
    weight_heave, weight_heave_rate : float
        Cost weights of the heave's position (in units of its box half-range) and rate
        (in units of ``heave_rate_max``), 1 and 0.1: without them and the high-pass (the
        position weighted as the tilt's, 0.01, no rate) the otoliths' slow error (5.33 s)
        lets the plan coast, 42 mm off home 4 s after a biased input fades; with them
        0.1 mm. They cost the heave cue (OMCT, 0.3 m/s^2: with 1 s of preview 0.45 to
        0.33 at 4 rad/s, 0.37 at 10 rad/s either way; without preview 0.17 to 0.12 and
        0.15).
    gain_y_sustained, sustained_tau : float
        A sway gain for the sustained part of the car's lateral force: the roll target
        is ``gain_y f + (gain_y_sustained - gain_y) LP(f)`` with ``LP`` a first-order
        low-pass of time constant ``sustained_tau`` (s), 1.0; ``gain_y_sustained`` 0 (the
        default) turns it off. A turn's held force asks for more than a lane change's
        quick reversal (docs/cueing.md: 0.4 lifts the braking in a turn's sway to 0.80 of
        the bound and leaves the lane change's at 0.75, its onset at 0.30 s).
    """

    _LABEL = "mpc"
    _ERROR = MpcParamError

    period: float = ranged(0.06, lambda v: 0 < v <= 0.5, "> 0 and <= 0.5 s")
    horizon: int = ranged(20, lambda v: v == int(v) and 2 <= v <= 200, "a whole number 2..200")
    gain_x: float = ranged(0.3, lambda v: 0 <= v <= 2, "0..2")
    gain_y: float = ranged(0.3, lambda v: 0 <= v <= 2, "0..2")
    gain_z: float = ranged(0.5, lambda v: 0 <= v <= 2, "0..2")
    gain_rot: float = ranged(1.0, lambda v: 0 <= v <= 2, "0..2")
    weight_f: float = ranged(1.0, lambda v: v >= 0, ">= 0")
    weight_raw: float = ranged(0.3, lambda v: v >= 0, ">= 0")
    weight_w: float = ranged(6.0, lambda v: v >= 0, ">= 0")
    weight_tilt: float = ranged(0.01, lambda v: v >= 0, ">= 0")
    weight_jerk: float = ranged(1e-3, lambda v: v > 0, "> 0")
    tilt_rate_max: float = ranged(math.radians(15.0), lambda v: v > 0, "> 0 rad/s")
    tilt_accel_max: float = ranged(math.radians(30.0), lambda v: v > 0, "> 0 rad/s^2")
    heave_rate_max: float = ranged(0.2, lambda v: v > 0, "> 0 m/s")
    heave_accel_max: float = ranged(3.0, lambda v: v > 0, "> 0 m/s^2")
    head_height: float = ranged(HEAD_HEIGHT_ROLL, lambda v: 0 <= v <= 2, "0..2 m")
    head_height_pitch: float = ranged(HEAD_HEIGHT_PITCH, lambda v: 0 <= v <= 2, "0..2 m")
    preview: float = ranged(0.0, lambda v: 0 <= v <= 10, "0..10 s")
    heave_fraction: float = ranged(0.25, lambda v: 0 < v <= 1, "in (0, 1]")
    stroke_margin: float = ranged(0.01, lambda v: 0 <= v < 0.2, "0..0.2 m")
    box_fraction: float = ranged(0.95, lambda v: 0 < v <= 1, "in (0, 1]")
    rotation_limit: float = ranged(0.7, lambda v: v >= 0, ">= 0 (0: off)")
    rotation_limit_pitch: float = ranged(0.8, lambda v: v >= 0, ">= 0 (0: off)")
    lead: float = ranged(0.0, lambda v: 0 <= v <= 0.5, "0..0.5 s")
    lead_x: float = ranged(0.0, lambda v: 0 <= v <= 0.5, "0..0.5 s")
    loop_omega: float = ranged(
        5.0, lambda v: v == 0 or 0.5 <= v <= 500, "0 (off) or 0.5..500 rad/s"
    )
    loop_zeta: float = ranged(0.72, lambda v: 0.05 <= v <= 5, "0.05..5")
    loop_zero: float = ranged(0.31, lambda v: 0 <= v <= 5, "0..5 s")
    loop_delay: float = ranged(0.03, lambda v: 0 <= v <= 0.5, "0..0.5 s")
    loop_filter: float = ranged(0.05, lambda v: 0 <= v <= 0.5, "0..0.5 s")
    knee: float = ranged(0.0, lambda v: 0 <= v <= 5, "0 (linear) or up to 5 m/s^2")
    jolt_limit: float = ranged(0.01, lambda v: 0 <= v <= 5, "0 (off) or up to 5 m/s^2")
    heave_washout: float = ranged(0.5, lambda v: 0 <= v <= 10, "0 (off) or up to 10 rad/s")
    weight_heave_rate: float = ranged(0.1, lambda v: v >= 0, ">= 0")
    weight_heave: float = ranged(1.0, lambda v: v >= 0, ">= 0")
    gain_y_sustained: float = ranged(0.0, lambda v: 0 <= v <= 2, "0 (off) or up to 2")
    sustained_tau: float = ranged(1.0, lambda v: 0.05 <= v <= 20, "0.05..20 s")
