"""UDP addresses of the live commands: ``HOST:PORT`` checked, a host resolved, one-line errors."""

from __future__ import annotations

import socket

from simpro_mj.core.errors import UserInputError

__all__ = ["parse_address", "resolve_address"]


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
