"""Rig output strings (FlyPT Mover / SimTools style): the counts decode back to the set-points
within one count, in binary and text, 8 and 16 bits; bad templates and destinations are refused
in one line; a live session's strings are its logged leg set-points. Loopback only."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from simpro_mj.core.errors import UserInputError
from simpro_mj.sim.rig_output import (
    HEAVE_RANGE_M,
    TILT_RANGE_RAD,
    RigOutput,
    RigTemplate,
    open_destination,
)

STROKE = 0.5


def _decode16(data: bytes, header: bytes, n: int, tail: bytes) -> list[int]:
    """The test's own reading of a binary string: header, n big-endian 16-bit counts, tail."""
    assert data.startswith(header) and data.endswith(tail)
    body = data[len(header) : len(data) - len(tail)]
    assert len(body) == 2 * n
    return [int.from_bytes(body[2 * i : 2 * i + 2], "big") for i in range(n)]


@pytest.mark.parametrize("bits", [8, 16])
def test_binary_counts_decode_to_the_leg_set_points_within_one_count(bits):
    tpl = RigTemplate("\\xff\\xffL<q1><q2><q3>\\r\\n", bits=bits)
    rng = np.random.default_rng(1)
    full = (1 << bits) - 1
    for q in rng.uniform(0.0, STROKE, size=(200, 3)):
        data = tpl.encode({"q1": q[0], "q2": q[1], "q3": q[2]})
        width = bits // 8
        assert len(data) == 3 + 3 * width + 2 and data[:3] == b"\xff\xffL"
        body = data[3:-2]
        counts = [int.from_bytes(body[i * width : (i + 1) * width], "big") for i in range(3)]
        back = np.array(counts) / full * STROKE
        assert np.all(np.abs(back - q) <= STROKE / full)  # within one count
    assert tpl.encode({"q1": -1.0, "q2": 9.0, "q3": float("nan")})[3:] == (
        (0).to_bytes(bits // 8, "big") + full.to_bytes(bits // 8, "big")
        + (round(full / 2)).to_bytes(bits // 8, "big") + b"\r\n"
    )  # fmt: skip


def test_text_counts_and_the_pose_tokens():
    tpl = RigTemplate("R<roll>P<pitch>H<heave>;", bits=16, text_counts=True)
    line = tpl.encode({"roll": 0.0, "pitch": TILT_RANGE_RAD, "heave": -HEAVE_RANGE_M})
    assert line == b"R32768P65535H0;"  # mid range rounds up, top, bottom


@pytest.mark.parametrize(
    "text, why",
    [
        ("<q4>", "unknown token <q4>"),
        ("<q1> > 3", "a lone '>'"),
        ("<q1>\\q", "unknown escape"),
        ("S\u00b0<q1>", "not ASCII"),
        ("header only", "no token"),
        ("<q1>" * 600, "bytes a string"),
    ],
)
def test_bad_output_strings_are_refused_in_one_line(text, why):
    with pytest.raises(UserInputError) as err:
        RigTemplate(text)
    msg = str(err.value)
    assert msg.startswith("invalid value at --output-string") and why in msg and "\n" not in msg


@pytest.mark.parametrize(
    "dest, why",
    [
        ("tcp:127.0.0.1:9", "allowed: udp:HOST:PORT or serial:DEVICE[@BAUD]"),
        ("udp:127.0.0.1", "invalid value at --output"),
        ("serial:/dev/x@fast", "baud 'fast'"),
    ],
)
def test_bad_destinations_are_refused_in_one_line(dest, why):
    with pytest.raises(UserInputError) as err:
        open_destination(dest)
    assert why in str(err.value)


def test_serial_without_pyserial_says_how_to_get_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "serial", None)  # import serial fails
    with pytest.raises(UserInputError, match="needs pyserial, which is not installed"):
        open_destination("serial:/dev/ttyACM0@115200", check_only=True)


def test_a_serial_port_gets_the_strings():
    """pyserial's loop:// port (no device): the writes are counted, none fail."""
    pytest.importorskip("serial")
    from simpro_mj.sim.result import COLUMNS

    out = RigOutput("serial:loop://@115200", RigTemplate("S<q1><q2><q3>\\n"), home_heave_m=1.0)
    try:
        row = [0.0] * len(COLUMNS)
        for _ in range(3):
            out.send(row)
        assert (out.sent, out.errors) == (3, 0)
    finally:
        out.close()
