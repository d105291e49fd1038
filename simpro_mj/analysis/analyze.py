"""``simpro-sim analyze``: stability analysis of the joint and task-space loops.

Computes (numbers from :mod:`controllers.analysis`, plots here):

* first, the loop the scenario ships (:func:`shipped`, default ``step_pitch``): its
  outer law and integrator, period, set-point filter and joint controllers on its
  design plant, closed around its joint loops lifted to the outer period
  (:func:`simpro_mj.analysis.stability.outer_loop`, the preflight's analysis) on
  the plant its actuators stand for and on eqs. (34)-(35); the stability limit and
  the spectral radius at its gains, and which loop that is;
* then the paper's loops (Fig. 7 as printed: the I law by forward Euler, no
  set-point filter), in the parameter tree below:
* inner loops: closed-loop poles, damping, step metrics of the printed
  (eqs. 36-37), corrected and redesigned controllers with the plants of
  eqs. (34)-(35);
* outer loop with the inner loop as a delay (eqs. 21, 24-27): poles at the
  chosen gains, step responses, root loci of the I (Fig. 8) and PI (Fig. 9)
  laws, exact stability limits (Jury) beside the paper's 20 and 50;
* the same outer loop around the real (discretised, lifted) inner loops,
  mapped to the task space with the IK Jacobian at home, and a sweep of the
  inner bandwidth showing when the delay assumption holds.

Parameters (``--set KEY=VALUE``): :class:`AnalyzeParams`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict
from typing import Annotated, Any, Literal, get_args

import numpy as np
from pydantic import Field, StrictBool, model_validator

from controllers.analysis.inner import inner_summary, step_metrics
from controllers.analysis.lifted import (
    lifted_inner,
    outer_closed_loop,
    real_inner_limit,
    real_inner_step,
    spectral_radius,
)
from controllers.analysis.outer_delay import (
    closed_form_limit,
    outer_poles,
    outer_polynomials,
    outer_step,
    schur_stable,
    stability_limit,
)
from controllers.design import (
    PAPER_SPEC,
    Reading,
    design_for,
    paper_plant,
    paper_units_info,
    redesigned_design,
)
from controllers.errors import DesignError
from controllers.frequency import LoopModel, predict
from controllers.geometry import nominal_geometry
from controllers.kinematics import jacobian
from controllers.task_space import Lag
from controllers.velocity_feedforward import velocity_gains
from simpro_mj.analysis.loop_records import (
    Analysis,
    DelayLoop,
    DelaySweep,
    FeedforwardLoop,
    InnerLoop,
    Limits,
    OuterLoops,
    PlantLimit,
    RealLoop,
    RealLoops,
    Shipped,
    ShippedLoop,
    SweepRow,
)
from simpro_mj.analysis.response_summary import figures
from simpro_mj.config.models import Outer, Scenario, as_scenario
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.keys import Block, Real, Whole, block, param

#: The paper's statements, for comparison.
PAPER = {
    "I_stability_limit": 20.0,
    "PI_stability_limit": 50.0,
    "I_gain": 3.0,
    "PI_gain": 20.0,
    "inner_zeta": PAPER_SPEC["zeta"],
    "inner_wn_rad_s": PAPER_SPEC["wn"],
}

Variant = Literal["printed", "corrected", "redesigned"]
VARIANTS: tuple[Variant, ...] = get_args(Variant)
ACTUATORS = ("actuator1", "actuator2")
Seconds = Annotated[Real, Field(ge=1e-5, le=10.0)]  # normal numbers: finite ratios
StepDuration = Annotated[Real, Field(gt=0, le=600)]
Gain = Annotated[Real, Field(ge=0, le=1e4)]
Samples = Annotated[Whole, Field(ge=1, le=100)]


class OuterParams(Block):
    """The outer loop with the inner loop as a delay (eqs. 21, 24-27)."""

    gain: Gain = param(3.0, "1/s", "K K_I of the I law (section 5.2.3)")
    pi_gain: Gain = param(20.0, "1/s", "K K_I at which Fig. 9 marks the PI poles")
    period_s: Seconds = param(0.06, "s", "outer period T")
    delay_samples: Samples = param(1, "samples", "the inner loop's delay (eq. 21)")
    pi_zero: Real = param(0.2, "", "c of the PI law T (z + c)/(z - 1)", gt=-1, lt=1)
    alt_period_s: Seconds = param(0.03, "s", "section 5.1's 30 ms period")
    alt_delay_samples: Samples = param(2, "samples", "its delay: q(k) = q_d(k - 2)")
    locus_gain_max: Real = param(60.0, "1/s", "largest gain of the root loci", gt=0, le=1e4)
    step_duration_s: StepDuration = param(3.0, "s", "the step responses' length")


class InnerParams(Block):
    """The joint loops of the real-inner-loop analysis, and the redesign's spec."""

    variant: Variant = param("corrected", "", "joint controller of the real-inner analysis")
    dt_s: Annotated[Real, Field(ge=1e-5, le=1.0)] = param(0.001, "s", "the joint loops' step")
    method: Literal["tustin", "zoh"] = param("tustin", "", "the joint loops' discretisation")
    zeta: Real = param(PAPER_SPEC["zeta"], "", "redesign spec: damping", gt=0, lt=2)
    wn_rad_s: Real = param(PAPER_SPEC["wn"], "rad/s", "redesign spec: wn", gt=0, le=1e4)
    p1_rad_s: Real | None = param(
        None, "rad/s", "null: from the printed denominator (76.0)", gt=0, le=1e5
    )
    p2_rad_s: Real | None = param(
        None, "rad/s", "null: from the printed denominator (56.7)", gt=0, le=1e5
    )
    step_duration_s: StepDuration = param(3.0, "s", "the step responses' length")

    def spec(self) -> dict:
        """The redesign's spec (:func:`controllers.design.redesigned_design`'s keywords)."""
        spec = {"zeta": self.zeta, "wn": self.wn_rad_s}
        for key, value in (("p1", self.p1_rad_s), ("p2", self.p2_rad_s)):
            if value is not None:
                spec[key] = value
        return spec

    @model_validator(mode="after")
    def _feasible(self):
        for act in ACTUATORS:  # the redesign must be feasible before anything is computed
            try:
                redesigned_design(act, **self.spec())
            except DesignError as exc:
                raise UserInputError(
                    f"infeasible joint design at inner.wn_rad_s: {exc}; allowed: a zeta, "
                    "wn_rad_s (and p1_rad_s, p2_rad_s) the pole placement can meet, e.g. 0.7, 10"
                ) from exc
        return self


