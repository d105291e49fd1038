"""The robustness floors of a Monte Carlo sweep over payload and seal friction.

A variant *meets the floors* when its run is ``ok`` (it settled: no limit
cycle, :mod:`simpro_mj.analysis.verdict`) and every axis with a step has an
overshoot of at most :data:`OVERSHOOT_PCT` and a 2 % settling time of at most
:data:`SETTLING_S` (``scenarios/sweep_robustness.yaml``). For a Monte Carlo file
that draws the payload mass and the legs' Coulomb friction,
:func:`robustness_table` gives the fraction meeting the floors, overall and per
cell of a payload x friction grid, and :func:`map_figure` draws the map:
payload against the smallest Coulomb friction of the three legs (the seal whose
breakaway stands farthest above its running friction when the breakaway is held,
as in the cabin's sweep), coloured by the verdict, the overshoot and the settling
time.

The fractions are over the variants that *finished* (ran to their end or diverged,
failed or were invalid): a variant the batch did not finish (``cancelled``, or
``interrupted`` when the batch was stopped while it ran) has no answer, so it is
neither a success nor a failure; the table counts those apart as ``unfinished``.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from simpro_mj.batch.summary import Row

#: The floors: overshoot (%) and 2 % settling time (s) of every stepped axis.
OVERSHOOT_PCT = 15.0
SETTLING_S = 4.0
#: The swept paths the map is drawn over.
PAYLOAD = "plant.payload.mass_kg"
COULOMB = "actuator.pneumatics.cylinder.coulomb_friction_n"
#: Cell edges of the table: payload (kg) and the smallest leg's Coulomb friction (N),
#: extended by whole cells to the largest drawn value (:func:`_edges`).
PAYLOAD_EDGES = (0.0, 100.0, 200.0, 300.0, 400.0)
COULOMB_EDGES = (0.0, 50.0, 100.0, 150.0, 200.0, 250.0)
#: The statuses of a variant the batch did not finish (no verdict to count).
UNFINISHED = ("cancelled", "interrupted")


def worst(row: Row) -> tuple[float | None, float | None]:
    """(largest overshoot %, longest settling s) over the stepped axes (those with an
    overshoot measured); inf: never settled."""
    stepped = [(o, a.settling_s) for a in row.axes if (o := a.overshoot_pct) is not None]
    if not stepped:
        return None, None
    over = max(float(o) for o, _ in stepped)
    return over, max(np.inf if s is None else float(s) for _, s in stepped)


def meets_floors(row: Row) -> bool:
    """Status ok, and every stepped axis within the overshoot and settling floors."""
    over, settle = worst(row)
    return (
        row.status == "ok"
        and over is not None
        and over <= OVERSHOOT_PCT
        and settle is not None
        and settle <= SETTLING_S
    )


def _point(row: Row) -> tuple[float, float] | None:
    values = row.values
    if PAYLOAD not in values or COULOMB not in values:
        return None
    return float(values[PAYLOAD]), float(np.min(values[COULOMB]))


def _edges(base: tuple, values) -> tuple:
    """``base`` extended by cells of its last width until it holds every value: a map
    over the catalogue's seals (up to 450 N) is drawn whole, not cut at 250 N."""
    edges, width = list(base), base[-1] - base[-2]
    while max(values, default=edges[-1]) > edges[-1]:
        edges.append(edges[-1] + width)
    return tuple(edges)


def _cell(edges, x: float) -> int:
    return int(np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2))


@dataclass
class Floors:
    """What a variant must meet (module docstring)."""

    overshoot_pct: float = OVERSHOOT_PCT
    settling_s: float = SETTLING_S
    status: str = "ok"


@dataclass
class Cell:
    """One payload x friction cell: its bands, its finished variants and those that met."""

    payload_kg: list[float]
    coulomb_n: list[float]
    n: int
    met: int
    fraction: float | None


@dataclass
class RobustnessTable:
    """The floors over the finished variants of one scenario file that drew payload and
    friction: ``n`` the finished variants, ``unfinished`` those the batch did not finish
    (module docstring), ``statuses`` the finished ones' statuses, ``cells`` one per
    payload x friction cell (payload rows, friction columns); ``fraction`` None when
    none finished."""

    scenario: str
    n: int
    met: int
    fraction: float | None
    unfinished: int
    floors: Floors = field(default_factory=Floors)
    statuses: dict[str, int] = field(default_factory=dict)
    cells: list[Cell] = field(default_factory=list)
    payload_edges: list[float] = field(default_factory=list)
    coulomb_edges: list[float] = field(default_factory=list)


def robustness_table(rows: list[Row], name: str) -> RobustnessTable | None:
    """The :class:`RobustnessTable` of scenario file ``name``; None when no variant
    drew both payload and friction."""
    drawn = [(r, p) for r in rows if r.scenario == name and (p := _point(r)) is not None]
    if not drawn:
        return None
    pts = [(r, p) for r, p in drawn if r.status not in UNFINISHED]
    met = [meets_floors(r) for r, _ in pts]
    statuses = dict(Counter(r.status for r, _ in pts))
    cells = []
    pay_edges = _edges(PAYLOAD_EDGES, [p[0] for _, p in drawn])
    cou_edges = _edges(COULOMB_EDGES, [p[1] for _, p in drawn])
    for i in range(len(pay_edges) - 1):
        for j in range(len(cou_edges) - 1):
            inside = [
                m
                for (_, (pay, cou)), m in zip(pts, met, strict=True)
                if _cell(pay_edges, pay) == i and _cell(cou_edges, cou) == j
            ]
            cells.append(
                Cell(
                    payload_kg=[pay_edges[i], pay_edges[i + 1]],
                    coulomb_n=[cou_edges[j], cou_edges[j + 1]],
                    n=len(inside),
                    met=sum(inside),
                    fraction=sum(inside) / len(inside) if inside else None,
                )
            )
    return RobustnessTable(
        scenario=name,
        n=len(pts),
        met=sum(met),
        fraction=sum(met) / len(pts) if pts else None,
        unfinished=len(drawn) - len(pts),
        statuses=statuses,
        cells=cells,
        payload_edges=list(pay_edges),
        coulomb_edges=list(cou_edges),
    )


