"""One output file by the write rule: a calibrated preset, a video, a telemetry CSV.

A file is written only if it does not exist, or its folder's marker lists it as
simpro-sim's and it is unchanged (:mod:`simpro_mj.report.marker`), or the user
says ``--overwrite``; under a temporary name, renamed into place, then listed.
"""

from __future__ import annotations

import os
from pathlib import Path

from simpro_mj.core.errors import UserInputError
from simpro_mj.core.safe_files import short
from simpro_mj.report.folders import locked, out_path
from simpro_mj.report.marker import foreign, record, replacing, result_kind


def check_file(path, overwrite: bool = False, option: str = "--out") -> Path:
    """Refuse a file path that is not simpro-sim's to write; return it absolute.

    A single output file (a calibrated preset, a video, a telemetry CSV) is
    written only if it does not exist, or the marker of its folder lists it as
    written by simpro-sim and it is unchanged (:func:`foreign`), or with
    ``overwrite`` (the user's explicit ``--overwrite``). A folder, a device, a
    dangling link, or a parent that is a file are refused whatever
    ``overwrite`` says. A link to a file is followed (the link is kept).

    Raises
    ------
    UserInputError
        Any of the above (nothing is touched).
    """
    path = out_path(path, "--out")
    if path.is_symlink():
        if not path.exists():
            raise UserInputError(
                f"refused {option} at {short(path)}: a symbolic link to a file that does not "
                "exist; nothing was touched; allowed: a new file path"
            )
        path = path.resolve()
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise UserInputError(
                    f"cannot write at {option}: {short(path)}: a parent is a file, not a "
                    "folder; allowed: a path in a folder"
                )
            if not os.access(parent, os.W_OK | os.X_OK):
                raise UserInputError(
                    f"cannot write at {option}: {short(path)}: permission denied in "
                    f"{short(parent)}; allowed: a writable path"
                )
            break
    if not os.path.lexists(path):
        return path
    if path.is_dir():
        raise UserInputError(
            f"refused {option} at {short(path)}: it is a folder; allowed: a file path"
        )
    if not path.is_file():
        raise UserInputError(
            f"refused {option} at {short(path)}: not a regular file; allowed: a new file path"
        )
    if overwrite or not foreign(path.parent, only=[path.name]):
        return path
    raise UserInputError(
        f"refused {option} at {short(path)}: the file exists and simpro-sim did not write "
        f"it (or it changed since); nothing was touched; allowed: a new file, or "
        f"{option} with --overwrite to replace it"
    )


def record_file(path, created: bool = False) -> None:
    """List a file just written in its folder's marker (the marker's kind kept),
    so that the next run may replace it; a folder without a marker gets one
    (kind ``files``) only if simpro-sim ``created`` it: a user's folder is never
    given a marker."""
    path = Path(path).absolute()
    kind = result_kind(path.parent)
    if kind is None and not created:
        return
    with locked(path.parent):
        record(path.parent, [path.name], kind or "files")


def write_file(path, data: str | bytes, overwrite: bool = False, option: str = "--out") -> Path:
    """Write one output file by the rule of :func:`check_file`: under a temporary
    name in its folder, renamed into place, then listed (:func:`record_file`)."""
    path = check_file(path, overwrite, option)
    created = not path.parent.exists()
    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path) as tmp:
        Path(tmp).write_bytes(data.encode("utf-8") if isinstance(data, str) else data)
    record_file(path, created)
    return path


def write_telemetry_file(out: Path, tel, comment: str) -> None:
    """Write the telemetry ``tel`` to ``out`` (checked by :func:`check_file`) whole or not
    at all: into a hidden file beside it, renamed over it once complete, then listed in
    the folder's marker (:func:`record_file`)."""
    from simpro_mj.config.telemetry import write_telemetry

    with replacing(out) as tmp:
        write_telemetry(tmp, tel, comment)
    record_file(out)
