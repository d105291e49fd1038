"""What ``simpro-sim analyze`` shows: the loops' analysis as figures and a printed summary.

:func:`plot` writes the root loci (Figs. 8-9), the step responses and the
delay-assumption sweep as PNG; :func:`summary` is the text printed. The numbers
are :func:`simpro_mj.analysis.analyze.compute`'s.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from controllers.analysis import outer_delay as an
from simpro_mj.analysis.analyze import ACTUATORS, VARIANTS, AnalyzeParams
from simpro_mj.analysis.loop_records import Analysis, Shipped


def plot(res: Analysis, p: AnalyzeParams, out: Path) -> list[str]:
    """Root loci (Figs. 8-9), step responses and the delay-assumption plot as PNG."""
    # matplotlib when a figure is drawn, not when the analyze command starts
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    files = []
    o = p.outer
    th = np.linspace(0, 2 * np.pi, 400)
    for mode, r, fig_no in (("I", res.outer.I, 8), ("PI", res.outer.PI, 9)):
        a, b = r._ab
        gains = np.linspace(0.0, o.locus_gain_max, 1201)
        loc = an.root_locus(a, b, gains)
        fig, ax = plt.subplots(figsize=(6, 6))
        ax.plot(np.cos(th), np.sin(th), "k:", lw=0.8, label="unit circle")
        for j in range(loc.shape[1]):
            ax.plot(loc[:, j].real, loc[:, j].imag, ".", ms=1.5, color="C0")
        pz = np.array([complex(*v) for v in r.poles])
        ax.plot(pz.real, pz.imag, "rs", label=f"poles at K K_I = {r.gain:g}")
        lim = r.stability_limit
        pl = an.outer_poles(mode, lim, o.period_s, o.delay_samples, o.pi_zero)
        label = f"limit K K_I = {lim:.2f} (paper {r.paper_stability_limit:g})"
        ax.plot(pl.real, pl.imag, "kx", ms=9, label=label)
        ax.set(aspect="equal", xlabel="Re z", ylabel="Im z")
        title = f"{mode} law, T = {o.period_s * 1e3:g} ms, one-sample inner delay"
        ax.set_title(f"{title} (cf. Fig. {fig_no})", fontsize=9)
        ax.legend(fontsize=8, loc="lower left")
        ax.grid(alpha=0.3)
        files.append(_save(plt, fig, out / f"root_locus_{mode}.png"))

    fig, ax = plt.subplots(figsize=(8, 4.5))
    ri = res.outer.real_inner
    for mode, c, r, rr in (("I", "C0", res.outer.I, ri.I), ("PI", "C1", res.outer.PI, ri.PI)):
        ax.step(r._t, r._y, where="post", color=c, label=f"{mode}, K K_I={r.gain:g}, delay model")
        label = f"{mode}, real inner loops ({rr.variant}), heave"
        ax.plot(rr._t, rr._y[:, 2], color=c, ls="--", label=label)
    ff = res.outer.feedforward
    lag = "lag from the joints" if ff.lag == "joints" else f"model {ff.model_tau_s * 1e3:g} ms"
    label = f"feedforward, K K_I={ff.gain:g}, {lag}, pitch"
    ax.plot(ff._t, ff._y[:, 1], color="C2", label=label)
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set(ylim=(-0.5, 2.0), xlabel="t (s)", ylabel="task output / step")
    ax.set_title("Outer-loop unit-step responses", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    files.append(_save(plt, fig, out / "outer_step.png"))

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, act in zip(axes, ACTUATORS, strict=True):
        for var in VARIANTS:
            loop = res.inner[act][var]
            ax.plot(loop._t, loop._y, label=f"{var} (OS {loop.step['overshoot_pct']:.0f} %)")
        ax.axvline(o.period_s, color="k", ls=":", lw=0.8, label="outer period")
        ax.set_title(f"{act}: joint-loop step (continuous)", fontsize=9)
        ax.set_xlabel("t (s)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("q / q_d")
    files.append(_save(plt, fig, out / "inner_step.png"))

    rows = res.outer.delay_assumption_sweep.rows
    if rows:
        fig, ax = plt.subplots(figsize=(7, 4))
        wn = [r.wn_rad_s for r in rows]
        ax.semilogx(wn, [r.I_stability_limit for r in rows], "o-", label="I, real inner")
        ax.semilogx(wn, [r.PI_stability_limit for r in rows], "s-", label="PI, real inner")
        dm = res.outer.delay_assumption_sweep.delay_model
        ax.axhline(dm["I_stability_limit"], color="C0", ls=":", label="I, delay model")
        ax.axhline(dm["PI_stability_limit"], color="C1", ls=":", label="PI, delay model")
        ax.set_xlabel("inner-loop wn (rad/s), zeta = 0.7, redesigned")
        ax.set_ylabel("largest stable K K_I")
        title = f"When is the inner loop a one-sample delay? T = {o.period_s * 1e3:g} ms"
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
        files.append(_save(plt, fig, out / "delay_assumption.png"))
    return files


def _save(plt, fig, path: Path) -> str:
    """Write ``fig`` at 120 dpi, close it, return its path."""
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return str(path)


def _shipped_lines(sh: Shipped) -> list[str]:
    """The scenario's own loop, first: which loop, and its limits."""
    lo = sh.loop
    db = lo.dead_band
    band = (
        f"; dead band {db['roll_deg']:g} deg / {db['pitch_deg']:g} deg / {db['heave_mm']:g} mm"
        if any(db.values())
        else ""
    )
    joints = lo.joint_integrator_dead_band_mm
    if any(joints):
        band += f"; joint integrators hold within {'/'.join(f'{w:g}' for w in joints)} mm"
    if band:
        band += " (dead bands: outside the linear analysis)"
    lines = [
        f"Shipped loop of {lo.scenario} (preset {lo.preset}, mode {lo.mode}): "
        f"{lo.law}, T = {lo.period_ms:g} ms, {lo.setpoint_filter} set-point filter, "
        f"{lo.joint_controllers}{band}"
    ]
    gains = ", ".join(f"{g:g}" for g in lo.gains)
    for r, what in ((sh.actuator, "its plant"), (sh.paper, "eqs. (34)-(35)")):
        lines.append(
            f"  on {what}: limit K K_I < {r.stability_limit:.2f}; at [{gains}] rho = "
            f"{r.spectral_radius_at_gains:.4f} "
            f"{'stable' if r.stable_at_gains else 'UNSTABLE'} ({r.basis})"
        )
    lines.append(
        "The paper's loops (Fig. 7 as printed: I law by forward Euler, no set-point filter):"
    )
    return lines


