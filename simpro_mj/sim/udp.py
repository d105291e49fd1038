"""The network side of a live session: telemetry datagrams in, pose lines out.

:class:`Receiver` reads a game's UDP telemetry (:mod:`simpro_mj.config.datagrams`)
without blocking, holds the newest sample and fades it to the vehicle at rest
when it goes stale; :class:`PoseSender` sends the platform's pose as a text
line of a checked template (:func:`pose_template`); :func:`send_datagrams`
plays a recorded stream as a game would (``simpro-sim send``);
:func:`parse_address` and :func:`resolve_address` check ``HOST:PORT``. The pacing
that joins them to the co-simulation is :mod:`simpro_mj.sim.live`.
"""

from __future__ import annotations

import contextlib
import math
import re
import socket
import string
import time

import numpy as np

from controllers.frames import GRAVITY
from simpro_mj.config.datagrams import AutoDecoder, make_decoder
from simpro_mj.config.games.common import DatagramError
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.interrupts import held_signals

#: Most datagrams read at one chunk boundary (a burst never stalls the loop).
MAX_DRAIN = 256
#: A game's time going back by more than this (s) is a new stream (a restart), not disorder.
RESTART_S = 1.0
#: Receive buffer asked of the kernel (bytes): a second of 1 kB datagrams at 1 kHz.
RCVBUF_BYTES = 1 << 20
#: Largest datagram read whole; anything longer is oversized in both formats.
_RECV_BYTES = 2048

#: The fields a pose line may hold (``--send-format``), degrees and millimetres: each the
#: logged column it shows, its scale, and whether it is measured from the home height.
POSE_FIELDS = {
    "t_s": ("time_s", 1.0, False),
    "roll_deg": ("roll_rad", 180.0 / math.pi, False),
    "pitch_deg": ("pitch_rad", 180.0 / math.pi, False),
    "heave_mm": ("heave_m", 1e3, True),
    "q1_mm": ("q1_ref_m", 1e3, False),
    "q2_mm": ("q2_ref_m", 1e3, False),
    "q3_mm": ("q3_ref_m", 1e3, False),
    "roll_ref_deg": ("roll_ref_rad", 180.0 / math.pi, False),
    "pitch_ref_deg": ("pitch_ref_rad", 180.0 / math.pi, False),
    "heave_ref_mm": ("heave_ref_m", 1e3, True),
}
#: The pose line sent by default: the platform's pose and the leg set-points.
DEFAULT_POSE_FORMAT = (
    "{t_s:.3f},{roll_deg:.4f},{pitch_deg:.4f},{heave_mm:.3f},{q1_mm:.3f},{q2_mm:.3f},{q3_mm:.3f}\n"
)


def pose_columns() -> dict[str, int]:
    """Logged column name -> its index in ``simpro_mj.sim.result.COLUMNS`` (on use: it
    loads MuJoCo)."""
    from simpro_mj.sim.result import COLUMNS

    return {name: j for j, name in enumerate(COLUMNS)}


#: Longest ``--send-format`` template (characters), and the widest field and most digits.
MAX_TEMPLATE_CHARS = 512
MAX_FIELD_WIDTH = 32
MAX_PRECISION = 12
#: What a field's format may be: ``[[fill]align][sign][0][width][,|_][.precision][type]``,
#: types ``f e g`` (and their capitals, ``%``): a number, bounded by the two maxima above.
_SPEC = re.compile(r"^(?:.?[<>=^])?[+\- ]?0?(\d{1,2})?[,_]?(?:\.(\d{1,2}))?[eEfFgG%]?$")


