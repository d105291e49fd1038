"""timeseries.csv's lines formatted on a second thread while the run steps
(:class:`simpro_mj.report.results.RowText`): the file is the one
``numpy.savetxt`` writes of the run's columns, however far the thread got."""

import io

import numpy as np
import pytest

from simpro_mj.config.scenario import load_scenario
from simpro_mj.report import results as results_mod
from simpro_mj.report.results import RowText, write_timeseries
from simpro_mj.report.runner import execute


def savetxt_text(columns) -> str:
    names = list(columns)
    names.insert(0, names.pop(names.index("time_s")))
    buf = io.StringIO()
    data = np.column_stack([columns[n] for n in names])
    np.savetxt(buf, data, fmt="%.12g", delimiter=",", header=",".join(names), comments="")
    return buf.getvalue()


def test_run_writes_savetxt_bytes_from_the_thread(tmp_path, monkeypatch):
    """A compiled run of 2.5 s logging every 10th step hands over its rows at
    steps 0, 1000 and 2000: the thread formats the 200 rows logged before step
    2000, the writer the other 51, and the file is numpy's to the byte."""
    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    monkeypatch.setattr(RowText, "if_useful", classmethod(lambda cls: cls()))
    taken = []
    lines_for = RowText.lines_for

    def spy(self, data):
        out = lines_for(self, data)
        taken.append((len(out), data.shape[0]))
        return out

    monkeypatch.setattr(RowText, "lines_for", spy)
    sc = load_scenario("step_pitch.yaml", ["duration_s=2.5", "logging.decimation=10"])
    res, _ = execute(sc, tmp_path / "run", plots=False, quiet=True, csv_beside=True)
    assert taken == [(200, 251)]
    assert (tmp_path / "run" / "timeseries.csv").read_text() == savetxt_text(res.columns)


def test_only_when_asked(tmp_path, monkeypatch):
    """A batch's runs (``csv_beside`` False, the default) start no formatting thread."""
    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    made = []
    monkeypatch.setattr(RowText, "if_useful", classmethod(lambda cls: made.append(1) or cls()))
    sc = load_scenario("step_pitch.yaml", ["duration_s=0.3"])
    execute(sc, tmp_path / "run", plots=False, quiet=True)
    assert made == []


def test_lines_stop_at_the_first_row_that_differs(tmp_path):
    """Rows changed after they were handed over are formatted again, from the
    first changed one: the file always shows the columns given."""
    rng = np.random.default_rng(7)
    log = rng.standard_normal((40, 3)) * [1e-3, 1.0, 6e5]
    rows = RowText()
    assert rows.pace(0, log[:30]) == RowText.EVERY
    columns = {"time_s": log[:, 0].copy(), "a_m": log[:, 1].copy(), "p_pa": log[:, 2].copy()}
    columns["a_m"][12] = np.nextafter(columns["a_m"][12], 2.0)  # one bit
    path = write_timeseries(tmp_path / "t.csv", columns, rows)
    assert len(rows.lines_for(np.column_stack(list(columns.values())))) == 12
    assert path.read_text() == savetxt_text(columns)


def test_no_rows_handed_over_starts_no_thread(tmp_path):
    rows = RowText()
    columns = {"time_s": np.arange(5.0), "x_m": np.linspace(0, 1, 5)}
    write_timeseries(tmp_path / "t.csv", columns, rows)
    assert rows._thread is None
    assert (tmp_path / "t.csv").read_text() == savetxt_text(columns)


@pytest.mark.parametrize("cores", [1, 2])
def test_thread_only_with_a_second_core(monkeypatch, cores):
    monkeypatch.setattr(results_mod.os, "sched_getaffinity", lambda pid: set(range(cores)))
    assert (RowText.if_useful() is not None) == (cores >= 2)
