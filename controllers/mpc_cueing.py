"""Model-predictive motion cueing: a QP on the perceived error, solved every period.

The optimal alternative to :mod:`controllers.washout` (Dagdelen et al. 2009, "Model-based
predictive motion cueing strategy for vehicle driving simulators"; Bruschetta et al.
2017): at every period ``T`` the platform's motion over the next ``N`` periods is chosen
to minimise what the driver would perceive as wrong, through the same otolith and canal
models the metrics use (:mod:`controllers.vestibular`), subject to the platform's reach.

Model (per tilt axis, linearised about rest, ISO angles, the head ``h`` above the pivot)
--------------------------------------------------------------------------------------
The decision is the angular jerk ``j``, held over a period; the platform's state is
``(a, a', a'')``. With ``a`` the ISO pitch (``theta``), or minus the ISO roll
(``-phi``), the head's specific force along x, or along y, is::

    f = h a'' - g a

(tilt: gravity's share ``-g a``; the head ``h`` = 0.75 m above the pivot is thrown
along the same axis by the angular acceleration, the non-minimum-phase zero at
``s = +sqrt(g/h)`` = 3.6 rad/s that makes a pure tilt first push the wrong way). The
felt rotation is ``sigma a'`` (``sigma`` +1 for pitch, -1 for roll). The errors fed to
the vestibular models are those of the head against the scaled vehicle::

    e_f = OTO(f - k_f f_v),  e_w = SCC(sigma a' - k_w w_v),  e_raw = f - k_f f_v

with OTO the otolith model and SCC the canal model of :mod:`controllers.vestibular`
without its two fastest terms (``tau_s`` = 5 ms and the neural lead ``tau_n`` = 60 ms
are above the period's Nyquist frequency; the lead enters as ``tau_n a''``). Heave:
``(z, z', z'')``, ``f_z - g = z''``, ``e_f = OTO(z'' - k_z HP(f_vz - g))`` with ``HP`` the
first-order high-pass ``s / (s + w_hp)`` (``heave_washout``): a heave cannot hold a
sustained specific force (a real accelerometer's bias, a slope's ``g cos``), so the
target keeps only what a stroke can make, and a biased or held ``f_z`` neither drifts the
platform nor keeps it off home.

Cost over the horizon, each error in units of its perception threshold::

    sum_k  w_f (e_f/thr_f)^2 + w_raw (e_raw/thr_f)^2 + w_w (e_w/thr_w)^2
           + w_tilt (a/a_max)^2 + w_jerk (j/j_ref)^2

Constraints at every predicted sample: ``|a| <= a_max`` (the workspace box,
:func:`controllers.workspace.inscribed_box`), ``|a'| <= rate_max``,
``|a''| <= accel_max`` (the platform's reach: :class:`MpcParams`), and the same for heave;
the felt-rotation and wrong-way-jolt limits (:class:`MpcParams`). Where those two cannot
both be met from the current state, the jolt limit gives way first (the QP is solved
again without it) and the felt rotation only if that is still infeasible: at a braking's
release the tilt coming back would otherwise lose both and be felt as a false pitch.

Information: at time ``t`` the solve knows the vehicle input up to ``t`` and assumes
it is held over the horizon; ``preview`` > 0 (an explicit option, named so) lets it see
the vehicle input ``preview`` seconds ahead instead, as a simulator replaying a
recording could. The model's own state is the controller's state: the law runs ahead of
a simulation (:mod:`simpro_mj.config.cueing`) as the washout does, each solve using
only what the rig's computer would know at that time.

Solver: OSQP (Stellato et al. 2020), one sparse QP of ``3 N`` jerks whose matrix is
fixed (only the linear cost and the bounds change), warm-started from the previous
solution. Each solve's wall time is recorded (:attr:`ModelPredictiveCueing.solve_times`).
Between two solves the set-point is the model's own trajectory under the held jerk,
evaluated every ``output_period``: smooth to the third derivative.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .cue_mpc_axis import AxisPrediction, MpcAxis
from .cue_mpc_params import MpcParams
from .frames import GRAVITY
from .geometry import PlatformGeometry, nominal_geometry
from .vestibular import CanalModel, OtolithModel
from .workspace import inscribed_box

#: What a solve's status adds when the QP was solved again with limits given up, in turn.
WITHOUT = (" without the jolt limit", " without the rotation and jolt limits")


@dataclass
class MpcResult:
    """Output of :meth:`ModelPredictiveCueing.run`: ``pose`` (n, 3) base-frame
    set-points at ``t`` (the output grid), ``solve_times`` (s) one per solve,
    ``status`` OSQP's status string per solve, ``iterations`` per solve."""

    t: np.ndarray
    pose: np.ndarray
    solve_times: np.ndarray
    status: list
    iterations: np.ndarray

    def solve_time_stats(self) -> dict:
        """p50, p99 and max of the solve times (ms), and the count of solves."""
        s = np.asarray(self.solve_times) * 1e3
        return {
            "solves": int(s.size),
            "p50_ms": float(np.percentile(s, 50)),
            "p99_ms": float(np.percentile(s, 99)),
            "max_ms": float(s.max()),
            "not_solved": int(sum(st != "solved" for st in self.status)),
        }


