"""``simpro-sim omct``'s figures, table and summary (:mod:`simpro_mj.analysis.omct`)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

from simpro_mj.report.figures import log_ticks, save

if TYPE_CHECKING:  # the analysis loads the laws: when the OMCT runs
    from simpro_mj.analysis.omct import Omct

CSV_COLUMNS = (
    "law",
    "test",
    "input",
    "output",
    "omega_rad_s",
    "frequency_hz",
    "gain",
    "gain_db",
    "phase_deg",
)

_DIRECT = ("surge", "sway", "heave", "pitch", "roll")
_CROSS = ("pitch-to-surge", "roll-to-sway", "surge-to-pitch", "sway-to-roll")
_REGION_COLOURS = {"high": "#c7e9c0", "medium": "#fdd0a2"}


def plot_omct(res: Omct, folder: Path) -> list[str]:
    """``omct_bode.png`` (gain and phase of every test per law against the OMCT
    frequencies) and ``omct_fidelity.png`` (each law's direct responses at 1 rad/s on the
    gain / phase-distortion plane with the fidelity regions)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from simpro_mj.analysis.omct import FIDELITY_REGIONS, FIDELITY_SOURCE

    laws = list(res.laws)
    colours = {law: f"C{i}" for i, law in enumerate(laws)}
    tests = _DIRECT + _CROSS
    fig, axes = plt.subplots(2, len(tests), figsize=(2.6 * len(tests), 5.6), sharex=True)
    for j, test in enumerate(tests):
        for law in laws:
            rows = [r for r in res.rows if r.law == law and r.test == test]
            om = [r.omega_rad_s for r in rows]
            axes[0, j].semilogx(om, [r.gain for r in rows], "o-", ms=3, color=colours[law],
                                label=law)  # fmt: skip
            axes[1, j].semilogx(om, [r.phase_deg for r in rows], "o-", ms=3,
                                color=colours[law])  # fmt: skip
        unit = rows[0].output if rows else ""
        cin = rows[0].input if rows else ""
        units = {"f": "m/s^2", "w": "deg/s"}
        axes[0, j].set_title(f"{test}\n({units[unit[:1]]} per {units[cin[:1]]})", fontsize=8)
        axes[1, j].set_xlabel("rad/s")
        for a in axes[:, j]:
            a.axvline(1.0, color="0.6", lw=0.6, ls=":")
            a.grid(True, which="both", lw=0.3)
            log_ticks(a)
    axes[0, 0].set_ylabel("gain")
    axes[1, 0].set_ylabel("phase (deg)")
    axes[0, 0].legend(fontsize=7, loc="best")
    fig.suptitle(
        "Objective motion cueing test per law: vehicle -> driver's head "
        f"(law, loop model, rigid cabin; sines of {res.f_mps2:g} m/s^2, "
        f"{res.w_deg_s:g} deg/s)",
        fontsize=10,
    )
    fig.tight_layout()
    files = [save(fig, folder / "omct_bode.png", 100).name]
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.4))
    groups = (
        ("translation (surge, sway, heave)", _DIRECT[:3]),
        ("rotation (pitch, roll)", _DIRECT[3:]),
    )
    markers = {"surge": "o", "sway": "s", "heave": "^", "pitch": "D", "roll": "v"}
    for ax, (title, names) in zip(axes, groups, strict=True):
        for name, lo, hi, ph in reversed(FIDELITY_REGIONS):
            label = f"Sinacori {name} fidelity: gain {lo:g}-{hi:g}, phase within {ph:g} deg"
            ax.add_patch(Rectangle((lo, 0), min(hi, 1.6) - lo, ph, color=_REGION_COLOURS[name],
                                   alpha=0.8, label=label, zorder=0))  # fmt: skip
        for law in laws:
            v = res.fidelity_at_1_rad_s[law]
            for test in names:
                if test in v:
                    # the phase's distance from 0, whatever its branch (deg, 0..180)
                    distortion = abs((v[test].phase_deg + 180.0) % 360.0 - 180.0)
                    ax.plot(v[test].gain, distortion, markers[test], color=colours[law], ms=7,
                            label=f"{law}: {test}")  # fmt: skip
        ax.text(0.05, 170, "low fidelity elsewhere", fontsize=7, va="top")
        ax.set_xlim(0, 1.6)
        ax.set_ylim(0, 180)
        ax.set_xlabel("gain at 1 rad/s")
        ax.set_ylabel("phase distortion at 1 rad/s (deg)")
        ax.set_title(title, fontsize=9)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=6, loc="upper right", ncol=1)
    fig.suptitle(
        "Each law's direct OMCT responses at 1 rad/s (ICAO 9625) in the fidelity regions of\n"
        + FIDELITY_SOURCE.replace("; ", ";\n"),
        fontsize=8,
    )
    fig.tight_layout()
    files.append(save(fig, folder / "omct_fidelity.png", 100).name)
    plt.close(fig)
    return files


def print_omct_summary(res: Omct, folder, files=(), file=None) -> None:
    """Per law the direct tests at 1 rad/s (gain, phase, fidelity region), then where
    the files are (``files``: their names in ``folder``)."""
    from simpro_mj.analysis.omct import CHAIN

    file = sys.stdout if file is None else file
    print("OMCT at 1 rad/s (gain, phase deg, fidelity):", file=file)
    head = f"{'law':<20}" + "".join(f"{t:>24}" for t in _DIRECT)
    print(head, file=file)
    print("-" * len(head), file=file)
    for law, v in res.fidelity_at_1_rad_s.items():
        cells = []
        for t in _DIRECT:
            c = v.get(t)
            cells.append(
                f"{'-':>24}" if c is None
                else f"{c.gain:>8.2f}{c.phase_deg:>8.0f} {c.fidelity:>7}"
            )  # fmt: skip
        print(f"{law:<20}" + "".join(cells), file=file)
    print(f"({CHAIN})", file=file)
    if folder is not None:
        print(f"results: {folder}", file=file)
        print("  " + ", ".join(files), file=file)
