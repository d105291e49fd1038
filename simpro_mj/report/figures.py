"""What every figure of simpro-sim shares: colours, the curve decimation, saving,
and the check that a legend names what is drawn.

Figures are :class:`matplotlib.figure.Figure` objects written by ``savefig``
(Agg, no pyplot, no display); importing this module does not load matplotlib,
so a command that only refuses a mistake stays fast. The
colours are those of the paper's Figs. 14-16 for set-point and output; each
leg has one colour in every figure and in the video's plot strip
(:data:`LEG_COLOURS`), none of them the set-point's blue or the output's
green.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from controllers.geometry import H0

if TYPE_CHECKING:  # matplotlib is loaded by whoever draws, not by importing this module
    from matplotlib.figure import Figure

DESIRED = "tab:blue"  # "in blue the wanted value" (Fig. 14)
OUTPUT = "tab:green"  # "in green the output"
MEASURED = "0.55"
#: leg (cylinder and valve) i -> its colour, the same in every figure and the video
LEG_COLOURS = {1: "tab:orange", 2: "tab:purple", 3: "tab:brown"}
DPI = 120
#: The task axes as drawn: (title, ref column, true column, measured column, scale to the
#: display unit, unit, zero); heave from the home height H0, as the summary's table and
#: metrics.json give it
TASK_AXES = (
    ("a) Roll", "roll_ref_rad", "roll_rad", "roll_meas_rad", 180.0 / math.pi, "deg", 0.0),
    ("b) Pitch", "pitch_ref_rad", "pitch_rad", "pitch_meas_rad", 180.0 / math.pi, "deg", 0.0),
    ("c) Heave from home", "heave_ref_m", "heave_m", "heave_meas_m", 1e3, "mm", H0),
)
#: Buckets of :func:`envelope`: more than the pixel columns of any figure's axes
#: at :data:`DPI` (a 12-inch figure is 1440 px wide), so the decimated curve
#: draws the same pixels as the full one.
ENVELOPE_BUCKETS = 2000


def envelope(t, y, buckets: int = ENVELOPE_BUCKETS):
    """A long curve reduced to each bucket's first, lowest, highest and last sample.

    A 20 s run logged every 1 ms has 20,001 samples, 15-20 per pixel column of
    a figure; drawing all of them (and placing a legend clear of them) is most
    of a figure's cost. Keeping, in time order, the extremes of each of
    ``buckets`` equal slices (and the slice's ends, so that consecutive buckets
    join where the curve does) draws the same envelope: every peak, step and
    spike survives, the line between two kept samples lies inside the pixels
    the dropped ones would have lit. Curves with a non-finite value are
    returned whole (a diverged run's last samples are what one looks at).

    Returns
    -------
    (ndarray, ndarray)
        The kept times and values (views of the inputs when nothing is dropped).
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    n = y.size
    if n <= 4 * buckets or not np.isfinite(y).all():
        return t, y
    size = -(-n // buckets)
    m = n // size * size
    blocks = y[:m].reshape(-1, size)
    base = np.arange(0, m, size)
    lo = base + blocks.argmin(axis=1)
    hi = base + blocks.argmax(axis=1)
    keep = np.concatenate([base, base + size - 1, lo, hi, np.arange(m, n)])
    keep = np.unique(keep)  # sorted: time order
    return t[keep], y[keep]


def margins(
    fig: Figure,
    left: float = 0.85,
    right: float = 0.2,
    top: float = 0.5,
    bottom: float = 0.55,
    hspace: float = 0.25,
    wspace: float = 0.2,
) -> Figure:
    """Fixed margins around the axes of ``fig`` (instead of a layout engine).

    ``left``, ``right``, ``top``, ``bottom`` in inches (so they fit the same
    labels at any figure size); ``hspace``, ``wspace`` as fractions of an
    axis's height and width (matplotlib's). Constrained layout measures every
    tick label at each save, half the cost of a run figure; the run figures'
    labels have a known length (a y label, 4-6 digit ticks, one title line).
    """
    w, h = fig.get_size_inches()
    fig.subplots_adjust(left=left / w, right=1.0 - right / w, top=1.0 - top / h,
                        bottom=bottom / h, hspace=hspace, wspace=wspace)  # fmt: skip
    return fig


def log_ticks(ax, axis: str = "x") -> None:
    """Plain decimal labels on a log axis (0.1, 1, 10) and, when it spans at most
    two decades, at 2 and 5 of each decade too; no other minor labels.

    matplotlib's default labels the minor ticks of a short log axis in
    scientific notation ("3x10^-1"), which overlap.
    """
    from matplotlib.ticker import FuncFormatter

    target = ax.xaxis if axis == "x" else ax.yaxis
    target.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))

    def minor(v, _pos):
        lo, hi = sorted(ax.get_xlim() if axis == "x" else ax.get_ylim())
        if lo <= 0 or hi / lo > 100.0:
            return ""
        lead = round(v / 10.0 ** np.floor(np.log10(v) + 1e-9), 6)
        return f"{v:g}" if lead in (2.0, 5.0) else ""

    target.set_minor_formatter(FuncFormatter(minor))


def loop_label(scenario) -> str:
    """The control scheme of a scenario as a title says it: ``task_space, I law``,
    ``joint_only``, ``feedforward, PI correction``."""
    ctl = scenario.get("controller", {}) if hasattr(scenario, "get") else {}
    mode = ctl.get("mode", "?")
    if mode == "task_space":
        return f"task_space, {ctl.get('outer', {}).get('type', '?')} law"
    if mode == "feedforward":
        return f"feedforward, {ctl.get('outer', {}).get('type', '?')} correction"
    return str(mode)


def save(fig: Figure, path, dpi: int = DPI) -> Path:
    """Write ``fig`` as a PNG and return its path."""
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    return path


def legend_mismatches(fig: Figure) -> list[str]:
    """What a figure's legends and its drawn series disagree on (empty: they agree).

    Every legend entry must name an artist drawn in the figure with data (a
    line with at least one point, a filled patch or a scatter with a point),
    and every labelled artist of an axis must be listed by some legend of the
    figure (an axis's legend, or the figure's). Returns one line per mismatch.
    """
    # matplotlib is loaded: the figure exists
    from matplotlib.collections import Collection
    from matplotlib.lines import Line2D

    drawn: dict[str, bool] = {}
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        for artist in (*ax.lines, *ax.collections, *ax.patches):
            label = artist.get_label()
            if not isinstance(label, str) or not label or label.startswith("_"):
                continue
            has_data = True
            if isinstance(artist, Line2D):
                has_data = np.size(artist.get_xydata()) > 0
            elif isinstance(artist, Collection):
                has_data = np.size(artist.get_offsets()) > 0 or bool(artist.get_paths())
            drawn[label] = drawn.get(label, False) or has_data
    listed: set[str] = set()
    legends = [ax.get_legend() for ax in fig.axes] + list(fig.legends)
    for legend in legends:
        if legend is None:
            continue
        listed.update(text.get_text() for text in legend.get_texts())
    problems = []
    for label in sorted(listed):
        if label not in drawn:
            problems.append(f"legend entry {label!r} names nothing drawn")
        elif not drawn[label]:
            problems.append(f"legend entry {label!r} names a series without data")
    for label in sorted(set(drawn) - listed):
        problems.append(f"series {label!r} is drawn but no legend lists it")
    return problems