def _plan(x0: np.ndarray, jerks: np.ndarray, period: float, t: np.ndarray) -> np.ndarray:
    """Position, rate and acceleration (3, len(t)) at times ``t`` of a triple integrator from
    ``x0`` under the jerks held one period each (the last one beyond the horizon)."""
    out = np.empty((3, t.size))
    seg = np.minimum((t // period).astype(int), jerks.size - 1)
    x = np.asarray(x0, float).copy()
    for k in range(int(seg.max()) + 1):
        sel = seg == k
        if sel.any():
            r = t[sel] - k * period
            j = jerks[k]
            out[0, sel] = x[0] + x[1] * r + 0.5 * x[2] * r**2 + j * r**3 / 6.0
            out[1, sel] = x[1] + x[2] * r + 0.5 * j * r**2
            out[2, sel] = x[2] + j * r
        j, T = jerks[k], period
        x = np.array(
            [
                x[0] + x[1] * T + 0.5 * x[2] * T**2 + j * T**3 / 6.0,
                x[1] + x[2] * T + 0.5 * j * T**2,
                x[2] + j * T,
            ]
        )
    return out


class MpcStream:
    """:class:`ModelPredictiveCueing` sample by sample: :meth:`step` every ``dt``, a QP
    every period, the plan evaluated in between (what a live session runs). The
    attributes a live session reads of a washout: ``box``, ``geometry``,
    ``last_rate_limited`` and ``last_softened`` (always False: the plan is constrained,
    not limited)."""

    def __init__(self, law: ModelPredictiveCueing, dt: float):
        p = law.params
        if p.preview > 0:
            raise ValueError(f"a stream knows only the past: preview must be 0, got {p.preview}")
        self.every = int(round(p.period / dt))
        if self.every < 1 or abs(self.every * dt - p.period) > 1e-9:
            raise ValueError(f"dt={dt!r} must divide the period {p.period!r}")
        self.law, self.dt = law, dt
        self.box, self.geometry = law.box, law.geometry
        self.last_rate_limited = self.last_softened = False
        self._k = 0
        self._u: np.ndarray | None = None
        self._held: tuple[np.ndarray, np.ndarray] = (np.zeros(3), np.zeros(3))

    def step(self, f, w) -> np.ndarray:
        """Vehicle ``f``, ``w`` (3,) now -> the set-point (roll, pitch, h) in B (3,)."""
        f = np.asarray(f, float)
        w = np.asarray(w, float)
        law, N = self.law, self.law.N
        j = self._k % self.every
        if j == 0:
            if self._u is not None:
                law._advance(self._u, *self._held)
            self._held = (f.copy(), w.copy())
            self._u = law.solve(np.tile(f, (N, 1)), np.tile(w, (N, 1)))
        self._k += 1
        assert self._u is not None  # solved at k = 0
        return law._pose(self._u, np.array([j * self.dt]), self.dt)[0]


class ModelPredictiveCueing:
    """MPC motion cueing, one QP per :attr:`MpcParams.period`.

    Parameters
    ----------
    params : MpcParams, optional
    geometry : PlatformGeometry, optional
        For the workspace box (default :func:`nominal_geometry`).
    otolith, canal : OtolithModel, CanalModel, optional
        The perception models in the cost (defaults those of the metrics).
    **overrides
        Field values replacing those of ``params``.
    """

    def __init__(
        self,
        params: MpcParams | None = None,
        geometry: PlatformGeometry | None = None,
        otolith: OtolithModel | None = None,
        canal: CanalModel | None = None,
        **overrides,
    ):
        import osqp
        from scipy import sparse

        p = MpcParams() if params is None else params
        if overrides:
            p = p.replace(**overrides)
        self.params = p
        self.geometry = nominal_geometry() if geometry is None else geometry
        self.box = inscribed_box(self.geometry, p.heave_fraction, p.stroke_margin)
        home = [float(v) for v in self.geometry.home]
        self._home = home
        oto = OtolithModel() if otolith is None else otolith
        scc = CanalModel() if canal is None else canal
        # symmetric limits inside the box (ISO tilt a: pitch a = theta -> B pitch -a;
        # roll a = -phi -> B roll +a), heave about home
        lim = []
        for k, name in enumerate(("roll", "pitch", "heave")):
            lo, hi = (float(v) for v in self.box[name])
            lim.append(p.box_fraction * min(hi - home[k], home[k] - lo))
        self.axes = [
            MpcAxis("pitch", p, oto, scc, lim[1]),
            MpcAxis("roll", p, oto, scc, lim[0]),
            MpcAxis("heave", p, oto, scc, lim[2]),
        ]
        self.N = int(p.horizon)
        self._build()
        P = sparse.csc_matrix(np.triu(self._P))
        A = sparse.csc_matrix(self._A)
        self._solver = osqp.OSQP()
        self._solver.setup(
            P,
            np.zeros(self._P.shape[0]),
            A,
            -np.ones(A.shape[0]),
            np.ones(A.shape[0]),
            verbose=False,
            warm_starting=True,
            polishing=False,
            # 1e-4: the plan within 0.03 deg of a 1e-5 solve, a fifth of the iterations
            eps_abs=1e-4,
            eps_rel=1e-4,
            max_iter=1000,
        )
        self.reset()

    # ------------------------------------------------------------------ the QP
    def _build(self) -> None:
        """Per axis the prediction matrices, and the QP's fixed Hessian and constraint
        matrix (block diagonal over the three axes)."""
        p, N = self.params, self.N
        blocks_p, blocks_a = [], []
        self._pred = []
        for ax in self.axes:
            n = ax.n
            ad, bd = ax.ad, ax.bd
            # x_{k+1} = Ad x_k + Bu u_k + Bd d_k, k = 0..N-1; X = [x_1..x_N]
            phi = np.zeros((N * n, n))
            gam = np.zeros((N * n, N))
            psi = np.zeros((N * n, 2 * N))  # d_k = (f_k, w_k)
            apow = np.eye(n)
            powers = [np.eye(n)]
            for _ in range(N):
                apow = ad @ apow
                powers.append(apow)
            for k in range(N):
                phi[k * n : (k + 1) * n] = powers[k + 1]
                for i in range(k + 1):
                    m = powers[k - i]
                    gam[k * n : (k + 1) * n, i] = (m @ bd[:, 0:1])[:, 0]
                    psi[k * n : (k + 1) * n, 2 * i : 2 * i + 2] = m @ bd[:, 1:3]
            # cost outputs y = Cy x + Dy d, per sample, scaled by the weights
            outs = []
            wf = math.sqrt(p.weight_f) / ax.thr_f
            wr = math.sqrt(p.weight_raw) / ax.thr_f
            outs.append((wf * ax.out_f[0], wf * ax.out_f[1][1:]))
            outs.append((wr * ax.out_raw[0], wr * ax.out_raw[1][1:]))
            if ax.out_w is not None:
                ww = math.sqrt(p.weight_w) / ax.thr_w
                outs.append((ww * ax.out_w[0], ww * ax.out_w[1][1:]))
            tilt = np.zeros(n)
            tilt[0] = math.sqrt(p.weight_heave if ax.kind == "heave" else p.weight_tilt) / ax.amax
            if ax.kind == "heave":
                # the stroke's rate, in units of its limit: the heave comes back home
                # instead of coasting on the otoliths' slow error
                tilt[1] = math.sqrt(p.weight_heave_rate) / ax.rate_max
            outs.append((tilt, np.zeros(2)))
            cy = np.array([o[0] for o in outs])
            dy = np.array([o[1] for o in outs])
            CY = np.kron(np.eye(N), cy)  # (N ny, N n)
            # the outputs at x_{k+1} see the vehicle input of that sample, d_{k+1} (the last
            # one held)
            shift = np.eye(N, k=1)
            shift[-1, -1] = 1.0
            DY = np.kron(shift, dy)  # (N ny, 2N)
            G = CY @ gam
            jref = ax.accel_max / p.period
            R = (p.weight_jerk / jref**2) * np.eye(N)
            blocks_p.append(2.0 * (G.T @ G + R))
            # constraints: a, a', a'' of x_1..x_N within limits (scaled to +-1)
            # and, with rotation_limit, the head's felt rotation (canal model) within
            # rotation_limit thresholds of the vehicle's (in units of the threshold)
            head, vehicle = ax.out_w_head, ax.out_w_vehicle
            felt = self._rotation_limit(ax.kind) > 0 and head is not None
            jolt = p.jolt_limit > 0 and ax.kind != "heave"
            rows = [np.eye(n)[0] / ax.amax, np.eye(n)[1] / ax.rate_max, np.eye(n)[2] / ax.accel_max]
            veh = None
            if felt and head is not None and vehicle is not None:
                rows.append(head[0] / ax.thr_w)
                vrow, vd = vehicle
                veh = (np.kron(np.eye(N), vrow / ax.thr_w), np.kron(shift, vd[1:] / ax.thr_w))
            if jolt:  # the head's specific force, in units of jolt_limit
                rows.append(ax.out_raw[0] / p.jolt_limit)
            sel = np.array(rows)
            S = np.kron(np.eye(N), sel)
            blocks_a.append(S @ gam)
            self._pred.append(
                AxisPrediction(phi, psi, CY, DY, G, S, sel.shape[0], veh,
                            3 if felt else None, sel.shape[0] - 1 if jolt else None, shift)
            )  # fmt: skip
        from scipy.linalg import block_diag

        self._P = block_diag(*blocks_p)
        self._A = block_diag(*blocks_a)
        # the rows given up, in turn, where the QP is infeasible: the jolt limit's, then
        # the felt rotation's as well
        jolt_rows: list[np.ndarray] = []
        felt_rows: list[np.ndarray] = []
        for pr in self._pred:
            for cols, out in (((pr.jolt,), jolt_rows), ((pr.felt, pr.jolt), felt_rows)):
                mask = np.zeros((N, pr.rows), bool)
                for r in cols:
                    if r is not None:
                        mask[:, r] = True
                out.append(mask.ravel())
        self._soft_rows = (np.concatenate(jolt_rows), np.concatenate(felt_rows))

    def reset(self) -> None:
        """Back to rest: the platform at home, the perception errors at zero."""
        self._x = [np.zeros(ax.n) for ax in self.axes]
        self._u = np.zeros(3 * self.N)
        self._lag = np.zeros((3, 2))  # the loop inverse's lags, per axis (:meth:`_loop_inverse`)
        self.solve_times: list[float] = []
        self.status: list[str] = []
        self.iterations: list[int] = []

    def _d(self, f_future: np.ndarray, w_future: np.ndarray, k: int) -> np.ndarray:
        """The stacked scaled vehicle inputs (f_k, w_k) of axis ``k`` over the horizon."""
        ax = self.axes[k]
        if ax.kind == "pitch":
            f, w = f_future[:, 0], w_future[:, 1]
        elif ax.kind == "roll":
            # a = -phi: f_y = g phi - h phi'' = h a'' - g a, as pitch; the rate sigma = -1
            f, w = f_future[:, 1], w_future[:, 0]
        else:
            f, w = f_future[:, 2] - GRAVITY, np.zeros(len(f_future))
            return np.column_stack([ax.kf * f, ax.kw * w]).ravel()
        return np.column_stack([self._scaled(f, ax.kf), ax.kw * w]).ravel()

    def _scaled(self, f: np.ndarray, gain: float) -> np.ndarray:
        """The vehicle's surge or sway specific force scaled for the platform:
        ``gain f + (1 - gain) f_k tanh(f / f_k)`` with ``f_k`` = :attr:`MpcParams.knee`
        (0: ``gain f``). Slope 1 at rest, ``gain`` beyond the knee: a weak cue is played
        at full size, so that it crosses the otoliths' threshold when the car's does,
        and a strong one is scaled into the workspace."""
        fk = self.params.knee
        if fk <= 0:
            return gain * f
        return gain * f + (1.0 - gain) * fk * np.tanh(f / fk)

    def _rotation_limit(self, kind: str) -> float:
        p = self.params
        return p.rotation_limit_pitch if kind == "pitch" else p.rotation_limit

    def solve(self, f_future: np.ndarray, w_future: np.ndarray) -> np.ndarray:
        """One QP: the vehicle input over the horizon (N, 3) each -> the N jerks per axis
        (3, N); records the solve's wall time and status."""
        N = self.N
        q_parts, lo_parts, hi_parts = [], [], []
        for k, pr in enumerate(self._pred):
            d = self._d(f_future, w_future, k)
            free = pr.phi @ self._x[k] + pr.psi @ d  # X without the jerks
            yfree = pr.CY @ free + pr.DY @ d
            q_parts.append(2.0 * pr.G.T @ yfree)
            sfree = pr.S @ free
            ax, cveh = self.axes[k], None
            if pr.veh is not None:  # the vehicle's felt rotation (free of the jerks)
                cveh = pr.veh[0] @ free + pr.veh[1] @ d
                # the neural lead on the vehicle's side: tau_n times its rate's change
                wv = d[1::2]
                lead = ax.tau_n * np.gradient(wv) / self.params.period
                cveh = cveh + lead / ax.thr_w
            # the car's specific force at each sample
            target = None if pr.jolt is None else pr.shift @ d[0::2]
            low, high = pr.bounds(ax, cveh, target, self._rotation_limit(ax.kind), N)
            lo_parts.append(low.ravel() - sfree)
            hi_parts.append(high.ravel() - sfree)
        q = np.concatenate(q_parts)
        lo, hi = np.concatenate(lo_parts), np.concatenate(hi_parts)
        # infeasible bounds (a state already outside, e.g. after a limit change) are opened
        bad = lo > hi
        lo[bad], hi[bad] = -np.inf, np.inf
        self._solver.update(q=q, l=lo, u=hi)
        warm = np.concatenate([np.r_[self._u[i * N + 1 : (i + 1) * N], 0.0] for i in range(3)])
        self._solver.warm_start(x=warm)
        t0 = time.perf_counter()
        res = self._solver.solve(raise_error=False)
        status = str(res.info.status)
        for rows, without in zip(self._soft_rows, WITHOUT, strict=True):
            if "infeasible" not in status or not rows.any():
                break
            # the jolt limit (then the felt rotation's too) cannot be met from here
            lo[rows], hi[rows] = -np.inf, np.inf
            self._solver.update(l=lo, u=hi)
            res = self._solver.solve(raise_error=False)
            status = str(res.info.status) + without
        self.solve_times.append(time.perf_counter() - t0)
        self.status.append(status)
        self.iterations.append(int(res.info.iter))
        if res.x is None or not np.all(np.isfinite(res.x)):
            u = warm  # the previous plan, shifted
        else:
            u = np.asarray(res.x, float)
        self._u = u
        return u.reshape(3, N)

    # ------------------------------------------------------------------ running
    def stream(self, dt: float) -> MpcStream:
        """The law sample by sample, every ``dt`` (which divides the period), as a live
        rig's computer runs it: only the past is known (``preview`` must be 0)."""
        return MpcStream(self, dt)

    def _advance(self, u: np.ndarray, f_now: np.ndarray, w_now: np.ndarray) -> None:
        """The model one period on under the first planned jerks and the vehicle input
        of the solve."""
        for k, ax in enumerate(self.axes):
            d = self._d(f_now[None, :], w_now[None, :], k)[:2]
            self._x[k] = ax.ad @ self._x[k] + ax.bd @ np.r_[u[k, 0], d]

    def _pose(self, u: np.ndarray, t: np.ndarray, dt: float) -> np.ndarray:
        """Base-frame set-points (len(t), 3) of the plan after the solve, ``dt`` apart,
        through the inverse of the platform loop (:meth:`_loop_inverse`)."""
        p = self.params
        out = np.empty((t.size, 3))
        for k, ax in enumerate(self.axes):
            a = _plan(self._x[k][:3], u[k], p.period, t + p.loop_delay + p.loop_filter)
            a = self._loop_inverse(k, a, dt)
            if ax.kind == "pitch":
                out[:, 1] = -a  # ISO pitch a -> B pitch -a
            elif ax.kind == "roll":
                out[:, 0] = a  # a = -phi ISO -> B roll = -phi = a
            else:
                out[:, 2] = self._home[2] + a
        return out

    def _loop_inverse(self, k: int, a: np.ndarray, dt: float) -> np.ndarray:
        """The set-point that makes the platform loop follow the plan of axis ``k``.

        The loop from set-point ``r`` to pose ``y`` is modelled as
        ``G(s) = (T_z s + 1) w^2 / (s^2 + 2 zeta w s + w^2) e^(-s T_d)``
        (:class:`MpcParams` ``loop_*``). With the plan's position, rate and
        acceleration ``a`` (3, n) evaluated ``T_d + T_f`` ahead::

            r = (a + (2 zeta / w) a' + a'' / w^2) / ((T_z s + 1) (T_f s + 1))

        the two first-order lags run sample by sample (their states kept between
        calls; the poles at ``-1/T_z`` and ``-1/T_f`` are stable). ``T_f``
        (``loop_filter``) bounds the inverse's gain above the loop's bandwidth, where the
        fitted model no longer holds (3.5 times at 4.4 Hz without it, 2.1 with 50 ms),
        and its lag is made up by the look-ahead. ``loop_omega`` 0: ``r = a``.
        """
        p = self.params
        if p.loop_omega <= 0:
            return a[0]
        v = a[0] + (2.0 * p.loop_zeta / p.loop_omega) * a[1] + a[2] / p.loop_omega**2
        for j, tau in enumerate((p.loop_zero, p.loop_filter)):
            if tau <= 0:
                continue
            e = math.exp(-dt / tau)
            r = np.empty(v.size)
            state = self._lag[k, j]
            for i, vi in enumerate(v):
                state = e * state + (1.0 - e) * vi
                r[i] = state
            self._lag[k, j] = state
            v = r
        return v

    def run(self, f, w, dt: float) -> MpcResult:
        """Run over a vehicle input sampled at ``dt`` (which divides the period).

        ``f``, ``w`` (n, 3) in V. Every ``period / dt`` samples a QP is solved with the
        vehicle input known at that sample (held, or ``preview`` ahead); between solves
        the platform follows the model under the first jerk. Returns a pose per sample.
        """
        f = np.asarray(f, float)
        w = np.asarray(w, float)
        if f.ndim != 2 or f.shape[1] != 3 or w.shape != f.shape:
            raise ValueError(f"f and w must both be (n, 3), got {f.shape} and {w.shape}")
        p = self.params
        every = int(round(p.period / dt))
        if every < 1 or abs(every * dt - p.period) > 1e-9:
            raise ValueError(f"dt={dt!r} must divide the period {p.period!r}")
        n = f.shape[0]
        N = self.N
        pose = np.empty((n, 3))
        ahead = int(round(p.preview / dt))
        # the cue planned ``lead`` (the surge's ``lead_x``) ahead of the recording, as far
        # as the preview reaches
        adv = min(int(round(p.lead / dt)), ahead)
        adv_x = min(int(round(max(p.lead, p.lead_x) / dt)), ahead)
        tau = dt * np.arange(every)
        for s in range(0, n, every):
            # known up to t + preview, held after
            # (the specific force only: the car's rotation is matched in time)
            idx = np.minimum(s + np.minimum(np.arange(N) * every, ahead), n - 1)
            fdx = np.minimum(s + np.minimum(np.arange(N) * every + adv, ahead), n - 1)
            xdx = np.minimum(s + np.minimum(np.arange(N) * every + adv_x, ahead), n - 1)
            ff = np.column_stack([f[xdx, 0], f[fdx, 1:]])
            u = self.solve(ff, w[idx])
            m = min(every, n - s)
            pose[s : s + m] = self._pose(u, tau[:m], dt)
            self._advance(u, ff[0], w[s])
        st = self.solve_times
        return MpcResult(
            t=dt * np.arange(n),
            pose=pose,
            solve_times=np.asarray(st),
            status=list(self.status),
            iterations=np.asarray(self.iterations),
        )