def pose_template(text: str | None) -> str:
    """The pose line template, checked at start: one-line :class:`UserInputError` naming
    ``--send-format`` for anything but the fields :data:`POSE_FIELDS` with a plain number
    format (no attribute or index access, no conversion, no nested field, widths up to
    :data:`MAX_FIELD_WIDTH`, precisions up to :data:`MAX_PRECISION`), ASCII, at most
    :data:`MAX_TEMPLATE_CHARS` characters. A line is then at most a few kB, whatever the
    values: it always fits one datagram and is formatted in microseconds."""
    if text is None:
        return DEFAULT_POSE_FORMAT
    allowed = (
        f"allowed: an ASCII template of at most {MAX_TEMPLATE_CHARS} characters with fields "
        f"{', '.join(POSE_FIELDS)}, each with a number format of width <= {MAX_FIELD_WIDTH} "
        f"and precision <= {MAX_PRECISION}, e.g. 'P{{pitch_deg:.2f}}R{{roll_deg:.2f}}\\n'"
    )

    def refuse(why: str):
        return UserInputError(f"invalid value at --send-format: {text[:60]!r}: {why}; {allowed}")

    if len(text) > MAX_TEMPLATE_CHARS or not text.isascii():
        raise refuse("too long" if len(text) > MAX_TEMPLATE_CHARS else "not ASCII")
    tpl = text.replace("\\n", "\n").replace("\\r", "\r").replace("\\t", "\t")
    try:
        parts = list(string.Formatter().parse(tpl))
    except ValueError as exc:
        raise refuse(str(exc)) from None
    for _, name, spec, conversion in parts:
        if name is None:
            continue
        if name not in POSE_FIELDS:
            if name.split(".")[0].split("[")[0] in POSE_FIELDS:
                raise refuse(f"field {name!r}: attribute or index access")
            raise UserInputError(
                f"invalid value at --send-format: unknown field {name!r}; allowed: "
                f"{', '.join(POSE_FIELDS)}"
            )
        if conversion is not None:
            raise refuse(f"field {name!r}: conversion !{conversion}")
        m = _SPEC.match(spec or "")
        if m is None or "{" in (spec or ""):
            raise refuse(f"field {name!r}: format {spec!r}")
        width, precision = int(m.group(1) or 0), int(m.group(2) or 0)
        if width > MAX_FIELD_WIDTH or precision > MAX_PRECISION:
            raise refuse(f"field {name!r}: width {width}, precision {precision}")
    try:
        tpl.format(**dict.fromkeys(POSE_FIELDS, -1e9))
    except (ValueError, IndexError, KeyError) as exc:
        raise refuse(str(exc)) from None
    return tpl


def parse_address(text: str, option: str, *, bind: bool = False) -> tuple[str, int]:
    """``HOST:PORT`` as (host, port); a one-line :class:`UserInputError` naming ``option``.

    Port 0 is allowed only where the address is bound (``bind``): the system
    picks a free port, which the readiness file names.
    """
    host, sep, port = str(text).rpartition(":")
    low = 0 if bind else 1
    try:
        p = int(port)
    except ValueError:
        p = -1
    if not sep or not host or not low <= p <= 65535:
        raise UserInputError(
            f"invalid value at {option}: {text!r}; allowed: HOST:PORT with a port {low}..65535 "
            "(e.g. 127.0.0.1:4444)"
        )
    return host.strip("[]"), p


def resolve_address(address: tuple[str, int], option: str) -> tuple:
    """The UDP socket address of ``(host, port)``: one line naming ``option`` if the host
    does not resolve."""
    try:
        info = socket.getaddrinfo(address[0], address[1], type=socket.SOCK_DGRAM)
    except (socket.gaierror, UnicodeError, OSError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        raise UserInputError(
            f"invalid value at {option}: {address[0]}:{address[1]}: the host does not "
            f"resolve ({why}); allowed: a host name or address this machine can reach"
        ) from None
    family, _, _, _, sockaddr = info[0]
    return family, sockaddr


def _bound_socket(address: tuple[str, int]) -> socket.socket:
    """A UDP socket bound to ``address``; a one-line error naming ``--listen`` if it cannot be."""
    family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_DGRAM)
    try:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RCVBUF_BYTES)
        sock.bind(address)
    except OSError as exc:
        sock.close()
        raise UserInputError(
            f"cannot listen at --listen {address[0]}:{address[1]}: "
            f"{exc.strerror or exc}; allowed: a local address and a free UDP port"
        ) from None
    return sock


