"""What a motion rig's controller reads: FlyPT Mover / SimTools-style output strings.

A rig's controller (an Arduino, a drive's serial interface) expects each
period one *string*: a header, the axes as unsigned counts, a terminator.
``simpro-sim live --output DEST --output-string TEMPLATE`` writes one such
string per ``1/--output-rate`` s, of the set-points the session commands,
to a UDP address or a serial port.

Template
--------
Literal text with tokens, as SimTools' "Output - Startup/Interface string"
and FlyPT Mover's output strings are written:

==========  ===================================================  ==================
token       value                                                 range mapped
==========  ===================================================  ==================
``<q1>``    leg 1 set-point: slide position from the bottom of     0 .. stroke (0.5 m)
``<q2>``    the stroke (``q1_ref_m``..), what the joint loops
``<q3>``    follow
``<roll>``  the set-point pose's roll, pitch (rad)                 +-:data:`TILT_RANGE_RAD`
``<pitch>``
``<heave>`` its heave from the home height (m)                     +-:data:`HEAVE_RANGE_M`
==========  ===================================================  ==================

A value ``v`` in ``[lo, hi]`` is sent as the count
``round((v - lo) / (hi - lo) * (2^bits - 1))``, clipped to ``0 .. 2^bits - 1``
(``bits`` 8 or 16). Binary (the default): 8-bit counts as one byte, 16-bit as
two bytes, most significant first (as SimTools' binary output sends them
and Arduino sketches read them); ``--output-text``: the count as decimal
digits. Escapes in the literal text: ``\\n \\r \\t \\\\`` and ``\\xHH`` (one byte),
so a binary header such as ``\\xff\\xff`` can be written. Example, three
16-bit legs between a header and a terminator::

    --output-string 'XL<q1><q2><q3>\\r\\n'        # 'X' 'L' 6 bytes CR LF: 10 bytes

Destinations: ``udp:HOST:PORT``, or ``serial:DEVICE[@BAUD]`` (default 115200
baud; needs pyserial, ``pip install pyserial``; pyserial's URLs such as
``loop://`` are accepted). A write that fails is counted, never fatal; a serial
write waits at most :data:`SERIAL_WRITE_TIMEOUT_S` for room in the port's buffer.
"""

from __future__ import annotations

import math
import re
import socket

from simpro_mj.core.errors import UserInputError

#: Range of the roll and pitch tokens (rad): +-30 deg, beyond the platform's reach.
TILT_RANGE_RAD = math.radians(30.0)
#: Range of the heave token (m) about home: +-0.25 m, the half stroke.
HEAVE_RANGE_M = 0.25
TOKENS = ("q1", "q2", "q3", "roll", "pitch", "heave")
#: Longest a serial write may wait for room in the port's buffer (s); then it counts as failed.
SERIAL_WRITE_TIMEOUT_S = 0.002
#: Longest string written a period (bytes).
MAX_STRING_BYTES = 1024
_PIECE = re.compile(r"<([A-Za-z0-9_]*)>|\\x([0-9A-Fa-f]{2})|\\(.)|(.)", re.S)
_ESCAPES = {"n": b"\n", "r": b"\r", "t": b"\t", "\\": b"\\", "<": b"<", ">": b">"}