class FeedforwardParams(Block):
    """``controller.mode = feedforward`` (docs/feedforward.md): the correction's I law."""

    gain: Gain = param(1.0, "1/s", "K K_I of the correction (controller.feedforward.gains)")
    model_tau_s: Real = param(0.2, "s", "the reference model's time constant", ge=0, le=10)
    lag: Lag = param("joints", "", "the joint loops' lag taken out of the error")
    leg_velocity: StrictBool = param(
        True, "", "leg velocity feed-forward (a0/b) J dy_d/dt in the frequency response"
    )
    step_duration_s: StepDuration = param(4.0, "s", "the step response's length")


class SweepParams(Block):
    """Redesigned inner loops with wn scaled, p1, p2 = (7.6, 5.67) wn."""

    wn_rad_s: list[Annotated[Real, Field(gt=0, le=1e4)]] = param(
        [5.0, 10.0, 20.0, 40.0, 80.0, 160.0], "rad/s", "the inner bandwidths", min_length=1
    )


class AnalyzeParams(Block):
    """The parameters of ``simpro-sim analyze`` (``--set outer.gain=2``)."""

    paper_units: Reading = param(
        "volts", "", "unit of Y in eqs. (34)-(37): volts (20 V/m) or metres"
    )
    outer: OuterParams = block(OuterParams)
    inner: InnerParams = block(InnerParams)
    feedforward: FeedforwardParams = block(FeedforwardParams)
    sweep: SweepParams = block(SweepParams)

    @model_validator(mode="after")
    def _whole_inner_steps(self):
        dt = self.inner.dt_s
        for key in ("period_s", "alt_period_s"):
            value = getattr(self.outer, key)
            ratio = value / dt
            if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio):
                raise UserInputError(
                    f"invalid value at outer.{key}: {value} s; allowed: a positive integer "
                    f"multiple of inner.dt_s = {dt} s"
                )
        return self


