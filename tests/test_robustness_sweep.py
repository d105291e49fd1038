"""The robustness sweep over payload and seal friction: its floors, table and map
(simpro_mj/batch/robustness.py, scenarios/sweep_robustness.yaml)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from simpro_mj.batch.robustness import (
    COULOMB,
    PAYLOAD,
    map_figure,
    meets_floors,
    robustness_table,
    table_lines,
)
from simpro_mj.batch.summary import AxisRow, Row
from simpro_mj.config.variants import load_sweep
from simpro_mj.report.figures import legend_mismatches


def _row(status="ok", over=5.0, settle=2.0, payload=250.0, coulomb=(100.0, 120.0, 140.0)):
    return Row(
        variant="v",
        scenario="rob",
        status=status,
        values={PAYLOAD: payload, COULOMB: list(coulomb)},
        pitch=AxisRow(overshoot_pct=over, settling_s=settle),
    )


def test_floors_are_overshoot_15_settling_4_and_a_settled_run():
    assert meets_floors(_row(over=15.0, settle=4.0))
    assert not meets_floors(_row(over=15.1))
    assert not meets_floors(_row(settle=4.2))
    assert not meets_floors(_row(settle=None))  # never settled
    assert not meets_floors(_row(status="limit_cycle"))
    assert not meets_floors(_row(status="not_settled"))


def test_table_counts_the_floors_per_payload_and_friction_cell():
    rows = [
        _row(payload=150.0, coulomb=(100.0, 120.0, 140.0)),  # 100-200 kg x 100-150 N: met
        _row(payload=160.0, coulomb=(110.0, 120.0, 130.0), status="limit_cycle"),  # same cell
        _row(payload=20.0, coulomb=(240.0, 230.0, 250.0), over=30.0),  # 0-100 x 200-250
        replace(_row(), scenario="other"),  # another file's variant
    ]
    t = robustness_table(rows, "rob")
    assert (t.n, t.met) == (3, 1) and abs(t.fraction - 1 / 3) < 1e-12
    assert t.statuses == {"ok": 2, "limit_cycle": 1}
    cells = {(tuple(c.payload_kg), tuple(c.coulomb_n)): c for c in t.cells}
    assert (
        cells[(100.0, 200.0), (100.0, 150.0)].n,
        cells[(100.0, 200.0), (100.0, 150.0)].met,
    ) == (2, 1)
    assert cells[(0.0, 100.0), (200.0, 250.0)].fraction == 0.0
    assert sum(c.n for c in t.cells) == 3
    text = "\n".join(table_lines(t))
    assert "1 of 3 finished variants (33.3 %)" in text and "limit_cycle 1" in text
    assert "not finished" not in text and t.unfinished == 0
    assert robustness_table([replace(_row(), values={})], "rob") is None


def test_the_table_and_map_extend_to_the_catalogue_seals():
    """Seals up to 450 N running (the catalogue's top) and payloads past 400 kg get
    cells of the same width, and the map's axes hold every point."""
    rows = [_row(payload=p, coulomb=[c] * 3) for p in (0.0, 450.0) for c in (75.0, 450.0)]
    t = robustness_table(rows, "rob")
    assert t.coulomb_edges[-1] == 450.0 and t.coulomb_edges[-2] == 400.0
    assert t.payload_edges[-1] == 500.0
    assert sum(c.n for c in t.cells) == 4
    assert {tuple(c.coulomb_n) for c in t.cells if c.n} == {(50.0, 100.0), (400.0, 450.0)}
    fig = map_figure(rows, t)
    lo, hi = fig.axes[0].get_ylim()
    assert lo < 75.0 and hi > 450.0
    assert "400-450" in "\n".join(table_lines(t))


def test_map_draws_every_variant_with_a_true_legend():
    rng = np.random.default_rng(0)
    rows = [
        _row(status=s, over=o, settle=st, payload=p, coulomb=[c] * 3)
        for s, o, st, p, c in zip(
            rng.choice(["ok", "ok", "limit_cycle", "not_settled"], 40), rng.uniform(0, 40, 40),
            rng.uniform(1, 6, 40), rng.uniform(0, 400, 40), rng.uniform(0, 250, 40), strict=True,
        )
    ]  # fmt: skip
    fig = map_figure(rows, robustness_table(rows, "rob"))
    assert legend_mismatches(fig) == []
    assert len([a for a in fig.axes if a.get_xlabel() == "payload [kg]"]) == 3
    drawn = sum(len(c.get_offsets()) for c in fig.axes[0].collections)
    assert drawn == 40


def test_the_shipped_sweep_spans_the_cabins_range():
    sf = load_sweep("sweep_robustness")
    good = [v.scenario for v in sf.variants if v.scenario is not None]
    assert len(good) == len(sf.variants) >= 200
    pay = np.array([s["plant"]["payload"]["mass_kg"] for s in good])
    cou = np.array([s["actuator"]["pneumatics"]["cylinder"]["coulomb_friction_n"] for s in good])
    bias = np.array([s["sensors"]["imu"]["bias_deg"] for s in good])
    sup = np.array([s["actuator"]["pneumatics"]["supply_pressure_bar_gauge"] for s in good])
    assert 0 <= pay.min() < 20 and 380 < pay.max() <= 400
    # each seal over the catalogue: 45-450 N running, 75-750 N breakaway
    assert cou.shape[1] == 3 and 45 <= cou.min() < 55 and 440 < cou.max() <= 450
    assert -0.5 <= bias.min() < -0.45 and 0.45 < bias.max() <= 0.5
    assert 5.0 <= sup.min() < 5.1 and 6.9 < sup.max() <= 7.0
    assert {s["plant"]["preset"] for s in good} == {"heavy_cabin"}
    # one controller for every drawn plant: the cabin's, on the preset's identified models
    assert {s["controller"]["inner"]["design_plant"] for s in good} == {"identified"}
    assert {s["controller"]["inner"]["identify"] for s in good} == {"preset"}


def test_a_stopped_batch_counts_finished_variants_only_and_names_the_rest():
    # 3 finished (1 meets the floors), 2 not run and 1 stopped while it ran: the
    # fraction is 1 of 3, not 1 of 6, and the unfinished are neither met nor failed
    rows = [
        _row(payload=150.0, coulomb=(100.0, 120.0, 140.0)),
        _row(payload=160.0, coulomb=(110.0, 120.0, 130.0), status="limit_cycle"),
        _row(payload=20.0, coulomb=(240.0, 230.0, 250.0), over=30.0),
        _row(payload=170.0, coulomb=(110.0, 120.0, 130.0), status="cancelled", over=None),
        _row(payload=30.0, coulomb=(10.0, 20.0, 30.0), status="cancelled", over=None),
        _row(payload=180.0, coulomb=(110.0, 120.0, 130.0), status="interrupted"),
    ]
    t = robustness_table(rows, "rob")
    assert (t.n, t.met, t.unfinished) == (3, 1, 3)
    assert abs(t.fraction - 1 / 3) < 1e-12
    assert t.statuses == {"ok": 2, "limit_cycle": 1}
    assert sum(c.n for c in t.cells) == 3
    cell = next(c for c in t.cells if c.payload_kg == [100.0, 200.0] and c.coulomb_n[0] == 100.0)
    assert (cell.met, cell.n) == (1, 2)  # the cancelled and interrupted ones left out
    text = "\n".join(table_lines(t))
    assert "1 of 3 finished variants (33.3 %)" in text and "3 not finished" in text
    # nothing finished: no fraction, no division by zero
    t0 = robustness_table([_row(status="cancelled")], "rob")
    assert (t0.n, t0.fraction, t0.unfinished) == (0, None, 1)
    assert "0 of 0 finished variants (-)" in "\n".join(table_lines(t0))