class RigTemplate:
    """A parsed output string: literal bytes and tokens; :meth:`encode` fills them.

    Parameters
    ----------
    text : str
        The template (module docstring).
    bits : {8, 16}
    text_counts : bool
        Counts as decimal digits instead of binary.
    stroke : float
        The legs' stroke (m): the range of ``<q1>``..``<q3>``.
    """

    def __init__(self, text: str, bits: int = 16, text_counts: bool = False, stroke: float = 0.5):
        if bits not in (8, 16):
            raise UserInputError(f"invalid value at --output-bits: {bits}; allowed: 8 or 16")
        self.bits, self.text_counts, self.full = bits, bool(text_counts), (1 << bits) - 1
        tilt, heave = (-TILT_RANGE_RAD, TILT_RANGE_RAD), (-HEAVE_RANGE_M, HEAVE_RANGE_M)
        self.ranges = dict(zip(TOKENS, [(0.0, stroke)] * 3 + [tilt, tilt, heave], strict=True))
        if not text.isascii():
            raise self._refuse(text, "not ASCII")
        self.pieces: list = []  # bytes, or a token name
        for m in _PIECE.finditer(text):
            token, hexa, esc, char = m.groups()
            if token is not None:
                if token not in TOKENS:
                    raise self._refuse(text, f"unknown token <{token}>")
                self.pieces.append(token)
            elif hexa is not None:
                self._literal(bytes([int(hexa, 16)]))
            elif esc is not None:
                if esc not in _ESCAPES:
                    raise self._refuse(text, f"unknown escape \\{esc}")
                self._literal(_ESCAPES[esc])
            else:
                if char in "<>":
                    raise self._refuse(text, f"a lone {char!r} (write \\{char})")
                self._literal(char.encode("ascii"))
        if not any(isinstance(p, str) for p in self.pieces):
            raise self._refuse(text, "no token")
        width = len(str(self.full)) if text_counts else bits // 8
        size = sum(len(p) if isinstance(p, bytes) else width for p in self.pieces)
        if size > MAX_STRING_BYTES:
            raise self._refuse(text, f"{size} bytes a string")

    def _literal(self, b: bytes) -> None:
        if self.pieces and isinstance(self.pieces[-1], bytes):
            self.pieces[-1] += b
        else:
            self.pieces.append(b)

    @staticmethod
    def _refuse(text: str, why: str) -> UserInputError:
        return UserInputError(
            f"invalid value at --output-string: {text[:60]!r}: {why}; allowed: ASCII text "
            f"with the tokens {' '.join(f'<{t}>' for t in TOKENS)} and the escapes \\n \\r "
            f"\\t \\\\ \\< \\> \\xHH, at most {MAX_STRING_BYTES} bytes a string"
        )

    def count(self, token: str, value: float) -> int:
        """The count of ``value`` on ``token``'s range (module docstring)."""
        lo, hi = self.ranges[token]
        if not math.isfinite(value):
            value = 0.5 * (lo + hi)
        c = round((value - lo) / (hi - lo) * self.full)
        return min(self.full, max(0, c))

    def encode(self, values: dict) -> bytes:
        """The string for ``values`` (token -> SI value)."""
        out = []
        for p in self.pieces:
            if isinstance(p, str):  # a token: its count
                c = self.count(p, values[p])
                p = str(c).encode() if self.text_counts else c.to_bytes(self.bits // 8, "big")
            out.append(p)
        return b"".join(out)


def open_destination(text: str, check_only: bool = False):
    """``udp:HOST:PORT`` or ``serial:DEVICE[@BAUD]`` as a ``write(bytes)`` callable and a
    ``close()``; one line naming ``--output`` when it cannot be opened. ``check_only``:
    the text checked (host resolved, pyserial present), nothing opened."""
    kind, sep, rest = str(text).partition(":")
    allowed = "allowed: udp:HOST:PORT or serial:DEVICE[@BAUD] (e.g. serial:/dev/ttyACM0@115200)"
    if kind == "udp" and sep:
        from simpro_mj.sim.udp import parse_address, resolve_address

        family, addr = resolve_address(parse_address(rest, "--output"), "--output")
        if check_only:
            return None
        sock = socket.socket(family, socket.SOCK_DGRAM)
        sock.setblocking(False)
        return (lambda data: sock.sendto(data, addr)), sock.close
    if kind == "serial" and sep and rest:
        device, _, baud = rest.partition("@")
        try:
            rate = int(baud) if baud else 115200
        except ValueError:
            rate = -1
        if rate <= 0:
            raise UserInputError(f"invalid value at --output: {text!r}: baud {baud!r}; {allowed}")
        try:
            import serial  # type: ignore[import-untyped]  # pyserial, optional
        except ImportError:
            raise UserInputError(
                f"invalid value at --output: {text!r}: a serial port needs pyserial, which is "
                "not installed; allowed: pip install pyserial, or udp:HOST:PORT"
            ) from None
        if check_only:
            return None
        try:
            port = serial.serial_for_url(
                device, baudrate=rate, timeout=0, write_timeout=SERIAL_WRITE_TIMEOUT_S
            )
        except (serial.SerialException, ValueError, OSError) as exc:
            raise UserInputError(
                f"invalid value at --output: {text!r}: cannot open the port ({exc}); {allowed}"
            ) from None
        return port.write, port.close
    raise UserInputError(f"invalid value at --output: {text!r}; {allowed}")


class RigOutput:
    """One string of :class:`RigTemplate` per output period, of a logged row's set-points.

    ``sent`` and ``errors`` count the writes (a failed write is counted, never fatal)."""

    def __init__(self, destination: str, template: RigTemplate, home_heave_m: float):
        self.template, self.home = template, float(home_heave_m)
        self.destination = destination
        self._write, self._close = open_destination(destination)
        self.sent = self.errors = 0
        self._col: dict[str, int] | None = None

    def values(self, row) -> dict:
        from simpro_mj.sim.udp import pose_columns  # on use: it loads MuJoCo

        c = self._col = self._col or pose_columns()
        refs = ("q1_ref_m", "q2_ref_m", "q3_ref_m", "roll_ref_rad", "pitch_ref_rad")
        values = {t: row[c[name]] for t, name in zip(TOKENS, refs, strict=False)}
        return values | {"heave": row[c["heave_ref_m"]] - self.home}

    def send(self, row) -> None:
        from simpro_mj.core.interrupts import held_signals

        data = self.template.encode(self.values(row))
        with held_signals():
            try:
                self._write(data)
                self.sent += 1
            except (OSError, ValueError):  # pyserial's errors are OSError or ValueError
                self.errors += 1

    def close(self) -> None:
        self._close()
