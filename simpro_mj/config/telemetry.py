"""Vehicle telemetry files: the input of the motion-cueing chain (issue 16).

Format
------
A CSV file, comma separated, one header line of column names, then one row
per sample. SI units, named in the column names. Frame: the vehicle frame
V, ISO 8855 (x forward, y left, z up), at the driver's head
(:mod:`controllers.frames`).

=================  ======================================================
column             meaning
=================  ======================================================
``time_s``         time (s), strictly increasing, finite
``fx_mps2``        specific force ``a - g`` along x (m/s^2); braking < 0
``fy_mps2``        along y; a left turn > 0
``fz_mps2``        along z; **includes gravity**: +9.81 at rest
``wx_rad_s``       angular velocity about x (roll rate, rad/s)
``wy_rad_s``       about y (pitch rate; nose down > 0)
``wz_rad_s``       about z (yaw rate; turning left > 0)
=================  ======================================================

Other columns (for instance ``speed_mps``) are allowed and ignored. Lines
starting with ``#`` are comments. The samples need not be uniform, but no
gap between two samples may exceed ``MAX_GAP_S`` (0.1 s: the 10 Hz below
which a 1-2 Hz vehicle motion is no longer described). Time 0 of the run is
the file's first time. The run may not outlast the file.

A file with other column names or units plays through a column mapping
(``setpoint.cueing.columns`` of a scenario, :func:`check_mapping`): per
required column, the file's column and a scale and offset to SI::

    columns:
      time_s: {column: t_ms, scale: 0.001}
      fx_mps2: {column: accel_x_g, scale: 9.80665}
      fz_mps2: {column: accel_z, offset: 9.80665}   # a log without gravity
      wy_rad_s: {column: pitch_rate_deg_s, scale: 0.017453292519943295}

(a plain string is the column with scale 1 and offset 0). The value used is
``scale * cell + offset``. A required column not mapped keeps its own name.

Resampling to the physics grid is linear interpolation
(:func:`resample`): telemetry is logged at 50-1000 Hz, the grid is 1 ms.

Errors are one line naming the file, the column and the row (1-based line
numbers of the file) and what is allowed; they subclass
:class:`~simpro_mj.core.errors.UserInputError` (exit 2).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from simpro_mj.core.errors import UserInputError

__all__ = [
    "TELEMETRY_COLUMNS",
    "MAX_GAP_S",
    "Telemetry",
    "TelemetryError",
    "read_telemetry",
    "check_mapping",
    "write_telemetry",
    "resample",
]

#: Required columns, in the order written.
TELEMETRY_COLUMNS = ("time_s", "fx_mps2", "fy_mps2", "fz_mps2", "wx_rad_s", "wy_rad_s", "wz_rad_s")
#: Largest allowed interval between two samples (s).
MAX_GAP_S = 0.1
#: Largest file read (bytes): a 600 s run at 1 kHz with 7 columns is ~60 MB.
MAX_BYTES = 200_000_000


class TelemetryError(UserInputError):
    """A telemetry file that does not follow the format; the message names column and row."""


@dataclass
class Telemetry:
    """Vehicle motion at the driver's head, V frame: ``t`` (n,), ``f`` (n, 3), ``w`` (n, 3)."""

    t: np.ndarray
    f: np.ndarray
    w: np.ndarray
    source: str = ""
    #: further columns (name -> (n,) array), written after the required ones
    extra: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if self.t.size else 0.0


def check_mapping(value) -> dict:
    """A column mapping, each entry spelled out ``{column, scale, offset}``.

    Raises ``ValueError`` (one line naming the entry) for an unknown column, a
    column that is not a non-empty string, a scale that is not a finite non-zero
    number or an offset that is not finite.
    """
    if not isinstance(value, dict):
        raise ValueError(f"expected a mapping of {list(TELEMETRY_COLUMNS)} to file columns")
    out = {}
    for std, entry in value.items():
        if std not in TELEMETRY_COLUMNS:
            raise ValueError(f"column {std!r} unknown; allowed: {list(TELEMETRY_COLUMNS)}")
        if isinstance(entry, str):
            entry = {"column": entry}
        if not isinstance(entry, dict):
            raise ValueError(f"{std}: expected a column name or {{column, scale, offset}}")
        extra = sorted(set(entry) - {"column", "scale", "offset"})
        if extra:
            raise ValueError(f"{std}: unknown key {extra[0]!r}; allowed: column, scale, offset")
        col = entry.get("column")
        if not isinstance(col, str) or not col.strip():
            raise ValueError(f"{std}.column: {col!r}; allowed: a column name of the file")
        scale, offset = entry.get("scale", 1.0), entry.get("offset", 0.0)
        for key, v, nonzero in (("scale", scale, True), ("offset", offset, False)):
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            if not ok or (nonzero and v == 0):
                allowed = "a finite non-zero number" if nonzero else "a finite number"
                raise ValueError(f"{std}.{key}: {v!r}; allowed: {allowed}")
        out[std] = {"column": col.strip(), "scale": float(scale), "offset": float(offset)}
    return out


