"""One axis of the MPC cueing law's model: platform, otoliths and canals, linear.

Per tilt axis (pitch, or roll as ``a = -phi``) and for heave, the state-space model that
:class:`controllers.mpc_cueing.ModelPredictiveCueing` predicts with (the maths is in
that module's docstring): the platform's triple integrator under the jerk, the otolith
error of the head's specific force against the scaled vehicle's, the canal error of its
rotation and the vehicle's own canal sensation, and the rows the cost and the
constraints read, discretised at the law's period by the zero-order hold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .analysis.inner import companion
from .cue_mpc_params import MpcParams
from .frames import GRAVITY
from .vestibular import CanalModel, OtolithModel


def discretise(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation by the block matrix exponential."""
    from scipy.linalg import expm

    n, m = a.shape[0], b.shape[1]
    big = np.zeros((n + m, n + m))
    big[:n, :n] = a
    big[:n, n:] = b
    e = expm(big * dt)
    return e[:n, :n], e[:n, n:]


@dataclass
class AxisPrediction:
    """One axis' prediction over the MPC's horizon (built by
    :class:`~controllers.mpc_cueing.ModelPredictiveCueing`): ``X = phi x_0 + gam u +
    psi d``; the weighted cost outputs ``CY X + DY d`` (``G = CY gam``); the constrained
    rows ``S X`` (``rows`` a sample), with the vehicle's felt rotation ``veh`` (its state
    and input maps) and the indices of the felt-rotation and jolt rows (None: not
    constrained); ``shift`` takes each output to its sample's input."""

    phi: np.ndarray
    psi: np.ndarray
    CY: np.ndarray
    DY: np.ndarray
    G: np.ndarray
    S: np.ndarray
    rows: int
    veh: tuple[np.ndarray, np.ndarray] | None
    felt: int | None
    jolt: int | None
    shift: np.ndarray

    def bounds(self, ax: MpcAxis, cveh, target, limit: float, n: int):
        """The constrained rows' bounds over ``n`` samples, (n, rows) each: +-1 (the
        pose's limits); the felt rotation within ``limit`` thresholds of the vehicle's
        ``cveh``; where the car's specific force ``target`` is past the otoliths'
        threshold, the head's not the other way by more than jolt_limit (its units)."""
        lo, hi = -np.ones((n, self.rows)), np.ones((n, self.rows))
        if cveh is not None:
            lo[:, self.felt] = np.minimum(cveh, 0.0) - limit
            hi[:, self.felt] = np.maximum(cveh, 0.0) + limit
        if self.jolt is not None:
            thr = ax.thr_f * ax.kf  # the car's past its threshold
            lo[:, self.jolt] = np.where(target > thr, -1.0, -np.inf)
            hi[:, self.jolt] = np.where(target < -thr, 1.0, np.inf)
        return lo, hi


