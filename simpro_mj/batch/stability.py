"""A variant's stability: measured from its time series, and analysed.

Stability criterion (measured)
------------------------------
From ``timeseries.csv``: per task axis the error ``reference - true pose``
in units of the settling floor (0.02 deg, 0.2 mm: the noise level of the
loop, :data:`simpro_mj.analysis.metrics.SETTLING_FLOOR`), and its peak in blocks of
0.5 s from 1 s after the reference last moves (the last half of the run if
it moves until less than 1.5 s before the end).

* ``growth_rate_1_s``: the envelope's growth rate, the largest over the axes
  of the least-squares slope of ln(peak) against time over the blocks above
  the noise (peak > 3 floors; at least 3 such blocks and one above 10
  floors; ``None`` if no axis has them: the run settled at noise level).
  Negative: decaying. It compares with ``analytic_growth_rate_1_s``.
* A run is **unstable** (``stable = False``) if it diverged, or the growth
  rate exceeds 0.1 1/s (the envelope grows by > 10 %/s), or on an axis whose
  envelope does not decay faster than 0.1 1/s the error's largest deviation
  from a straight line fitted over the last half of the run (an offset or a
  slow drift is not an oscillation) exceeds both 10 floors and half the
  largest reference excursion: an oscillation that saturation or the end
  stops keep from growing further, or one on the limit.

Stability limit (sweeps of ``controller.outer.gains``)
------------------------------------------------------
For every combination of the other grid values, over the variants with a
common gain g = K K_I on the three axes: the simulated limit lies between
the largest stable and the smallest unstable g; its estimate is where the
measured growth rate crosses zero (linear interpolation between those two
variants; the midpoint if their rates do not bracket zero). The analytic
limit is :func:`simpro_mj.analysis.stability.outer_loop` (the analysis the
preflight runs, on the plant assumption ``"paper"``): the variant's outer
type, period, ``pi_zero``, inner variant and discretisation on the paper's
plants under ``paper_units`` with the IK Jacobian at home (``analytic_limit``; ``None``
if the joint loops are designed on the identified plants or the mode is
joint-only), and ``analytic_limit_delay_model`` the one-sample-delay model
of eq. (21). The analysis is linear: it describes ``actuator.model:
linear``; the table notes when the plant is the nonlinear one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from simpro_mj.analysis.metrics import SETTLING_FLOOR
from simpro_mj.analysis.stability import outer_loop
from simpro_mj.config.models import Scenario, as_scenario
from simpro_mj.report.results import read_timeseries

#: Stability criterion (module docstring).
BLOCK_S = 0.5
GROWTH_LIMIT_1_S = 0.1
AMPLITUDE_FLOORS = 10.0
NOISE_FLOORS = 3.0
SETTLE_AFTER_S = 1.0
HELD_FRACTION = 0.5

_TS_COLUMNS = {
    a: (f"{a}_ref_{u}", f"{a}_{u}") for a, u in dict(roll="rad", pitch="rad", heave="m").items()
}


@dataclass
class Stability:
    """Measured stability of a run (criterion: module docstring).

    ``growth_rate_1_s`` the error envelope's growth (None: settled at noise level),
    ``oscillation_floors`` and ``reference_floors`` the largest detrended error and
    reference excursion, in settling floors, ``why`` None or the reason it is unstable.
    """

    stable: bool = True
    growth_rate_1_s: float | None = None
    oscillation_floors: float | None = None
    reference_floors: float | None = None
    why: str | None = None


def stability_of(columns: Mapping, status: str | None = "ok") -> Stability:
    """Measured stability of a run from its time series (criterion: module docstring)."""

    out = Stability()
    if status == "diverged":
        out.stable, out.why = False, "diverged"
    t = np.asarray(columns.get("time_s", []), dtype=float)
    if t.size < 2:
        return out
    ok = np.isfinite(t)
    errs, refs = {}, 0.0
    for axis, (ref_name, true_name) in _TS_COLUMNS.items():
        floor = SETTLING_FLOOR[axis]
        ref = np.asarray(columns[ref_name], dtype=float)
        errs[axis] = (ref - np.asarray(columns[true_name], dtype=float)) / floor
        ok &= np.isfinite(errs[axis])
        fin = ref[np.isfinite(ref)]
        if fin.size:
            refs = max(refs, float(np.max(np.abs(fin - fin[0]))) / floor)
    n = t.size if ok.all() else int(np.argmin(ok))  # a diverged run: its finite part
    t = t[:n]
    out.reference_floors = refs
    if n < 2:
        return out
    start = _settled_from(columns, t)
    edges = np.arange(start, t[-1] + 1e-9, BLOCK_S)
    late = t >= t[0] + 0.5 * (t[-1] - t[0])
    rates, osc, held = [], [], []
    for err in errs.values():
        e = err[:n]
        peaks, centres = [], []
        for a in edges[:-1]:
            sel = (t >= a) & (t < a + BLOCK_S)
            if sel.any():
                peaks.append(float(np.abs(e[sel]).max()))
                centres.append(a + 0.5 * BLOCK_S)
        # the envelope above the noise: blocks of more than NOISE_FLOORS
        loud = np.asarray(peaks) > NOISE_FLOORS
        rate = None
        if loud.sum() >= 3 and max(peaks) > AMPLITUDE_FLOORS:
            x, y = np.asarray(centres)[loud], np.log(np.asarray(peaks)[loud])
            rate = float(np.polyfit(x, y, 1)[0])
            rates.append(rate)
        # the oscillation about a straight line: an offset or a slow drift is not one
        tl, el = t[late], e[late]
        amp = 0.0
        if tl.size >= 3:
            amp = float(np.abs(el - np.polyval(np.polyfit(tl - tl[0], el, 1), tl - tl[0])).max())
        osc.append(amp)
        if (
            amp > AMPLITUDE_FLOORS
            and amp > HELD_FRACTION * refs
            and (rate is None or rate > -GROWTH_LIMIT_1_S)
        ):
            held.append(amp)
    out.oscillation_floors = max(osc) if osc else None
    out.growth_rate_1_s = max(rates) if rates else None
    if out.why is None:
        if rates and max(rates) > GROWTH_LIMIT_1_S:
            out.stable, out.why = False, f"error envelope grows at {max(rates):.3g} 1/s"
        elif held:
            out.stable = False
            out.why = f"held oscillation of {max(held):.3g} floors (reference {refs:.3g} floors)"
    return out


def _settled_from(columns: Mapping, t) -> float:
    """Start of the envelope fit: 1 s after the reference last moves, else the last half."""

    n = t.size
    moving = np.zeros(max(n - 1, 0), dtype=bool)
    for ref_name, _ in _TS_COLUMNS.values():
        ref = np.asarray(columns[ref_name], dtype=float)[:n]
        moving |= np.abs(np.diff(ref)) > 1e-12
    half = float(t[0] + 0.5 * (t[-1] - t[0]))
    if not moving.any():
        return float(t[0])
    start = float(t[int(np.flatnonzero(moving)[-1]) + 1]) + SETTLE_AFTER_S
    return start if t[-1] - start >= 3 * BLOCK_S else half


def stability_of_folder(folder: Path, status: str | None = "ok") -> Stability:
    """:func:`stability_of` of a result folder's ``timeseries.csv``."""
    return stability_of(read_timeseries(Path(folder) / "timeseries.csv"), status)


class Analytic(NamedTuple):
    """The analysis' view of a variant's outer loop (module docstring): ``limit`` (real
    inner loops), ``limit_delay_model`` and ``growth_rate_1_s`` (ln of the closed loop's
    spectral radius per outer period, at the variant's gains); None when the analysis
    does not apply (joint-only, identified design plants)."""

    limit: float | None = None
    limit_delay_model: float | None = None
    growth_rate_1_s: float | None = None


def analytic(scenario: Scenario | Mapping) -> Analytic:
    """The :class:`Analytic` view of a variant's outer loop."""
    c = (sc := as_scenario(scenario)).controller
    if c.mode != "task_space" or c.inner.design_plant != "paper":
        return Analytic()
    # the joint loops on the plants they were designed for (the paper's)
    info = outer_loop(sc, plant="paper")
    return Analytic(info["limit"], info["delay_model_limit"], info["growth_rate_1_s"])
