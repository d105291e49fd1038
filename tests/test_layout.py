"""The step's memory by name: one declared layout per block, its offsets and packing."""

from __future__ import annotations

import re

import numpy as np
import pytest

from controllers import step_functions as cs
from controllers.layout import layout
from simpro_mj.sim import step


def test_offsets_follow_the_sizes_in_order():
    L = layout("Block", p=6, spool=3, ps=1, tab=None)
    assert (L.p, L.spool, L.ps, L.tab, L.LEN) == (0, 6, 9, 10, 10)
    wider = layout("Block", p=6, temp=6, spool=3, ps=1, tab=None)  # a field added
    assert (wider.spool, wider.ps, wider.tab, wider.LEN) == (12, 15, 16, 16)


def test_pack_places_every_field_and_views_give_them_back():
    L = layout("Block", p=2, s=1, m=4, tab=None)
    a = L.pack(p=[1.0, 2.0], s=3.0, m=np.arange(4.0).reshape(2, 2), tab=[7.0, 8.0, 9.0])
    assert a.tolist() == [1.0, 2.0, 3.0, 0.0, 1.0, 2.0, 3.0, 7.0, 8.0, 9.0]
    v = L.views(a)
    v.s[0] = -1.0  # a view, not a copy
    assert a[L.s] == -1.0 and v.tab.tolist() == [7.0, 8.0, 9.0]


@pytest.mark.parametrize(
    "values, word",
    [
        (dict(p=[1.0, 2.0]), "missing ['s']"),
        (dict(p=[1.0, 2.0], s=1.0, q=0.0), "unknown fields ['q']"),
        (dict(p=[1.0, 2.0, 3.0], s=1.0), "Block.p: 3 values, expected 2"),
    ],
)
def test_pack_names_the_wrong_field(values, word):
    with pytest.raises(ValueError, match=word.replace("[", r"\[").replace("]", r"\]")):
        layout("Block", p=2, s=1).pack(**values)


def test_declaration_errors_name_the_field():
    with pytest.raises(ValueError, match="only the last field may be open"):
        layout("Block", tab=None, p=2)
    with pytest.raises(ValueError, match=r"Block.p: size 0"):
        layout("Block", p=0)
    with pytest.raises(ValueError, match="reserved"):
        layout("Block", LEN=1)


def test_compiled_reads_a_layout_offset_as_a_constant():
    """numba folds ``L.spool + i`` into the load: the IR indexes by the literal byte offset."""
    numba = pytest.importorskip("numba")
    L = layout("Block", p=6, spool=3)

    def read(a, i):
        return a[L.spool + 2] + a[L.p + i]

    fn = numba.njit(read)
    a = np.arange(9.0)
    assert fn(a, 1) == read(a, 1) == 9.0
    ir = fn.inspect_llvm(fn.signatures[0])
    assert re.search(r"getelementptr [^\n]*, i64 64\n", ir)  # a[8]: a fixed byte offset


def test_the_controllers_blocks_pack_to_their_lengths():
    """Each controller's packed block has its layout's length, fields where declared."""
    from controllers.geometry import nominal_geometry

    geom = nominal_geometry()
    g = cs.geometry_constants(geom)
    assert g.size == cs.GEOM.LEN and g[cs.GEOM.stroke] == geom.stroke
    assert g[cs.GEOM.base + 3] == geom.base_points[1][0]  # A_2's x
    assert step.ST.ts - step.ST.ss == step.ps.SS.LEN and step.ST.jx - step.ST.ts == cs.TS.LEN


def test_the_plants_blocks_pack_by_name_where_the_step_reads():
    """Each leg's seal friction, a chamber and the supply sit where the step reads them."""
    from simpro_mj.plant import step_functions as ps
    from simpro_mj.plant.pneumatics.nonlinear import NonlinearActuators
    from simpro_mj.plant.sensors import DEFAULT_SENSORS, SensorConfig

    act = NonlinearActuators()
    P, ac = act.params, act.step_constants
    n = int(ac[ps.AC.ntab])
    assert ac.size == ps.AC.LEN + 3 * n and ac[ps.AC.kind] == 0.0
    leg2 = ps.AC.fric + ps.FRIC.LEN
    assert ac[leg2 + ps.FRIC.coulomb] == P.coulomb[1]
    assert ac[leg2 + ps.FRIC.breakaway] == P.breakaway[1]
    rod1 = ps.AC.ch + 3 * ps.CH.LEN  # chamber 3: leg 1's rod side
    assert ac[rod1 + ps.CH.dvdq] == -P.area_rod_side
    assert ac[ps.AC.sup + ps.SUP.pset] == P.p_supply
    assert act.step_state.size == ps.ACT.LEN and act.step_state[ps.ACT.ps] == P.p_supply
    sc = SensorConfig.from_tree(DEFAULT_SENSORS, 1e-3).step_constants
    assert sc.size == ps.SC.LEN and sc[ps.SC.idt2] == pytest.approx(1e6)
    # the step's own blocks hold the plant's at their lengths
    assert step.ST.ring - step.ST.ast == ps.ACT.LEN and step.CT.tc - step.CT.sc == ps.SC.LEN
    from simpro_mj.sim.result import COLUMNS

    assert step.ROW.LEN == len(COLUMNS)  # the log row's fields, one column each