def read_telemetry(path, *, label: str | None = None, columns: dict | None = None) -> Telemetry:
    """Read and check a telemetry CSV; times are shifted to start at 0.

    ``columns``: a mapping (:func:`check_mapping`) from the required columns to
    the file's, with their scale and offset to SI.

    Raises
    ------
    TelemetryError
        Missing or unreadable file, missing column, a non-number or non-finite
        value, unsorted or repeated times, a gap over :data:`MAX_GAP_S`, fewer
        than 2 rows.
    """
    path = Path(path)
    name = label or str(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise TelemetryError(
            f"telemetry file {name}: cannot read ({exc.strerror or exc}); "
            "allowed: a CSV file in the format of docs (simpro_mj/config/telemetry.py)"
        ) from None
    if not path.is_file():
        raise TelemetryError(f"telemetry file {name}: not a file; allowed: a CSV file")
    if size > MAX_BYTES:
        raise TelemetryError(f"telemetry file {name}: {size} bytes; allowed: <= {MAX_BYTES}")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TelemetryError(f"telemetry file {name}: cannot read as UTF-8 text ({exc})") from None
    rows = []
    lines = []
    for lineno, row in _rows(text):
        rows.append(row)
        lines.append(lineno)
    if not rows:
        raise TelemetryError(
            f"telemetry file {name}: empty; allowed: a header {','.join(TELEMETRY_COLUMNS)}"
        )
    header = [h.strip() for h in rows[0]]
    mapping = check_mapping(columns or {})
    names = [mapping.get(c, {}).get("column", c) for c in TELEMETRY_COLUMNS]
    for col, given in zip(TELEMETRY_COLUMNS, names, strict=True):
        if given not in header:
            via = f" (mapped to {col} by setpoint.cueing.columns)" if col in mapping else ""
            raise TelemetryError(
                f"telemetry file {name}: missing column {given}{via} (header, row {lines[0]}); "
                f"the header has: {', '.join(header)}; required: {', '.join(TELEMETRY_COLUMNS)}"
                + ("" if via else " or a mapping in setpoint.cueing.columns")
            )
    pos = [header.index(c) for c in names]
    body = rows[1:]
    if len(body) < 2:
        raise TelemetryError(f"telemetry file {name}: {len(body)} data rows; allowed: >= 2")
    data = np.empty((len(body), len(pos)))
    for i, row in enumerate(body):
        for j, (c, k) in enumerate(zip(TELEMETRY_COLUMNS, pos, strict=True)):
            cell = row[k].strip() if k < len(row) else ""
            try:
                v = float(cell)
            except ValueError:
                raise TelemetryError(
                    f"telemetry file {name}: column {c} row {lines[i + 1]}: {cell!r} is not a "
                    "number; allowed: a finite number"
                ) from None
            if not math.isfinite(v):
                raise TelemetryError(
                    f"telemetry file {name}: column {c} row {lines[i + 1]}: {cell}; "
                    "allowed: a finite number"
                )
            data[i, j] = v
    for j, c in enumerate(TELEMETRY_COLUMNS):
        if c in mapping:
            data[:, j] = mapping[c]["scale"] * data[:, j] + mapping[c]["offset"]
    t = data[:, 0]
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0)) + 1
        raise TelemetryError(
            f"telemetry file {name}: column time_s row {lines[i + 1]}: {t[i]:g} s after "
            f"{t[i - 1]:g} s; allowed: strictly increasing times"
        )
    if np.any(dt > MAX_GAP_S):
        i = int(np.argmax(dt > MAX_GAP_S)) + 1
        raise TelemetryError(
            f"telemetry file {name}: column time_s row {lines[i + 1]}: gap of {dt[i - 1]:g} s "
            f"after {t[i - 1]:g} s; allowed: <= {MAX_GAP_S} s between samples"
        )
    return Telemetry(t=t - t[0], f=data[:, 1:4].copy(), w=data[:, 4:7].copy(), source=name)


def _rows(text: str):
    """(line number, cells) of the non-comment, non-blank lines."""
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        yield lineno, next(csv.reader([line]))


def write_telemetry(path, tel: Telemetry, comment: str = "") -> Path:
    """Write ``tel`` (and its ``extra`` columns) in the format above (``%.9g``),
    with ``#`` comment lines first."""
    path = Path(path)
    cols = [tel.t, *tel.f.T, *tel.w.T]
    names = list(TELEMETRY_COLUMNS)
    for k, v in tel.extra.items():
        names.append(k)
        cols.append(np.asarray(v, float))
    head = "".join(f"# {line}\n" for line in comment.splitlines())
    body = np.column_stack(cols)
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(head + ",".join(names) + "\n")
        np.savetxt(fh, body, fmt="%.9g", delimiter=",")
    return path


def resample(tel: Telemetry, t) -> tuple[np.ndarray, np.ndarray]:
    """``f``, ``w`` (len(t), 3) linearly interpolated at times ``t`` (within the file)."""
    t = np.asarray(t, dtype=float)
    if t.size and (t[0] < tel.t[0] - 1e-12 or t[-1] > tel.t[-1] + 1e-9):
        raise TelemetryError(
            f"telemetry file {tel.source}: covers 0..{tel.t[-1]:g} s, the run needs "
            f"{t[0]:g}..{t[-1]:g} s; allowed: duration_s <= {tel.t[-1]:g}"
        )
    f = np.column_stack([np.interp(t, tel.t, tel.f[:, k]) for k in range(3)])
    w = np.column_stack([np.interp(t, tel.t, tel.w[:, k]) for k in range(3)])
    return f, w