def summary(res: Analysis, files: list[str]) -> str:
    u = res.paper_units
    lines = _shipped_lines(res.shipped) if res.shipped is not None else []
    lines.append(
        f"Inner (joint) loops, continuous, plants eqs. (34)-(35); paper_units = {u['reading']} "
        f"(Y in {u['y_unit']}, {u['y_per_metre']:g} per m): k_p in V/m"
    )
    for act in ACTUATORS:
        for var in VARIANTS:
            loop = res.inner[act][var]
            d = loop.slowest_complex_pair
            st = loop.step
            lines.append(
                f"  {act:9s} {var:10s} k_p={loop.controller['kp']:7.1f} slowest pair "
                f"zeta={d['zeta']:.3f} wn={d['wn_rad_s']:.2f} "
                f"rad/s | rise {st['rise_time_s']:.3f} s, settle {st['settling_time_s']:.3f} s, "
                f"OS {st['overshoot_pct']:.1f} %, q(T)/q_d={loop.fraction_at_outer_period:.2f}"
            )
    o = res.outer
    lines.append("Outer loop, inner loop = delay (eqs. 21, 24):")
    for m, r in (("I", o.I), ("PI", o.PI)):
        lines.append(
            f"  {m:2s} T={r.period_s * 1e3:g} ms d={r.delay_samples}: limit K K_I < "
            f"{r.stability_limit:.3f} (paper {r.paper_stability_limit:g}); "
            f"poles at {r.gain:g}: " + ", ".join(f"{complex(*z):.4f}" for z in r.poles)
        )
    for m, r in o.alt_period.items():
        lines.append(
            f"  {m:2s} T={r.period_s * 1e3:g} ms d={r.delay_samples}: limit K K_I < "
            f"{r.stability_limit:.3f}"
        )
    ri = o.real_inner
    lines.append(f"Outer loop around the real inner loops ({ri.I.variant}, J at home):")
    for key, real in (("I", ri.I), ("PI", ri.PI), *ri.alt_period.items()):
        legs = ", ".join(f"{k} {v:.2f}" for k, v in real.stability_limit_per_leg.items())
        lines.append(
            f"  {key:2s} T={real.period_s * 1e3:g} ms: limit {real.stability_limit:.3f} "
            f"(per leg: {legs}); at K K_I={real.gain:g}: rho={real.spectral_radius_at_gain:.4f}"
            f" {'stable' if real.stable_at_gain else 'UNSTABLE'}"
        )
    for variant, lim in ri.by_variant.items():
        lines.append(
            f"  {variant:10s} T={res.outer.I.period_s * 1e3:g} ms: "
            + "; ".join(
                f"{m} limit {lim[m].stability_limit:.3f} (per leg "
                + ", ".join(f"{k} {v:.2f}" for k, v in lim[m].per_leg.items())
                + ")"
                for m in ("I", "PI")
            )
        )
    ff = o.feedforward
    pitch = ff.step_pitch
    lines.append(
        f"Feed-forward scheme (lag {ff.lag}"
        + (f", model tau {ff.model_tau_s * 1e3:g} ms" if ff.lag == "model" else "")
        + f", K K_I = {ff.gain:g}): limit {ff.stability_limit:.3f}"
        + (" (1/T)" if ff.lag == "joints" else " (the I loop's)")
        + "; pitch step "
        + (
            f"rise {pitch['rise_time_s']:.3f} s, OS {pitch['overshoot_pct']:.1f} %, "
            f"settle {pitch['settling_time_s']:.3f} s"
            if pitch
            else "unstable"
        )
    )
    for mode, axes in ff.frequency_response.items():
        v = axes["pitch"]
        bw = v["bandwidth_3db_hz"]
        bw_text = f">{v['bandwidth_above_hz']:.2f}" if bw is None else f"{bw:.2f}"
        lines.append(
            f"  {mode:11s} pitch: bandwidth {bw_text} Hz, phase "
            f"{v['phase_deg_at_0_5_hz']:.1f} deg at 0.5 Hz, {v['phase_deg_at_1_hz']:.1f} at 1 Hz, "
            f"delay {v['equivalent_delay_ms']:.0f} ms"
        )
    lines.append("Delay assumption (redesigned inner loops, wn swept):")
    for row in o.delay_assumption_sweep.rows:
        lines.append(
            f"  wn={row.wn_rad_s:6.1f} rad/s: q(T)/q_d={row.inner_fraction_at_T:.2f}, "
            f"limits I {row.I_stability_limit:.2f}, PI {row.PI_stability_limit:.2f}"
        )
    if files:
        lines.append("Plots: " + ", ".join(files))
    return "\n".join(lines)
