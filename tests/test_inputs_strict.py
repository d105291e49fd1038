"""Wrong results never reported ok: an outer loop that cannot move the platform is
refused, a telemetry CSV is read by one strict parser (ragged rows refused with
their line number, a byte-order mark dropped, the 10 Hz limit inclusive)."""

from __future__ import annotations

import resource
import subprocess
import sys

import numpy as np
import pytest

from simpro_mj.analysis.preflight import MIN_GAIN_DURATION, check_gains_move
from simpro_mj.config.telemetry import (
    GAP_TOLERANCE_S,
    MAX_GAP_S,
    TELEMETRY_COLUMNS,
    TelemetryError,
    read_telemetry,
)
from simpro_mj.core.errors import UserInputError

HEADER = ",".join(TELEMETRY_COLUMNS)


def _child_cpu_s() -> float:
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


@pytest.mark.parametrize("gains", ["[0,0,0]", "[3,-0.0,3]", "[3,3,1e-300]"])
def test_an_outer_gain_that_cannot_move_the_platform_is_refused(gains):
    cpu0 = _child_cpu_s()
    r = subprocess.run(
        [sys.executable, "-m", "simpro_mj.commands.main", "run", "step_pitch.yaml",
         "--set", f"controller.outer.gains={gains}", "--no-plots"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 2, r.stderr
    (line,) = r.stderr.splitlines()
    assert line.startswith("error: invalid value at controller.outer.gains[")
    assert "less than 1 % of a step" in line and "Traceback" not in r.stderr
    assert _child_cpu_s() - cpu0 < 2.0  # refused before any identification or step


def test_the_gain_bound_is_one_percent_of_a_step_within_the_run():
    # an integrating loop follows a step as 1 - exp(-K t): 1 % at K t = 0.01005
    assert 1 - np.exp(-MIN_GAIN_DURATION) == pytest.approx(0.01, rel=0.01)
    check_gains_move([3.0, 3.0, 3.0], 20.0)
    check_gains_move([MIN_GAIN_DURATION / 20.0] * 3, 20.0)  # at the bound: allowed
    with pytest.raises(UserInputError, match=r"gains\[1\]: 0 on pitch"):
        check_gains_move([3.0, 0.0, 3.0], 20.0)
    with pytest.raises(UserInputError, match=r"gains\[2\]: nan"):
        check_gains_move([3.0, 3.0, float("nan")], 20.0)


def _rows(n: int, dt: float = 0.01) -> list[str]:
    return [f"{i * dt!r},0.1,0.2,9.81,0.01,0.02,0.03" for i in range(n)]


def test_a_ragged_row_is_refused_with_its_line_number(tmp_path):
    rows = _rows(100)
    rows[10] += ",5"  # a field too many, then one too few: the comma count balances
    rows[11] = rows[11].rsplit(",", 1)[0]
    bad = tmp_path / "ragged.csv"
    bad.write_text(HEADER + "\n" + "\n".join(rows) + "\n")
    with pytest.raises(TelemetryError, match=r"row 12: 8 fields; allowed: 7"):
        read_telemetry(bad)
    # a comment line does not change it: the same parser reads both
    bad.write_text(HEADER + "\n" + "\n".join(rows) + "\n# a comment\n")
    with pytest.raises(TelemetryError, match=r"row 12: 8 fields"):
        read_telemetry(bad)


def test_a_byte_order_mark_is_dropped(tmp_path):
    path = tmp_path / "excel.csv"
    path.write_text(HEADER + "\n" + "\n".join(_rows(50)) + "\n", encoding="utf-8-sig")
    tel = read_telemetry(path)
    assert tel.t[-1] == pytest.approx(0.49) and tel.f[0, 2] == pytest.approx(9.81)


def test_ten_hertz_is_inside_the_gap_limit(tmp_path):
    path = tmp_path / "ten.csv"  # times written as Python prints 0.1 * i: 0.30000000000000004
    path.write_text(HEADER + "\n" + "\n".join(_rows(50, 0.1)) + "\n")
    assert read_telemetry(path).t[-1] == pytest.approx(4.9)
    rows = _rows(50, 0.1)
    rows[20] = rows[20].replace(rows[20].split(",")[0], repr(1.9 + MAX_GAP_S + 2 * GAP_TOLERANCE_S))
    path.write_text(HEADER + "\n" + "\n".join(rows[:21]) + "\n")
    with pytest.raises(TelemetryError, match=r"row 22: gap of 0\.100002 s"):
        read_telemetry(path)