def check_listen(address: tuple[str, int]) -> None:
    """Refuse at once an address that cannot be bound (busy, not local), before the
    seconds a session takes to build; the session binds it again for good."""
    _bound_socket(address).close()


class Receiver:
    """The UDP input: a non-blocking socket, the newest sample, the counts.

    The newest valid sample is held; once it is older than ``stale_after_s``
    it fades linearly, over ``fade_s``, to the vehicle at rest
    (``f = (0, 0, g)``, ``w = 0``), so that the washout brings the platform
    back to neutral when the game pauses or the link drops. Before the first
    sample the input is at rest.

    Attributes
    ----------
    received, bad, idle, late, restarts : int
        Datagrams read; of them, not a sample (``bad_kinds``: short,
        oversized, malformed); well-formed but saying the game is not driving
        (Forza's ``IsRaceOn = 0``: skipped, the input goes stale); older than
        the newest sample (out of order or repeated, skipped); game times that
        jumped back by more than :data:`RESTART_S` (taken as a new stream).
        A format without a game clock (BeamNG's) is ordered by arrival.
    format : str
        The format read: ``fmt``, or for ``auto`` the one the first good
        datagram showed (``on_choose(name)`` is called then).
    """

    REST_F = (0.0, 0.0, GRAVITY)
    REST_W = (0.0, 0.0, 0.0)

    def __init__(self, address: tuple[str, int], fmt: str, stale_after_s: float, fade_s: float,
                 on_choose=None):  # fmt: skip
        self.fmt = fmt
        self.decode = make_decoder(fmt)
        if isinstance(self.decode, AutoDecoder):
            self.decode.on_choose = on_choose
        self.stale_after, self.fade = float(stale_after_s), float(fade_s)
        self.sock = _bound_socket(address)
        self.sock.setblocking(False)
        self.address = self.sock.getsockname()[:2]
        self._buf = bytearray(_RECV_BYTES)
        self.received = self.bad = self.idle = self.late = self.restarts = 0
        self.bad_kinds = {"short": 0, "oversized": 0, "malformed": 0}
        self.last_time: float | None = None  # the game's time of the newest sample
        self.last_wall: float | None = None  # when it arrived
        self.f, self.w = self.REST_F, self.REST_W

    def poll(self, now: float) -> int:
        """Read the datagrams waiting (at most :data:`MAX_DRAIN`); returns how many."""
        recv, buf, decode = self.sock.recv_into, self._buf, self.decode
        n = 0
        for _ in range(MAX_DRAIN):
            try:
                size = recv(buf)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # e.g. an ICMP error surfacing on the socket: not data
                continue
            n += 1
            try:
                if size >= len(buf):  # filled the buffer: cut short by the read
                    raise DatagramError("oversized", f">= {size} bytes")
                t, f, w = decode(bytes(buf[:size]))
            except DatagramError as exc:
                if exc.kind == "idle":
                    self.idle += 1
                else:
                    self.bad += 1
                    self.bad_kinds[exc.kind] += 1
                continue
            if t is None:  # no game clock in the packet: its arrival orders it
                t = now
            if self.last_time is not None and t <= self.last_time:
                if self.last_time - t <= RESTART_S:
                    self.late += 1
                    continue
                self.restarts += 1
            self.last_time, self.last_wall, self.f, self.w = t, now, f, w
        self.received += n
        return n

    def sample(self, now: float) -> tuple[tuple, tuple, bool]:
        """``(f, w, stale)``: the input to use now (held, or faded to rest)."""
        if self.last_wall is None:
            return self.REST_F, self.REST_W, True
        age = now - self.last_wall
        if age <= self.stale_after:
            return self.f, self.w, False
        a = min(1.0, (age - self.stale_after) / self.fade) if self.fade > 0 else 1.0
        f = tuple((1.0 - a) * v + a * r for v, r in zip(self.f, self.REST_F, strict=True))
        w = tuple((1.0 - a) * v for v in self.w)
        return f, w, True

    @property
    def format(self) -> str:
        chosen = getattr(self.decode, "chosen", None)
        return chosen or self.fmt

    def counts(self) -> dict:
        counts = {k: getattr(self, k) for k in ("received", "bad", "late", "idle")}
        return {"format": self.format, **counts, "bad_kinds": dict(self.bad_kinds),
                "restarts": self.restarts}  # fmt: skip

    def close(self) -> None:
        self.sock.close()


