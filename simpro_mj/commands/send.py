"""``simpro-sim send TELEMETRY.csv --to HOST:PORT``: a telemetry file replayed as UDP datagrams.

The stand-in for a game, so that ``simpro-sim live`` can be tried (and
tested) without one: the file (:mod:`simpro_mj.config.telemetry`) is
resampled every ``1/--rate`` s and each sample sent as one datagram of
``--format`` (:mod:`simpro_mj.config.datagrams`: ``outsim`` packs the
attitude integrated from the file's rates), at absolute deadlines from the
first. A refused send (nobody listening) is counted, not fatal; a host that
does not resolve, or an address nothing can be sent to, is refused at once
(exit 2), and a run that sent nothing exits 1. ``TELEMETRY.csv`` is a path,
or the name of a shipped file (``simpro-sim list``).

``--jitter-ms``, ``--loss``, ``--duplicate``, ``--reorder``, ``--pause`` and
``--bias-fz-mps2`` send the feed as a game and a network deliver it
(:mod:`simpro_mj.sim.live_feed`), reproducibly from ``--seed``.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from simpro_mj.config.datagrams import SEND_FORMATS, telemetry_datagrams
from simpro_mj.config.telemetry import read_telemetry
from simpro_mj.core.errors import UserInputError
from simpro_mj.core.jsonout import emit_json
from simpro_mj.core.shipped import TELEMETRY_DIR
from simpro_mj.sim.live_feed import FeedImpairment, biased, impair
from simpro_mj.sim.udp import parse_address, send_datagrams

HELP = "send a telemetry CSV as paced UDP datagrams (OutSim, Forza, ...): a game's stand-in"
#: no scenario to override; its lines on stderr are what it sends
COMMON_OPTIONS = ("json",)


def add_arguments(parser) -> None:
    parser.add_argument("telemetry", metavar="TELEMETRY.csv",
                        help="a telemetry file (e.g. scenarios/telemetry/"
                        "braking_100kmh.csv)")  # fmt: skip
    parser.add_argument("--to", required=True, metavar="HOST:PORT", help="where to send")
    parser.add_argument("--format", dest="fmt", choices=SEND_FORMATS, default="outsim",
                        help="datagram format, as a game sends it (default outsim)")  # fmt: skip
    parser.add_argument("--rate", type=float, default=100.0, metavar="HZ",
                        help="datagrams per second (default 100, at most 1000)")  # fmt: skip
    parser.add_argument("--jitter-ms", type=float, default=0.0, metavar="MS",
                        help="move each send uniformly within +-MS (default 0)")  # fmt: skip
    for name, what in (("loss", "dropped"), ("duplicate", "sent twice"),
                       ("reorder", "swapped with the next")):  # fmt: skip
        parser.add_argument(f"--{name}", type=float, default=0.0, metavar="SHARE",
                            help=f"share of the datagrams {what} (default 0)")  # fmt: skip
    parser.add_argument("--pause", action="append", default=[], metavar="AT_S:LENGTH_S",
                        help="send nothing for LENGTH_S from AT_S (repeatable)")  # fmt: skip
    parser.add_argument("--bias-fz-mps2", type=float, default=0.0, metavar="M/S2",
                        help="add this to the vertical specific force (default 0)")  # fmt: skip
    parser.add_argument("--seed", type=int, default=1,
                        help="seed of the jitter, loss, duplicate and reorder draws")  # fmt: skip


def run(args) -> int:
    address = parse_address(args.to, "--to")
    if not (math.isfinite(args.rate) and 0 < args.rate <= 1000):
        raise UserInputError(f"invalid value at --rate: {args.rate:g}; allowed: > 0 and <= 1000")
    imp = FeedImpairment(jitter_s=args.jitter_ms * 1e-3, loss=args.loss,
                         duplicate=args.duplicate, reorder=args.reorder,
                         pauses=tuple(_pause(p) for p in args.pause), seed=args.seed)  # fmt: skip
    tel = read_telemetry(_telemetry_path(args.telemetry))
    if args.bias_fz_mps2:
        tel = biased(tel, args.bias_fz_mps2)
    times, grams = telemetry_datagrams(tel, args.fmt, args.rate)
    times, grams, counts = impair(times, grams, imp)

    def say(line: str) -> None:
        if not args.json:
            sys.stderr.write(line + "\n")

    info = send_datagrams(grams, times, address, say=say)
    info.update(to=f"{address[0]}:{address[1]}", format=args.fmt, rate_hz=args.rate,
                impaired=counts)  # fmt: skip
    if args.json:
        emit_json(info)
    else:
        print(
            f"sent {info['sent']} {args.fmt} datagrams to {info['to']} in "
            f"{info['duration_s']:.2f} s ({info['errors']} refused)"
        )
    return 0 if info["sent"] else 1


def _pause(text: str) -> tuple[float, float]:
    """``AT_S:LENGTH_S`` as two numbers, or a one-line error naming ``--pause``."""
    at, sep, length = text.partition(":")
    try:
        if not sep:
            raise ValueError
        return float(at), float(length)
    except ValueError:
        raise UserInputError(
            f"invalid value at --pause: {text!r}; allowed: AT_S:LENGTH_S, e.g. 20:1.5"
        ) from None


def _telemetry_path(text: str) -> Path:
    """The file as given, else the shipped file of that name (as scenarios find it)."""
    path = Path(text).expanduser()
    if not path.exists() and not path.is_absolute() and (TELEMETRY_DIR / path).is_file():
        return TELEMETRY_DIR / path
    return path