def _pairs(z) -> list:
    z = np.atleast_1d(np.asarray(z, dtype=complex))
    return [[float(v.real), float(v.imag)] for v in z]


def _outer_delay(mode, gain, period, delay, pi_zero, duration, paper=None) -> DelayLoop:
    a, b = outer_polynomials(mode, period, delay, pi_zero)
    lim = stability_limit(a, b)
    try:
        closed = closed_form_limit(mode, period, delay, pi_zero)
    except NotImplementedError:
        closed = None
    poles = outer_poles(mode, gain, period, delay, pi_zero)
    n = int(round(duration / period)) + 1
    y = outer_step(mode, gain, period, n, delay, pi_zero)
    t = np.arange(n) * period
    return DelayLoop(
        period_s=period,
        delay_samples=delay,
        gain=gain,
        stability_limit=lim,
        stability_limit_closed_form=closed,
        jury_stable_at_gain=schur_stable(np.polyadd(a, gain * b)),
        poles=_pairs(poles),
        pole_magnitudes=[float(abs(p)) for p in poles],
        step=step_metrics(t, y, final=1.0) if max(abs(poles)) < 1 else None,
        _t=t,
        _y=y,
        _ab=(a, b),
        paper_stability_limit=paper,
    )


def _real(mode, gain, period, p: AnalyzeParams, spec, jac, duration) -> RealLoop:
    i = p.inner
    kw: dict[str, Any] = dict(variant=i.variant, dt=i.dt_s, method=i.method, spec=spec)
    lifted = lifted_inner(period, **kw)
    f = outer_closed_loop(mode, gain, period, lifted, jac, p.outer.pi_zero)[0]
    rho = spectral_radius(f)
    lim = real_inner_limit(mode, period, jac=jac, pi_zero=p.outer.pi_zero, **kw)
    per_leg = {
        act: real_inner_limit(mode, period, actuators=(act,), pi_zero=p.outer.pi_zero, **kw)
        for act in ACTUATORS
    }
    t, y = real_inner_step(
        mode, gain, period, duration, jac=jac, pi_zero=p.outer.pi_zero, axis=2, **kw
    )
    return RealLoop(
        variant=i.variant,
        period_s=period,
        gain=gain,
        stability_limit=lim,
        stability_limit_per_leg=per_leg,
        spectral_radius_at_gain=rho,
        stable_at_gain=rho < 1.0,
        step_heave=step_metrics(t, y[:, 2], final=1.0) if rho < 1.0 else None,
        _t=t,
        _y=y,
    )


