"""What ``simpro-sim identify`` shows: the fitted models against the paper's (Fig. 12).

:func:`summary` is the table printed, :func:`plot` the figure written next to
``identify.json`` (:mod:`simpro_mj.identification.identify` does the experiment
and the fit).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.signal import lti, step

from controllers.design import paper_units_info
from simpro_mj.identification.identify import paper_models, simulate_velocity


def summary(results: dict, reading: str = "volts", preset: str = "") -> str:
    """Table of fitted vs paper coefficients (ω_n, ζ, b/a0), the paper's in SI
    under ``reading``."""
    info = paper_units_info(reading)
    paper = paper_models(reading)
    lines = [
        f"plant preset {preset or '-'}; paper eqs. (34)-(35) in SI under paper_units = "
        f"{reading} (Y in {info['y_unit']}: b / {info['y_per_metre']:g})",
        f"{'':10s} {'b':>9s} {'a1':>8s} {'a0':>8s} {'wn rad/s':>9s} {'zeta':>7s} "
        f"{'b/a0 m/s/V':>11s} {'fit %':>6s}",
    ]
    for name, r in results.items():
        p = paper[name]
        lines.append(
            f"{name:10s} {r.b:9.2f} {r.a1:8.3f} {r.a0:8.1f} {r.wn_rad_s:9.2f} "
            f"{r.zeta:7.3f} {r.velocity_gain_m_s_per_v:11.4f} {r.fit_percent or 0:6.1f}"
        )
        lines.append(
            f"{'  paper':10s} {p.b:9.2f} {p.a1:8.3f} {p.a0:8.1f} {p.wn_rad_s:9.2f} "
            f"{p.zeta:7.3f} {p.velocity_gain_m_s_per_v:11.4f}"
        )
        lines.append(
            f"{'  ratio':10s} {'':9s} {'':8s} {'':8s} {r.wn_rad_s / p.wn_rad_s:9.3f} "
            f"{r.zeta - p.zeta:+7.3f} "
            f"{r.velocity_gain_m_s_per_v / p.velocity_gain_m_s_per_v:11.4f}"
        )
    return "\n".join(lines)


def plot(results: dict, records: dict, path: Path, reading: str = "volts") -> None:
    """Step responses (fitted vs paper) and a window of measured vs fitted velocity."""
    # matplotlib when a figure is drawn, not when the identify command starts
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(results)
    fig, axes = plt.subplots(2, len(names), figsize=(4.6 * len(names), 7), squeeze=False)
    for c, name in enumerate(names):
        r, p = results[name], paper_models(reading)[name]
        t = np.linspace(0, 1.0, 1000)
        ax = axes[0, c]
        for coef, lab, sty in ((r, "simulation fit", "-"), (p, "paper eq. (34)/(35)", "--")):
            _, y = step(lti([coef.b], [1.0, coef.a1, coef.a0, 0.0]), T=t)
            ax.plot(t, y * 1e3, sty, label=lab)
        ax.set(title=f"{name}: 1 V step, position", xlabel="t (s)", ylabel="Δq (mm)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        rec = records[name]
        n = min(rec.t.size, 3000)
        s0 = rec.t.size // 2
        sl = slice(s0, s0 + n)
        vhat = simulate_velocity((r.b, r.a1, r.a0, r.offset_v), rec.u - 5.0, rec.dt)
        ax = axes[1, c]
        ax.plot(rec.t[sl], rec.qdot[sl] * 1e3, lw=0.8, label="MuJoCo + pneumatics")
        ax.plot(rec.t[sl], vhat[sl] * 1e3, lw=0.8, label=f"fit ({r.fit_percent:.0f} %)")
        ax.set(xlabel="t (s)", ylabel="qdot (mm/s)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
