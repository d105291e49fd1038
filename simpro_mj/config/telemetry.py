"""Vehicle telemetry files: the input of the motion-cueing chain.

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
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from simpro_mj.core.errors import UserInputError

#: Required columns, in the order written.
TELEMETRY_COLUMNS = ("time_s", "fx_mps2", "fy_mps2", "fz_mps2", "wx_rad_s", "wy_rad_s", "wz_rad_s")
#: Largest allowed interval between two samples (s).
MAX_GAP_S = 0.1
#: Tolerance on :data:`MAX_GAP_S` (s): a 10 Hz log whose times are written rounded
#: (``0.30000000000000004 - 0.2``) is at the limit, not past it.
GAP_TOLERANCE_S = 1e-6
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

    The file is opened without blocking and only if it is a regular file of at
    most :data:`MAX_BYTES` (:func:`simpro_mj.core.safe_files.open_regular`: a FIFO
    or a device is refused at once), then streamed in blocks of
    :data:`BLOCK_BYTES`, each parsed by NumPy and checked before the next is
    read: a bad value is refused where it is, and the file is never held whole
    as text. A line longer than :data:`MAX_LINE_CHARS` is refused.

    Raises
    ------
    TelemetryError
        Missing or unreadable file, missing column, a non-number, non-finite
        or implausible value (:data:`PLAUSIBLE`), unsorted or repeated times,
        a gap over :data:`MAX_GAP_S`, fewer than 2 rows.
    """
    from simpro_mj.core.safe_files import open_regular

    path = Path(path)
    name = label or str(path)
    try:
        fh = open_regular(path, MAX_BYTES, "telemetry", binary=True)
    except UserInputError as exc:
        raise TelemetryError(
            f"telemetry file {name}: {str(exc).split(': ', 1)[-1]}; see "
            "simpro_mj/config/telemetry.py for the format"
        ) from None
    with fh:
        header, lineno = None, 0
        while header is None:  # comments, then the header line
            raw = fh.readline(MAX_LINE_CHARS + 2)
            if not raw:
                raise TelemetryError(
                    f"telemetry file {name}: empty; allowed: a header {','.join(TELEMETRY_COLUMNS)}"
                )
            lineno += 1
            line = _text(raw, lineno, name)
            if line and not line.startswith("#"):
                header = [h.strip() for h in next(csv.reader([line]))]
        mapping = check_mapping(columns or {})
        names = [mapping.get(c, {}).get("column", c) for c in TELEMETRY_COLUMNS]
        for col, given in zip(TELEMETRY_COLUMNS, names, strict=True):
            if given not in header:
                via = f" (mapped to {col} by setpoint.cueing.columns)" if col in mapping else ""
                raise TelemetryError(
                    f"telemetry file {name}: missing column {given}{via} (header, row "
                    f"{lineno}); the header has: {', '.join(header)}; required: "
                    f"{', '.join(TELEMETRY_COLUMNS)}"
                    + ("" if via else " or a mapping in setpoint.cueing.columns")
                )
        pos = [header.index(c) for c in names]
        blocks, last, carry = [], None, b""
        while True:
            chunk = fh.read(BLOCK_BYTES)
            body = carry + chunk
            cut = body.rfind(b"\n") + 1 if chunk else len(body)
            body, carry = body[:cut], body[cut:]
            if len(carry) > MAX_LINE_CHARS:
                raise TelemetryError(
                    f"telemetry file {name}: row {lineno + 1}: a line of more than "
                    f"{MAX_LINE_CHARS:,} characters; allowed: at most {MAX_LINE_CHARS:,}"
                )
            if body:
                data, lines = _parse(body, lineno, header, pos, name)
                lineno += body.count(b"\n") + (not body.endswith(b"\n"))
                for j, c in enumerate(TELEMETRY_COLUMNS):  # the file's units to SI
                    if c in mapping:
                        data[:, j] = mapping[c]["scale"] * data[:, j] + mapping[c]["offset"]
                if len(data):
                    _check(data, lines, last, name)
                    blocks.append(data)
                    last = (data[-1, 0], lines[-1])
            if not chunk:
                break
    data = np.concatenate(blocks) if blocks else np.empty((0, len(TELEMETRY_COLUMNS)))
    if len(data) < 2:
        raise TelemetryError(f"telemetry file {name}: {len(data)} data rows; allowed: >= 2")
    t = data[:, 0]
    return Telemetry(t=t - t[0], f=data[:, 1:4].copy(), w=data[:, 4:7].copy(), source=name)


#: Bytes parsed at once while streaming a telemetry file.
BLOCK_BYTES = 4_000_000
#: Longest line of a telemetry file (characters): 7 numbers need about 200.
MAX_LINE_CHARS = 10_000
#: Largest magnitude of each quantity (why): beyond it the file is not a vehicle's motion.
PLAUSIBLE = {
    "time_s": (1e9, "about 30 years of log"),
    "fx_mps2": (100.0, "about 10 g: more than any road vehicle short of a crash"),
    "fy_mps2": (100.0, "about 10 g: more than any road vehicle short of a crash"),
    "fz_mps2": (100.0, "about 10 g: more than any road vehicle short of a crash"),
    "wx_rad_s": (20.0, "about 1150 deg/s: more than a rolling-over car"),
    "wy_rad_s": (20.0, "about 1150 deg/s: more than a rolling-over car"),
    "wz_rad_s": (20.0, "about 1150 deg/s: more than a spinning car"),
}


