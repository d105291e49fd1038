"""Opening a file a user named, with bounds: no input can make the reader block.

Every file simpro-sim reads (scenarios, presets, calibration targets,
telemetry, the files of a result folder read back) is opened by
:func:`open_regular`:

* ``open(2)`` with ``O_NONBLOCK``, so that a FIFO without a writer does not
  block the open (a plain ``open`` of a FIFO waits for a writer forever);
* ``fstat`` on the descriptor, not the name (no race with a rename): only a
  regular file is read; a FIFO, a device (``/dev/zero`` reads without end), a
  socket or a folder is refused at once;
* the size checked against the caller's bound before a byte is read;
* then ``O_NONBLOCK`` cleared (a regular file never blocks; the flag only
  matters for the open).

Each refusal is a :class:`UnreadableFile` (a
:class:`~simpro_mj.core.errors.UserInputError`, so one line and exit 2) naming
the file and what is allowed.
"""

from __future__ import annotations

import fcntl
import io
import os
import stat
from pathlib import Path

from simpro_mj.core.errors import UserInputError


class UnreadableFile(UserInputError):
    """A file that is not a regular file, is over its size bound, or cannot be opened."""


_KINDS = (
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISLNK, "a symbolic link"),
)


def kind_of(mode: int) -> str:
    """What a file of ``st_mode`` is, in words (``a FIFO (named pipe)``, ...)."""
    for test, name in _KINDS:
        if test(mode):
            return name
    return "a regular file" if stat.S_ISREG(mode) else "a special file"


def short(path, limit: int = 200) -> str:
    """``path`` as text, its start and end around ``...`` when longer than ``limit``."""
    text = str(path)
    return text if len(text) <= limit else f"{text[:90]}...{text[-90:]}"


def open_regular(path, max_bytes: int, what: str = "file", binary: bool = False):
    """Open ``path`` for reading if it is a regular file of at most ``max_bytes``.

    Parameters
    ----------
    path : path
        The file.
    max_bytes : int
        The largest size read (checked on the open descriptor, before reading).
    what : str
        What the file is, for the message (``scenario``, ``telemetry``, ...).
    binary : bool
        A binary stream (default: UTF-8 text).

    Returns
    -------
    file object
        Open for reading; the caller closes it.

    Raises
    ------
    UnreadableFile
        Missing, unreadable, not a regular file, or over ``max_bytes``.
    """
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise UnreadableFile(
            f"cannot read {what} at {short(path)}: {exc.strerror or exc}; "
            f"allowed: a readable regular {what} file"
        ) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise UnreadableFile(
                f"not a regular file at {short(path)}: {kind_of(st.st_mode)}; "
                f"allowed: a regular {what} file"
            )
        if st.st_size > max_bytes:
            raise UnreadableFile(
                f"file too large at {short(path)}: {st.st_size:,} bytes; "
                f"allowed: a {what} file of at most {max_bytes:,} bytes"
            )
        flags = fcntl.fcntl(fd, fcntl.F_GETFL)
        fcntl.fcntl(fd, fcntl.F_SETFL, flags & ~os.O_NONBLOCK)
        raw = os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
    if binary:
        return raw
    return io.TextIOWrapper(raw, encoding="utf-8", newline=None)


def read_bytes(path, max_bytes: int, what: str = "file") -> bytes:
    """The bytes of a regular file of at most ``max_bytes`` (:func:`open_regular`)."""
    with open_regular(path, max_bytes, what, binary=True) as fh:
        data = fh.read(max_bytes + 1)
    if len(data) > max_bytes:  # grew after the check
        raise UnreadableFile(
            f"file too large at {short(path)}: over {max_bytes:,} bytes; "
            f"allowed: a {what} file of at most {max_bytes:,} bytes"
        )
    return data


def read_text(path, max_bytes: int, what: str = "file") -> str:
    """The UTF-8 text of a regular file of at most ``max_bytes``.

    Raises
    ------
    UnreadableFile
        As :func:`open_regular`, or the bytes are not UTF-8.
    """
    data = read_bytes(path, max_bytes, what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UnreadableFile(
            f"not UTF-8 text at {short(path)}: byte {exc.start}; allowed: a UTF-8 {what} file"
        ) from None