class PoseSender:
    """The pose out: one ASCII datagram of :data:`POSE_FIELDS` per send period.

    ``roll_deg``, ``pitch_deg``, ``heave_mm``: the simulated platform's pose
    (base frame, heave from the home height); ``q1_mm``..``q3_mm``: the leg
    set-points the joint loops follow (slide positions from the bottom of the
    stroke, what a real rig's controller takes); ``*_ref_*``: the cueing's
    set-point pose. Send errors are counted, never fatal.
    """

    def __init__(self, address: tuple[str, int], template: str, home_heave_m: float):
        family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.address, self.template, self.home = address, template, float(home_heave_m)
        self.sent = self.errors = 0
        c = pose_columns()
        self._fields = [(name, c[col], scale, self.home if home else 0.0)
                        for name, (col, scale, home) in POSE_FIELDS.items()]  # fmt: skip

    def send(self, row) -> None:
        """Send the pose of one logged row (``simpro_mj.sim.result.COLUMNS`` order)."""
        line = self.template.format(**{n: float(row[j] - z) * s for n, j, s, z in self._fields})
        with held_signals():  # a signal never falls between the send and its count
            try:
                self.sock.sendto(line.encode("ascii"), self.address)
                self.sent += 1
            except OSError:
                self.errors += 1

    def close(self) -> None:
        self.sock.close()


def send_datagrams(grams, times, address: tuple[str, int], *, say=None,
                   clock=time.perf_counter, sleep=time.sleep) -> dict:  # fmt: skip
    """Send ``grams[i]`` at ``start + times[i]`` (absolute deadlines) to ``address``.

    The stand-in for a game (``simpro-sim send``). Returns the figures:
    ``sent``, ``errors`` (refused sends, counted), ``duration_s``,
    ``lateness_us`` {p50, p99, max} of the sends. The host is resolved first;
    a first send that fails other than by a refusal from the other end (a
    broadcast address without permission, no route) ends it at once with a
    one-line :class:`UserInputError` naming ``--to``: nothing could be sent.
    """
    family, sockaddr = resolve_address(address, "--to")
    sock = socket.socket(family, socket.SOCK_DGRAM)
    late = np.zeros(len(grams))
    sent = errors = 0
    start = clock()
    try:
        for i, (g, t) in enumerate(zip(grams, times, strict=True)):
            deadline = start + float(t)
            now = clock()
            if now < deadline:
                sleep(deadline - now)
                now = clock()
            late[i] = max(0.0, now - deadline)
            try:
                sock.sendto(g, sockaddr)
                sent += 1
            except ConnectionRefusedError:  # the other end said no to an earlier one
                errors += 1
            except OSError as exc:
                errors += 1
                if sent == 0:
                    raise UserInputError(
                        f"invalid value at --to: {address[0]}:{address[1]}: nothing could be "
                        f"sent ({exc.strerror or exc}); allowed: a unicast HOST:PORT this "
                        "machine can send to"
                    ) from None
            if say is not None and i and i % 1000 == 0:
                say(f"send t {float(t):7.2f} s | sent {sent} errors {errors}")
    finally:
        sock.close()
    return {
        "sent": sent,
        "errors": errors,
        "duration_s": clock() - start,
        "lateness_us": spread(late[: sent + errors] * 1e6),
    }


def spread(x: np.ndarray) -> dict:
    """The median, 99th percentile and largest of ``x`` (None each when empty)."""
    if not x.size:
        return {"p50": None, "p99": None, "max": None}
    p50, p99 = np.percentile(x, [50, 99])
    return {"p50": float(p50), "p99": float(p99), "max": float(x.max())}