def _text(raw: bytes, lineno: int, name: str) -> str:
    if len(raw) > MAX_LINE_CHARS + 1:
        raise TelemetryError(
            f"telemetry file {name}: row {lineno}: a line of more than {MAX_LINE_CHARS:,} "
            f"characters; allowed: at most {MAX_LINE_CHARS:,}"
        )
    try:  # a byte-order mark (Excel's UTF-8 CSV) before the header is dropped
        return raw.decode("utf-8-sig" if lineno == 1 else "utf-8").strip()
    except UnicodeDecodeError:
        raise TelemetryError(
            f"telemetry file {name}: row {lineno}: not UTF-8 text; allowed: a CSV file"
        ) from None


def _parse(body: bytes, lineno: int, header, pos, name) -> tuple[np.ndarray, np.ndarray]:
    """The required columns of ``body``'s data lines (the first is line ``lineno + 1``),
    each as many fields as the header (else refused by line), and each row's line number."""
    width = len(header)
    raw_lines = body.split(b"\n")
    if raw_lines[-1] == b"":
        raw_lines.pop()
    keep = [k for k, ln in enumerate(raw_lines) if ln.strip() and not ln.lstrip().startswith(b"#")]
    for k in keep:
        if raw_lines[k].count(b",") != width - 1 and b'"' not in raw_lines[k]:
            raise TelemetryError(
                f"telemetry file {name}: row {lineno + 1 + k}: "
                f"{raw_lines[k].count(b',') + 1} fields; allowed: {width}, as in the header "
                "(a field too many or too few would shift values across columns)"
            )
    n = len(keep)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            joined = b",".join(raw_lines[k] for k in keep).replace(b"\r", b"")
            flat = np.fromstring(joined.decode("ascii"), sep=",") if n else np.empty(0)
        except (ValueError, UnicodeDecodeError):
            flat = None
    if flat is not None and flat.size == n * width:
        return flat.reshape(n, width)[:, pos], np.array(keep, dtype=int) + lineno + 1
    rows, lines = [], []
    for k in keep:
        line = _text(raw_lines[k], lineno + 1 + k, name)
        row = next(csv.reader([line]))
        if len(row) != width:
            raise TelemetryError(
                f"telemetry file {name}: row {lineno + 1 + k}: {len(row)} fields; allowed: "
                f"{width}, as in the header"
            )
        vals = []
        for c, j in zip(TELEMETRY_COLUMNS, pos, strict=True):
            cell = row[j].strip() if j < len(row) else ""
            try:
                vals.append(float(cell))
            except ValueError:
                raise TelemetryError(
                    f"telemetry file {name}: column {c} row {lineno + 1 + k}: {cell[:40]!r} "
                    "is not a number; allowed: a finite number"
                ) from None
        rows.append(vals)
        lines.append(lineno + 1 + k)
    return np.array(rows, dtype=float).reshape(-1, len(pos)), np.array(lines, dtype=int)


def _check(data: np.ndarray, lines, last, name: str) -> None:
    """Values finite and plausible, times increasing without gaps (``last``: the
    previous block's last time and line)."""
    for j, c in enumerate(TELEMETRY_COLUMNS):
        limit, why = PLAUSIBLE[c]
        col = data[:, j]
        bad = ~(np.abs(col) <= limit)  # NaN too
        if bad.any():
            i = int(np.argmax(bad))
            bound = f", |value| <= {limit:g} ({why})" if math.isfinite(col[i]) else ""
            raise TelemetryError(
                f"telemetry file {name}: column {c} row {lines[i]}: {col[i]:g}; "
                f"allowed: a finite number{bound}"
            )
    t = data[:, 0] if last is None else np.concatenate([[last[0]], data[:, 0]])
    rows = list(lines) if last is None else [last[1], *lines]
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0)) + 1
        raise TelemetryError(
            f"telemetry file {name}: column time_s row {rows[i]}: {t[i]:g} s after "
            f"{t[i - 1]:g} s; allowed: strictly increasing times"
        )
    if np.any(dt > MAX_GAP_S + GAP_TOLERANCE_S):
        i = int(np.argmax(dt > MAX_GAP_S + GAP_TOLERANCE_S)) + 1
        raise TelemetryError(
            f"telemetry file {name}: column time_s row {rows[i]}: gap of {dt[i - 1]:.9g} s "
            f"after {t[i - 1]:g} s; allowed: <= {MAX_GAP_S} s between samples (10 Hz or "
            f"faster, {GAP_TOLERANCE_S * 1e6:g} us tolerance for rounded times)"
        )


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
