"""Messages on one line: what a user, a summary row or a log line is shown of an exception.

One helper for every place that turns an exception into text: the command
line's ``error: ...`` line (at most :data:`MAX_MESSAGE_CHARS`), a failed batch
or response task's ``reason`` (``Type: message``), an invalid variant's reason.
"""

from __future__ import annotations

#: Longest error line printed (characters); a longer one keeps its start and its
#: end (where "allowed: ..." is) around "...". Fields echo cut values already.
MAX_MESSAGE_CHARS = 1000


def one_line(
    exc: BaseException | str, *, with_type: bool = False, max_chars: int | None = None
) -> str:
    """The text of ``exc`` with every run of whitespace (newlines too) as one space.

    Parameters
    ----------
    exc : exception or str
        What to show.
    with_type : bool
        Prefix the exception's class, ``Type: message`` (``Type`` alone when the
        message is empty): the reason of a task that failed unexpectedly.
    max_chars : int, optional
        Cut a longer text to its start and its end around ``" ... "``.
    """
    text = " ".join(str(exc).split())
    if max_chars is not None and len(text) > max_chars:
        half = max_chars // 2 - 3
        text = f"{text[:half]} ... {text[-half:]}"
    if with_type and isinstance(exc, BaseException):
        return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return text