def _feedforward(p: AnalyzeParams, spec: dict, jac, real_i: RealLoop) -> FeedforwardLoop:
    """The feed-forward scheme on the paper's plants: the I law's limit at the correction's
    gain (its path is outside the loop), its pitch step and frequency response per axis."""

    o, i, ff = p.outer, p.inner, p.feedforward
    reading = p.paper_units
    acts = ("actuator1", "actuator2", "actuator3")
    plants = [paper_plant(a, reading) for a in acts]
    sp = dict(spec) if i.variant == "redesigned" else {}
    designs = [
        design_for(a, i.variant, plant=pl, reading=reading, **sp)
        for a, pl in zip(acts, plants, strict=True)
    ]
    kw: dict[str, Any] = dict(variant=i.variant, dt=i.dt_s, method=i.method, spec=spec)
    t, y = real_inner_step(
        "feedforward", ff.gain, o.period_s, ff.step_duration_s, jac=jac, axis=1,
        model_tau=ff.model_tau_s, lag=ff.lag, **kw,
    )  # fmt: skip
    f_hz = np.geomspace(0.02, 5.0, 240)
    freq = {}
    for mode in ("joint_only", "I", "feedforward"):
        model = LoopModel(
            plants=plants, designs=designs, jac=jac, mode=mode,
            gains=np.full(3, ff.gain if mode == "feedforward" else o.gain),
            period=o.period_s, dt=i.dt_s, method=i.method, pi_zero=o.pi_zero,
            model_tau=ff.model_tau_s, lag=ff.lag, velocity_ff=(
                velocity_gains(plants) if mode == "feedforward" and ff.leg_velocity
                else np.zeros(3)
            ),
        )  # fmt: skip
        h = predict(model, 2 * np.pi * f_hz)["true"]
        ph = np.degrees(np.unwrap(np.angle(h), axis=0))
        freq[mode] = {
            ax: asdict(figures(f_hz, h[:, j, j], ph[:, j, j]))
            for j, ax in enumerate(("roll", "pitch", "heave"))
        }
    if ff.lag == "joints":
        # e = y_d - y - J^-1 (q_d - q) = -c[k-1] in the linear loop: z^2 - z + T g,
        # stable (Jury) for 0 < T g < 1
        limit = 1.0 / o.period_s
        note = ("the correction sees its own last value, z^2 - z + T K K_I: stable "
                "below 1/T (the IMU filter's lag, not in this model, adds a little)")  # fmt: skip
    else:
        limit = real_i.stability_limit
        note = ("the correction closes the I loop around the real inner loops: same "
                "characteristic polynomial, same limit")  # fmt: skip
    stable = ff.gain < limit
    return FeedforwardLoop(
        gain=ff.gain,
        model_tau_s=ff.model_tau_s,
        lag=ff.lag,
        leg_velocity=ff.leg_velocity,
        stability_limit=limit,
        stability_limit_note=note,
        stable_at_gain=stable,
        step_pitch=step_metrics(t, y[:, 1], final=1.0) if stable else None,
        frequency_response=freq,
        _t=t,
        _y=y,
    )


def _law_text(outer: Outer) -> str:
    """The outer law as the scenario runs it, in words."""
    if outer.type == "PI":
        return f"PI law T (z + {outer.pi_zero:g})/(z - 1)"
    if outer.integrator == "backward":
        return "I law by backward Euler, T z/(z - 1)"
    return "I law by forward Euler, T/(z - 1) (Fig. 7 as printed)"


def shipped(scenario: Scenario | Mapping) -> Shipped:
    """The loop ``scenario`` ships, analysed as the preflight does (module docstring).

    ``scenario`` is resolved and carries its design plants
    (:func:`simpro_mj.identification.auto.with_identified`). Returns the loop's
    description (``loop``), and per plant assumption (``actuator``: the plant its
    actuator model stands for; ``paper``: eqs. 34-35) the stability limit of the
    common K K_I, the spectral radius at the scenario's gains and what was analysed.
    """
    from simpro_mj.analysis.stability import outer_loop

    sc = as_scenario(scenario)
    c = sc.controller
    outer, inner, sf = c.outer, c.inner, c.setpoint_filter
    times = "/".join(f"{t:g}" for t in sf.time_ms)
    loop = ShippedLoop(
        scenario=sc.name,
        preset=sc.plant.preset,
        mode=c.mode,
        law=_law_text(outer),
        period_ms=outer.period_ms,
        gains=list(outer.gains),
        setpoint_filter=f"{sf.type} {times} ms" if sf.type != "none" else "none",
        joint_controllers=f"{inner.variant} joint controllers designed on the "
        f"{inner.design_plant} plant",
        dead_band=outer.dead_band.model_dump(),
        joint_integrator_dead_band_mm=list(inner.dead_band_mm),
    )
    limits = {}
    for plant in ("actuator", "paper"):
        r = outer_loop(sc, plant)
        limits[plant] = PlantLimit(
            stability_limit=r["limit"],
            spectral_radius_at_gains=r["spectral_radius"],
            stable_at_gains=r["spectral_radius"] < 1.0,
            basis=r["basis"],
        )
    return Shipped(loop=loop, **limits)