def table_lines(table: RobustnessTable) -> list[str]:
    """The table as text: the fraction, then one row per payload band."""
    f = table.floors
    pay_edges, cou_edges = table.payload_edges, table.coulomb_edges
    per_row = len(cou_edges) - 1
    lines = [
        f"\nRobustness {table.scenario}: {fraction_text(table)} meet overshoot <= "
        f"{f.overshoot_pct:g} %, settling <= {f.settling_s:g} s, status ok; statuses "
        + (", ".join(f"{k} {v}" for k, v in sorted(table.statuses.items())) or "none"),
        "  met / n per cell (n: finished variants): payload (kg) rows, smallest Coulomb "
        "friction of a leg (N) columns",
        "  " + " " * 10 + "".join(f"{_band(cou_edges, j):>10}" for j in range(per_row)),
    ]
    for i in range(len(pay_edges) - 1):
        cells = table.cells[i * per_row : (i + 1) * per_row]
        text = "".join(f"{str(c.met) + '/' + str(c.n):>10}" for c in cells)
        lines.append(f"  {_band(pay_edges, i):<10}{text}")
    return lines


def fraction_text(table: RobustnessTable) -> str:
    """``"51 of 53 finished variants (96.2 %)"``, with the unfinished ones named."""
    pct = "-" if table.fraction is None else f"{100 * table.fraction:.1f} %"
    text = f"{table.met} of {table.n} finished variants ({pct})"
    if table.unfinished:
        text += f" [{table.unfinished} not finished, not counted]"
    return text


def _band(edges, i: int) -> str:
    return f"{edges[i]:g}-{edges[i + 1]:g}"


_VERDICT_STYLE = {
    "meets the floors": ("o", "tab:green"),
    "ok, beyond a floor": ("s", "tab:orange"),
    "not_settled": ("v", "tab:purple"),
    "limit_cycle": ("x", "tab:red"),
    "other": ("D", "0.4"),
}


def _verdict_class(row: Row) -> str:
    if meets_floors(row):
        return "meets the floors"
    if row.status == "ok":
        return "ok, beyond a floor"
    return row.status if row.status in ("not_settled", "limit_cycle") else "other"


def map_figure(rows: list[Row], table: RobustnessTable):
    """Payload x the smallest leg's Coulomb friction, coloured by verdict, overshoot, settling
    (a matplotlib Figure; None without points)."""
    from matplotlib.figure import Figure  # when drawn: the batch's start does not load it

    pts = [
        (r, p)
        for r in rows
        if r.scenario == table.scenario
        and (p := _point(r)) is not None
        and r.status not in UNFINISHED
    ]
    if not pts:
        return None
    fig = Figure(figsize=(15, 4.8), layout="constrained")
    axes = fig.subplots(1, 3, sharex=True, sharey=True)
    ax = axes[0]
    for cls, (marker, colour) in _VERDICT_STYLE.items():
        sel = [p for r, p in pts if _verdict_class(r) == cls]
        if sel:
            x, y = np.array(sel).T
            ax.scatter(x, y, marker=marker, color=colour, s=28, label=f"{cls} ({len(sel)})")
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title("verdict", fontsize=10)
    worsts = [worst(r) for r, _ in pts]
    for ax, k, label, vmax, floor in (
        (axes[1], 0, "largest overshoot [%]", 3 * OVERSHOOT_PCT, OVERSHOOT_PCT),
        (axes[2], 1, "longest 2 % settling [s]", 3 * SETTLING_S, SETTLING_S),
    ):
        x = np.array([p[0] for _, p in pts])
        y = np.array([p[1] for _, p in pts])
        v = np.array([np.nan if w[k] is None else w[k] for w in worsts], float)
        v = np.where(np.isinf(v), vmax, v)
        sc = ax.scatter(x, y, c=np.clip(v, 0, vmax), cmap="viridis", vmin=0, vmax=vmax, s=28)
        beyond = v > floor
        ax.scatter(x[beyond], y[beyond], facecolors="none", edgecolors="red", s=70, lw=0.8)
        cb = fig.colorbar(sc, ax=ax)
        cb.set_label(f"{label}; ringed: beyond {floor:g}", fontsize=8)
        ax.set_title(label.split(" [")[0] + (" (never settled: top of the scale)" if k else ""),
                     fontsize=10)  # fmt: skip
    for ax in axes:
        ax.set_xlabel("payload [kg]")
        ax.set_xlim(table.payload_edges[0] - 10, table.payload_edges[-1] + 10)
        ax.set_ylim(table.coulomb_edges[0] - 5, table.coulomb_edges[-1] + 5)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("smallest Coulomb friction of a leg [N]")
    f = table.floors
    fig.suptitle(
        f"{table.scenario}: {fraction_text(table)} meet overshoot <= {f.overshoot_pct:g} %, "
        f"settling <= {f.settling_s:g} s, no limit cycle",
        fontsize=11,
    )
    return fig