class MpcAxis:
    """One channel's linear model: state, inputs (jerk, vehicle f, vehicle w) and the
    cost and constraint outputs, continuous and discretised at the period."""

    def __init__(self, kind: str, p: MpcParams, oto: OtolithModel, scc: CanalModel, amax):
        h = p.head_height_pitch if kind == "pitch" else p.head_height
        g = GRAVITY
        oa, ob, oc, od = companion(*oto.tf())
        self.kind = kind
        if kind == "heave":
            sigma, no_, nc = 0.0, oa.shape[0], 0
            kf, kw = p.gain_z, 0.0
            ca = cb = cc = cd = None
            thr_f, thr_w = oto.thresholds[2], 1.0
        else:
            sigma = 1.0 if kind == "pitch" else -1.0
            tau_l = (
                scc.tau_l[0 if kind == "roll" else 1]
                if isinstance(scc.tau_l, tuple)
                else (scc.tau_l)
            )
            k = scc.tau_a * tau_l
            ca, cb, cc, cd = companion([k, 0.0, 0.0], np.polymul([scc.tau_a, 1.0], [tau_l, 1.0]))
            no_, nc = oa.shape[0], ca.shape[0]
            kf, kw = (p.gain_x, p.gain_rot) if kind == "pitch" else (p.gain_y, p.gain_rot)
            thr_f = oto.thresholds[0 if kind == "pitch" else 1]
            thr_w = scc.thresholds[1 if kind == "pitch" else 0]
        # one more state, the low-passed target ``q`` (``q' = w_q (d - q)``), and the target
        # seen by the cost ``d + c q``: heave ``c = -1`` (the high-pass of the vehicle's,
        # ``w_q`` = heave_washout); roll with gain_y_sustained, ``c`` the sustained gain's
        # excess over gain_y (``w_q = 1 / sustained_tau``)
        wash, cq = 0.0, 0.0
        if kind == "heave" and p.heave_washout > 0:
            wash, cq = p.heave_washout, -1.0
        elif kind == "roll" and p.gain_y_sustained > 0 and p.gain_y > 0:
            wash, cq = 1.0 / p.sustained_tau, p.gain_y_sustained / p.gain_y - 1.0
        nq = 1 if wash > 0 else 0
        n = 3 + no_ + 2 * nc + nq  # platform, otolith error, canal error, vehicle's canal, q
        a = np.zeros((n, n))
        b = np.zeros((n, 3))  # inputs: jerk, vehicle f (scaled), vehicle w (scaled)
        a[0, 1] = a[1, 2] = 1.0
        b[2, 0] = 1.0
        if nq:
            a[n - 1, n - 1] = -wash
            b[n - 1, 1] = wash
        # head specific force (heave: change from g) as a row over the platform states
        fh = np.zeros(n)
        if kind == "heave":
            fh[2] = 1.0
        else:
            fh[0], fh[2] = -g, h
        o = slice(3, 3 + no_)
        a[o, o] = oa
        a[o, :] += ob @ fh[None, :]
        b[o, 1] = -ob[:, 0]
        raw = fh.copy()
        if nq:  # the target d + c q: c q enters against the head
            a[o, n - 1] -= cq * ob[:, 0]
            raw[n - 1] = -cq
        # the outputs read by the cost and the constraints, each (state row, input row)
        # over (jerk, vehicle f, vehicle w); the canal ones None on heave
        e_f = np.zeros(n)
        e_f[o] = oc[0]
        self.out_f = (e_f, np.zeros(3))
        self.out_raw = (raw, np.array([0.0, -1.0, 0.0]))
        self.out_w = self.out_w_vehicle = self.out_w_head = None
        if nc:
            assert ca is not None and cb is not None and cc is not None and cd is not None
            c = slice(3 + no_, 3 + no_ + nc)
            v = slice(3 + no_ + nc, 3 + no_ + 2 * nc)
            rate = np.zeros(n)
            rate[1], rate[2] = sigma, sigma * scc.tau_n
            a[c, c] = ca
            a[c, :] += cb @ rate[None, :]
            b[c, 2] = -cb[:, 0]
            e_w = cd[0, 0] * rate
            e_w[c] += cc[0]
            self.out_w = (e_w, np.array([0.0, 0.0, -cd[0, 0]]))
            # the vehicle's own canal sensation (of the scaled rate), and the head's
            a[v, v] = ca
            b[v, 2] = cb[:, 0]
            veh = np.zeros(n)
            veh[v] = cc[0]
            self.out_w_vehicle = (veh, np.array([0.0, 0.0, cd[0, 0]]))
            self.out_w_head = (e_w + veh, np.zeros(3))
        self.n, self.kf, self.kw = n, kf, kw
        self.tau_n = float(scc.tau_n)
        self.thr_f, self.thr_w = float(thr_f), float(thr_w)
        self.amax = amax
        if kind == "heave":
            self.rate_max, self.accel_max = p.heave_rate_max, p.heave_accel_max
        else:
            self.rate_max, self.accel_max = p.tilt_rate_max, p.tilt_accel_max
        self.ad, self.bd = discretise(a, b, p.period)