def compute(p: AnalyzeParams | None = None, scenario: Scenario | Mapping | None = None) -> Analysis:
    """All numbers of the analysis for the parameters ``p`` (default: :class:`AnalyzeParams`'s),
    the loop ``scenario`` ships first (:func:`shipped`) when one is given."""
    p = p or AnalyzeParams()
    o, i = p.outer, p.inner
    spec = i.spec()
    inner: dict[str, dict[str, InnerLoop]] = {}
    for act in ACTUATORS:
        inner[act] = {}
        for var in VARIANTS:
            s = inner_summary(act, var, t_end=i.step_duration_s, spec=spec, reading=p.paper_units)
            wns, zetas = s.wn_rad_s, s.zeta
            dom = int(np.argmin(np.where(np.abs(s.closed_loop_poles.imag) > 0, wns, np.inf)))
            inner[act][var] = InnerLoop(
                controller=s.controller,
                closed_loop_poles=_pairs(s.closed_loop_poles),
                wn_rad_s=wns.tolist(),
                zeta=zetas.tolist(),
                slowest_complex_pair={"wn_rad_s": float(wns[dom]), "zeta": float(zetas[dom])},
                step=s.step,
                fraction_at_outer_period=float(np.interp(o.period_s, s.t, s.y)),
                _t=s.t,
                _y=s.y,
            )
    dur = o.step_duration_s
    laws = {"I": o.gain, "PI": o.pi_gain}
    delay = {
        m: _outer_delay(
            m, g, o.period_s, o.delay_samples, o.pi_zero, dur, PAPER[f"{m}_stability_limit"]
        )
        for m, g in laws.items()
    }
    alt = {
        m: _outer_delay(m, g, o.alt_period_s, o.alt_delay_samples, o.pi_zero, dur)
        for m, g in laws.items()
    }
    jac = jacobian(nominal_geometry().home)
    real = {m: _real(m, g, o.period_s, p, spec, jac, dur) for m, g in laws.items()}
    real_alt = {m: _real(m, g, o.alt_period_s, p, spec, jac, dur) for m, g in laws.items()}
    by_variant: dict[str, dict[str, Limits]] = {}
    for var in VARIANTS:
        kw: dict[str, Any] = dict(
            variant=var, dt=i.dt_s, method=i.method, spec=spec, pi_zero=o.pi_zero
        )
        by_variant[var] = {
            m: Limits(
                stability_limit=real_inner_limit(m, o.period_s, jac=jac, **kw),
                per_leg={
                    act: real_inner_limit(m, o.period_s, actuators=(act,), **kw)
                    for act in ACTUATORS
                },
            )
            for m in laws
        }
    rows = []
    for wn in p.sweep.wn_rad_s:
        sp = {"zeta": i.zeta, "wn": float(wn), "p1": 7.6 * wn, "p2": 5.67 * wn}
        s = inner_summary("actuator2", "redesigned", t_end=i.step_duration_s, spec=sp)
        kw = dict(variant="redesigned", dt=i.dt_s, method=i.method, spec=sp, jac=jac)
        rows.append(
            SweepRow(
                wn_rad_s=float(wn),
                inner_fraction_at_T=float(np.interp(o.period_s, s.t, s.y)),
                inner_settling_time_s=s.step["settling_time_s"],
                I_stability_limit=real_inner_limit("I", o.period_s, **kw),
                PI_stability_limit=real_inner_limit("PI", o.period_s, **kw),
            )
        )
    outer = OuterLoops(
        I=delay["I"],
        PI=delay["PI"],
        alt_period=alt,
        real_inner=RealLoops(
            jacobian_at_home=jac,
            I=real["I"],
            PI=real["PI"],
            alt_period=real_alt,
            by_variant=by_variant,
        ),  # fmt: skip
        feedforward=_feedforward(p, spec, jac, real["I"]),
        delay_assumption_sweep=DelaySweep(
            delay_model={f"{m}_stability_limit": delay[m].stability_limit for m in laws},
            rows=rows,
        ),
    )
    return Analysis(
        shipped=shipped(scenario) if scenario is not None else None,
        paper=PAPER,
        paper_units=paper_units_info(p.paper_units),
        inner=inner,
        outer=outer,
    )


def document(res: Analysis, p: AnalyzeParams, files: list[str]) -> dict:
    """The ``--json`` document: the results without the plotting arrays, the
    parameters and the plots written."""
    return res.to_json() | {"params": p.model_dump(), "plots": files}
