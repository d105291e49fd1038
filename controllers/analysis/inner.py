"""One joint loop, continuous: its realisation, step response and step information
(eqs. 34-37; python-control's ``step_response`` and ``step_info``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controllers.design import (
    DEFAULT_READING,
    closed_loop_poles,
    closed_loop_tf,
    damping,
    design_for,
    paper_plant,
)


# --------------------------------------------------------------------------
# Inner loops
# --------------------------------------------------------------------------
def companion(num, den):
    """Controllable canonical ``(A, B, C, D)`` of ``num / den``.

    Kept by hand (it runs in every run's preflight, which python-control's
    1-2 s import would slow): equal to :func:`control.tf2ss` exactly
    (``tests/test_analysis.py``).
    """
    num = np.atleast_1d(np.asarray(num, float))
    den = np.asarray(den, float)
    num, den = num / den[0], den / den[0]
    n = den.size - 1
    num = np.r_[np.zeros(n + 1 - num.size), num]
    d = num[0]
    nn = num[1:] - d * den[1:]
    a = np.zeros((n, n))
    a[0, :] = -den[1:]
    a[1:, :-1] = np.eye(n - 1)
    b = np.zeros((n, 1))
    b[0, 0] = 1.0
    return a, b, nn[None, :], np.array([[d]])


def tf_step(num, den, t) -> np.ndarray:
    """Samples of the continuous unit-step response on a uniform grid t.

    python-control's :func:`control.step_response`, which integrates the
    state-space realisation exactly between samples (zero-order hold of the
    step), so the samples carry no discretisation error. The step is applied
    at ``t[0]`` with the system at rest.
    """
    import control  # imported on use: ``import controllers`` stays light

    t = np.asarray(t, float)
    res = control.step_response(control.tf(num, den), T=t)
    return np.asarray(res.outputs, float).reshape(-1)


def step_metrics(t, y, final: float | None = None, settle: float = 0.02) -> dict:
    """Rise time 10-90 %, settling time (band ``settle``), overshoot (%) of a step.

    :func:`control.step_info` on the samples with ``final`` as the steady
    state (default the last sample). A response that never reaches 90 % of it
    has no rise time, overshoot or settling (NaN, 0, NaN: ``step_info`` would
    raise); a zero final value is refused (``step_info`` divides by it).
    """
    import control  # imported on use: ``import controllers`` stays light

    t = np.asarray(t, float)
    y = np.asarray(y, float)
    yf = float(y[-1]) if final is None else float(final)
    if yf == 0.0:
        raise ValueError("step_metrics: the final value is 0; allowed: a step to a non-zero value")
    nan = float("nan")
    if not np.any(np.sign(yf) * (y - 0.9 * yf) >= 0):
        return {"final": yf, "rise_time_s": nan, "overshoot_pct": 0.0, "settling_time_s": nan}
    info = control.step_info(
        y, T=t, yfinal=yf, SettlingTimeThreshold=settle, RiseTimeLimits=(0.1, 0.9)
    )
    return {
        "final": yf,
        "rise_time_s": float(info["RiseTime"]),
        "overshoot_pct": float(info["Overshoot"]),
        "settling_time_s": float(info["SettlingTime"]),
    }


@dataclass
class InnerSummary:
    """One continuous joint loop (:func:`inner_summary`): its controller
    (:meth:`~controllers.design.JointDesign.as_dict`), closed-loop poles with their
    natural frequencies (rad/s) and damping ratios, the step response ``y`` at ``t``
    and its figures (:func:`step_metrics`)."""

    controller: dict
    closed_loop_poles: np.ndarray
    wn_rad_s: np.ndarray
    zeta: np.ndarray
    step: dict
    t: np.ndarray
    y: np.ndarray


def inner_summary(
    actuator: str,
    variant: str,
    t_end: float = 3.0,
    dt: float = 1e-3,
    spec=None,
    reading: str = DEFAULT_READING,
) -> InnerSummary:
    """Closed-loop poles, damping and step metrics of one continuous joint loop.

    The plant is eq. (34)/(35) and the controller eq. (36)/(37) in SI under
    ``reading`` (:data:`controllers.design.READINGS`); the closed loop does
    not depend on the reading (``k_p b`` does not), the printed ``k_p`` does.
    """
    plant = paper_plant(actuator, reading)
    spec = dict(spec or {}) if variant == "redesigned" else {}
    des = design_for(actuator, variant, plant=plant, reading=reading, **spec)
    poles = closed_loop_poles(des, plant)
    wn, zeta = damping(poles)
    t = np.arange(0.0, t_end + dt / 2, dt)
    y = tf_step(*closed_loop_tf(des, plant), t)
    return InnerSummary(des.as_dict(), poles, wn, zeta, step_metrics(t, y, final=1.0), t, y)
