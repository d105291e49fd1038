"""timeseries.csv as text: the bytes ``numpy.savetxt`` writes of the run's columns
(``%.12g`` of every value), formatted many rows to one ``%``
(:func:`simpro_mj.report.results.write_timeseries`)."""

import io

import numpy as np
import pytest

from simpro_mj.report.results import NUMBER_FORMAT, ROWS_PER_FORMAT, write_timeseries


def savetxt_text(columns) -> str:
    names = list(columns)
    names.insert(0, names.pop(names.index("time_s")))
    buf = io.StringIO()
    data = np.column_stack([columns[n] for n in names])
    np.savetxt(buf, data, fmt=NUMBER_FORMAT, delimiter=",", header=",".join(names), comments="")
    return buf.getvalue()


@pytest.mark.parametrize("rows", [1, ROWS_PER_FORMAT - 1, ROWS_PER_FORMAT, 2 * ROWS_PER_FORMAT + 3])
def test_the_file_is_savetxts_to_the_byte(tmp_path, rows):
    """Whatever the number of rows against the block: every value written as
    ``savetxt`` writes it, the signed zero, NaN, infinities, subnormals, the
    largest and smallest doubles and 12-digit ties among them."""
    rng = np.random.default_rng(3)
    odd = [0.0, -0.0, np.nan, np.inf, -np.inf, 5e-324, 2.2250738585072014e-308,
           1.7976931348623157e308, 0.1234567890125, 1234567890123.5, 1e-5, 123456789012.0,
           -2.5e-13, 1.0 / 3.0]  # fmt: skip
    columns = {"x_m": rng.standard_normal(rows) * 1e-3, "p_pa": rng.uniform(1e5, 7e5, rows)}
    columns["odd"] = np.resize(np.array(odd), rows)
    columns["time_s"] = np.arange(rows) * 1e-3
    path = write_timeseries(tmp_path / "t.csv", columns)
    assert path.read_text() == savetxt_text(columns)


def test_no_rows_is_the_header_alone(tmp_path):
    columns = {"time_s": np.zeros(0), "x_m": np.zeros(0)}
    assert write_timeseries(tmp_path / "t.csv", columns).read_text() == "time_s,x_m\n"


def test_a_run_writes_its_columns_as_savetxt_does(tmp_path, monkeypatch):
    """A compiled run of 2.5 s logging every 10th step: the file is numpy's to the byte."""
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.report.runner import execute

    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    sc = load_scenario("step_pitch.yaml", ["duration_s=2.5", "logging.decimation=10"])
    res, _ = execute(sc, tmp_path / "run", plots=False, quiet=True)
    assert (tmp_path / "run" / "timeseries.csv").read_text() == savetxt_text(res.columns)
    assert len(res.columns["time_s"]) == 251
