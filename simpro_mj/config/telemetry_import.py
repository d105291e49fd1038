"""Recorded drives into telemetry: a phone's or a data logger's accelerometer and gyroscope.

A recording gives the specific force ``a`` (m/s^2, gravity included: 9.81 up at rest)
and the angular velocity ``w`` (rad/s) in the axes of the device, not of the car.
:func:`import_recording` turns them into the cueing chain's input
(:mod:`simpro_mj.config.telemetry`: ISO 8855 vehicle frame, x forward, y left, z up)
in four steps, each one named in the file it writes:

1. **One time grid.** Both sensors linearly interpolated onto a uniform grid at
   ``rate_hz`` (default 100 Hz) over the times both cover, trimmed to
   ``[start_s, end_s]`` of the recording.
2. **Level** (``frame`` ``device``). The car's mean pitch and roll over a drive are
   near zero, so the mean specific force points up: the device is turned by the
   smallest rotation that takes the mean of ``a`` onto +z. A road grade or a mean
   acceleration over the trimmed drive tilts this by their ratio to g (a mean
   0.2 m/s^2 of acceleration: 1.2 deg) and is removed with it, as the bias stage
   below would. ``level`` and ``earth`` data are level already (their z is up).
3. **Heading.** The car's forward axis in the levelled horizontal plane:

   * ``device`` and ``level``: the principal axis of the horizontal specific force
     while the car drives straight (each sample weighted by
     ``exp(-(r / 0.03 rad/s)^2)``, ``r`` the yaw rate): braking and accelerating push
     along it, a turn across it. It is estimated over windows of ``window_s``
     (default 20 s, every quarter of it; one window over the whole drive for a
     ``device`` fixed in the car, ``window_s`` 0) and interpolated between them, so a
     heading that drifts slowly (a phone's "earth" frame whose north comes from a
     magnetometer the car's steel disturbs) is followed.
   * ``earth`` (x east, y north, z up, the heading a true compass's): the frame is
     first turned back by the integrated yaw rate, then the slow remainder as above.

   The principal axis has no sign; the lateral axis is chosen so that the lateral
   force follows the yaw rate (``f_y = v r`` with ``v`` > 0: a left turn pushes left)
   over the whole drive, and ``x = y x z``. ``vehicle``: the columns are the car's
   axes already (with ``axes`` naming each one's sign, e.g. ``x,-y,-z`` for a
   forward-right-down logger) and nothing is estimated.
4. **Conditioning** (:class:`controllers.conditioning.InputConditioner`, the same
   stages a live session runs): a slow bias removal (``bias_tau_s``, 10 s) and a
   vibration low-pass (``vibration_hz``, 10 Hz); 0 leaves either out.

The estimate's quality is returned and written in the file's comment lines:
``lateral_yaw_corr`` (the correlation of the lateral force with the yaw rate; a car
turning at speed gives 0.5-0.95), ``straight_lateral_share`` (the share of the
horizontal force on the lateral axis while driving straight; a well-found heading
leaves it small), the tilt and heading found.

Errors are one line naming the file, the column or option and what is allowed
(:class:`ImportError_`, a :class:`~simpro_mj.core.errors.UserInputError`: exit 2).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from controllers.conditioning import BIAS_TAU_S, VIBRATION_HZ, InputConditioner
from simpro_mj.config.telemetry import Telemetry
from simpro_mj.core.errors import UserInputError

#: The frames a recording's axes may be given in.
FRAMES = ("vehicle", "device", "level", "earth")
#: Yaw rate below which the car counts as driving straight (rad/s): 0.03 rad/s is a
#: 1 km radius at 30 m/s, whose lateral force (0.9 m/s^2) is still small.
STRAIGHT_YAW_RATE = 0.03
#: Moving average (s) of the force and yaw rate the heading is found from: a phone's
#: gyroscope in a car reads 0.05-0.1 rad/s of vibration, above the straight-driving
#: yaw rate, which 1 s of averaging brings to 0.01-0.02 rad/s.
HEADING_SMOOTH_S = 1.0
#: Largest file read (bytes).
MAX_BYTES = 200_000_000


class RecordingError(UserInputError):
    """A recording that cannot be imported; the message names the file and the field."""


@dataclass
class Recording:
    """Raw sensor samples: accelerometer ``ta`` (n,), ``a`` (n, 3); gyroscope ``tg``, ``g``."""

    ta: np.ndarray
    a: np.ndarray
    tg: np.ndarray
    g: np.ndarray
    source: str = ""


@dataclass
class ImportReport:
    """What :func:`import_recording` estimated, and how well."""

    frame: str
    tilt_deg: float = 0.0
    heading_deg: tuple = (0.0, 0.0)
    lateral_yaw_corr: float = float("nan")
    straight_lateral_share: float = float("nan")
    trimmed: tuple = (0.0, 0.0)
    notes: list = field(default_factory=list)

    def lines(self) -> list[str]:
        lo, hi = self.heading_deg
        return [
            f"frame {self.frame}: tilt to level {self.tilt_deg:.2f} deg, heading "
            f"{lo:.1f}..{hi:.1f} deg in the levelled data's axes",
            f"lateral_yaw_corr {self.lateral_yaw_corr:.3f}, straight_lateral_share "
            f"{self.straight_lateral_share:.3f}",
            f"trimmed to {self.trimmed[0]:g}..{self.trimmed[1]:g} s of the recording",
            *self.notes,
        ]


def _columns(spec: str, what: str) -> list[str]:
    cols = [c.strip() for c in str(spec).split(",")]
    if len(cols) != 3 or not all(cols):
        raise RecordingError(
            f"invalid value at {what}: {spec!r}; allowed: three column names x,y,z"
        )
    return cols


def _read_table(path: Path, names: list[str], what: str) -> np.ndarray:
    from simpro_mj.core.safe_files import open_regular

    try:
        fh = open_regular(path, MAX_BYTES, "recording", binary=False)
    except UserInputError as exc:
        raise RecordingError(f"recording {path}: {str(exc).split(': ', 1)[-1]}") from None
    with fh:
        header = None
        for line in fh:
            if line.strip() and not line.lstrip().startswith("#"):
                header = [h.strip() for h in next(csv.reader([line]))]
                break
        if header is None:
            raise RecordingError(f"recording {path}: empty; allowed: a CSV with a header line")
        for n in names:
            if n not in header:
                raise RecordingError(
                    f"recording {path}: missing column {n} ({what}); the header has: "
                    f"{', '.join(header)}"
                )
        pos = [header.index(n) for n in names]
        rows = []
        for k, line in enumerate(fh, start=2):
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            cells = line.rstrip("\r\n").split(",")
            try:
                rows.append([float(cells[j]) for j in pos])
            except (ValueError, IndexError):
                raise RecordingError(
                    f"recording {path}: row {k}: not a number in {', '.join(names)}; "
                    "allowed: finite numbers"
                ) from None
    data = np.asarray(rows, float).reshape(-1, len(names))
    if len(data) < 2 or not np.isfinite(data).all():
        raise RecordingError(
            f"recording {path}: {len(data)} rows or a non-finite value; allowed: >= 2 finite rows"
        )
    return data


def read_csv_sensors(accel_path, *, time: str, accel: str, gyro: str, gyro_path=None,
                     gyro_time: str | None = None, time_scale: float = 1.0,
                     accel_scale: float = 1.0, gyro_scale: float = 1.0) -> Recording:  # fmt: skip
    """Accelerometer and gyroscope columns of one CSV, or of two (``gyro_path``).

    ``time``: the time column (``time_scale`` to seconds; ``gyro_time`` the gyroscope's
    if it has its own); ``accel`` and ``gyro``: three column names each, ``x,y,z``
    (scaled to m/s^2 and rad/s: a logger whose accelerometer reads -1 g up at rest,
    as iOS's does, takes ``accel_scale`` -9.80665)."""
    for name, v in (("--time-scale", time_scale), ("--accel-scale", accel_scale),
                    ("--gyro-scale", gyro_scale)):  # fmt: skip
        if not (math.isfinite(v) and v != 0):
            raise RecordingError(
                f"invalid value at {name}: {v!r}; allowed: a finite non-zero number"
            )
    a_path, g_path = Path(accel_path), Path(gyro_path or accel_path)
    da = _read_table(a_path, [time, *_columns(accel, "--accel")], "--time/--accel")
    gt = gyro_time or time
    dg = _read_table(g_path, [gt, *_columns(gyro, "--gyro-columns")], "--gyro-time/--gyro-columns")
    return Recording(
        ta=da[:, 0] * time_scale,
        a=da[:, 1:] * accel_scale,
        tg=dg[:, 0] * time_scale,
        g=dg[:, 1:] * gyro_scale,
        source=a_path.name if g_path == a_path else f"{a_path.name} + {g_path.name}",
    )


def read_comma2k19(segment) -> Recording:
    """A comma2k19 segment's ``processed_log/IMU`` (accelerometer, gyro: NumPy arrays
    ``t`` and ``value``, axes forward-right-down; Schafer et al. 2018, MIT licence)."""
    seg = Path(segment)
    out = []
    for name in ("accelerometer", "gyro"):
        d = seg / "processed_log" / "IMU" / name
        try:
            t = np.load(d / "t", allow_pickle=False)
            v = np.load(d / "value", allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise RecordingError(
                f"recording {seg}: cannot read processed_log/IMU/{name}/t and value ({exc}); "
                "allowed: a comma2k19 segment folder"
            ) from None
        if t.ndim != 1 or v.shape != (t.size, 3) or t.size < 2:
            raise RecordingError(
                f"recording {seg}: processed_log/IMU/{name}: shapes {t.shape}, {v.shape}; "
                "allowed: (n,) and (n, 3)"
            )
        out += [np.asarray(t, float), np.asarray(v, float)]
    ta, a, tg, g = out
    return Recording(ta=ta, a=a, tg=tg, g=g, source=f"comma2k19 {seg.parent.name}/{seg.name}")


def _grid(rec: Recording, rate_hz: float, start_s: float, end_s: float):
    """Both sensors on one uniform grid, trimmed; times from the recording's start."""
    dropped = 0
    for name in ("a", "g"):  # a logger's repeated rows (the same time twice) are dropped
        t, x = getattr(rec, "t" + name), getattr(rec, name)
        keep = np.concatenate([[True], np.diff(t) > 0])
        if np.any(np.diff(t) < 0):
            i = int(np.argmax(np.diff(t) < 0)) + 1
            raise RecordingError(
                f"recording {rec.source}: {'accelerometer' if name == 'a' else 'gyroscope'} "
                f"time at sample {i + 1} goes back; allowed: increasing times"
            )
        dropped += int((~keep).sum())
        setattr(rec, "t" + name, t[keep])
        setattr(rec, name, x[keep])
    t0 = max(rec.ta[0], rec.tg[0])
    t_end = min(rec.ta[-1], rec.tg[-1]) - t0
    end = t_end if end_s <= 0 else min(end_s, t_end)
    if not (0 <= start_s < end):
        raise RecordingError(
            f"invalid value at --start-s/--end-s: {start_s:g}..{end_s:g} s; allowed: within "
            f"0..{t_end:.3f} s of the recording"
        )
    dt = 1.0 / rate_hz
    t = start_s + np.arange(int(math.floor((end - start_s) / dt + 1e-9)) + 1) * dt
    a = np.column_stack([np.interp(t + t0, rec.ta, rec.a[:, k]) for k in range(3)])
    g = np.column_stack([np.interp(t + t0, rec.tg, rec.g[:, k]) for k in range(3)])
    return t, a, g, (float(t[0]), float(t[-1])), dropped


def _level(a: np.ndarray) -> np.ndarray:
    """The smallest rotation taking the mean of ``a`` onto +z (Rodrigues)."""
    m = a.mean(axis=0)
    u = m / np.linalg.norm(m)
    z = np.array([0.0, 0.0, 1.0])
    v, c = np.cross(u, z), float(u @ z)
    if c < -1 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)


def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    """A centred moving average over ``n`` samples, per column (edges padded)."""
    if n <= 1:
        return x
    pad = np.pad(x, ((n // 2, n - 1 - n // 2), (0, 0)), mode="edge")
    c = np.cumsum(np.vstack([np.zeros((1, x.shape[1])), pad]), axis=0)
    return (c[n:] - c[:-n]) / n


def _principal_axis(h: np.ndarray, wts: np.ndarray) -> tuple[float, float, float]:
    """Angle (rad) of the weighted principal axis of the horizontal force ``h`` (n, 2),
    the weighted mean square along it and the ratio of the two axes' (its clarity)."""
    cov = (h * wts[:, None]).T @ h
    vals, vecs = np.linalg.eigh(cov)
    mean_sq = float(vals[1] / max(wts.sum(), 1e-12))
    return float(math.atan2(vecs[1, 1], vecs[0, 1])), mean_sq, float(vals[1] / max(vals[0], 1e-12))


#: A window's heading is kept if its straight-line force along the axis has at least this
#: share of the whole drive's mean square and its axis is this clear (ratio of the axes'):
#: a window of cruising holds no direction of its own and takes its neighbours'.
WINDOW_MIN_SHARE, WINDOW_MIN_RATIO = 0.2, 4.0


def _heading(t, h, r, window_s: float) -> np.ndarray:
    """The forward axis's angle (rad) at every sample, modulo pi (see the module)."""
    wts = np.exp(-((r / STRAIGHT_YAW_RATE) ** 2))
    whole, whole_sq, _ = _principal_axis(h, wts)
    if window_s <= 0 or window_s >= t[-1] - t[0]:
        return np.full(t.size, whole)
    step = window_s / 4
    centres: list[float] = []
    angles: list[float] = []
    for c in np.arange(t[0] + window_s / 2, t[-1] - window_s / 2 + step, step):
        m = np.abs(t - c) <= window_s / 2
        if wts[m].sum() < 1:
            continue
        ang, sq, ratio = _principal_axis(h[m], wts[m])
        if sq < WINDOW_MIN_SHARE * whole_sq or ratio < WINDOW_MIN_RATIO:
            continue
        ref = angles[-1] if angles else whole
        ang += math.pi * round((ref - ang) / math.pi)  # the axis has no sign: nearest
        centres.append(c)
        angles.append(ang)
    if not angles:
        return np.full(t.size, whole)
    return np.interp(t, centres, angles)


def import_recording(rec: Recording, frame: str, *, rate_hz: float = 100.0,
                     start_s: float = 0.0, end_s: float = 0.0, window_s: float = 20.0,
                     axes: str = "x,y,z", bias_tau_s: float = BIAS_TAU_S,
                     vibration_hz: float = VIBRATION_HZ):  # fmt: skip
    """``rec`` in the vehicle frame at the head, conditioned (the module's four steps):
    ``(Telemetry, ImportReport)``."""
    if frame not in FRAMES:
        raise RecordingError(f"invalid value at --frame: {frame!r}; allowed: {', '.join(FRAMES)}")
    if not (math.isfinite(rate_hz) and 20 <= rate_hz <= 1000):
        raise RecordingError(f"invalid value at --rate-hz: {rate_hz!r}; allowed: 20..1000 Hz")
    if not (math.isfinite(window_s) and window_s >= 0):
        raise RecordingError(f"invalid value at --window-s: {window_s!r}; allowed: >= 0 s (0: one)")
    t, a, g, trimmed, dropped = _grid(rec, rate_hz, start_s, end_s)
    report = ImportReport(frame=frame, trimmed=trimmed)
    if dropped:
        report.notes.append(f"{dropped} repeated samples (the same time twice) dropped")
    if frame == "vehicle":
        rot = np.zeros((3, 3))
        for k, tok in enumerate(_columns(axes, "--axes")):
            sg, name = (-1.0, tok[1:]) if tok.startswith("-") else (1.0, tok.lstrip("+"))
            if name not in ("x", "y", "z"):
                raise RecordingError(
                    f"invalid value at --axes: {axes!r}; allowed: each of x, y, z once, with an "
                    "optional sign (x,-y,-z: forward-right-down)"
                )
            rot["xyz".index(name), k] = sg  # the device's axis k is the car's axis
        if np.any(np.abs(rot).sum(axis=1) != 1):
            raise RecordingError(f"invalid value at --axes: {axes!r}; allowed: x, y, z once each")
        f, w = a @ rot.T, g @ rot.T
    else:
        if frame == "device":
            lev = _level(a)
            report.tilt_deg = math.degrees(math.acos(min(1.0, lev[2, 2])))
            a, g = a @ lev.T, g @ lev.T
        else:
            m = a.mean(axis=0)
            report.tilt_deg = math.degrees(math.acos(min(1.0, abs(m[2]) / np.linalg.norm(m))))
        n = max(1, int(round(HEADING_SMOOTH_S * rate_hz)))  # the heading from slow motion
        a_s, g_s = _smooth(a, n), _smooth(g, n)
        r = g_s[:, 2]
        psi = np.zeros(t.size)
        if frame == "earth":  # turn the horizontal axes back with the car's yaw
            psi = np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * np.diff(t))])
        c, s = np.cos(psi), np.sin(psi)
        h = np.column_stack([c * a_s[:, 0] + s * a_s[:, 1], -s * a_s[:, 0] + c * a_s[:, 1]])
        phi = _heading(t, h, r, window_s if frame != "device" else 0.0) + psi
        lat = -np.sin(phi) * a_s[:, 0] + np.cos(phi) * a_s[:, 1]
        cov = float(np.mean((lat - lat.mean()) * (r - r.mean())))
        if cov < 0:  # a left turn pushes left: the lateral axis's sign
            phi = phi + math.pi
        cphi, sphi = np.cos(phi), np.sin(phi)

        def turn(x):
            return np.column_stack(
                [cphi * x[:, 0] + sphi * x[:, 1], -sphi * x[:, 0] + cphi * x[:, 1], x[:, 2]]
            )

        f, w = turn(a), turn(g)
        fs = turn(a_s)
        lat_s = fs[:, 1]
        report.lateral_yaw_corr = float(np.corrcoef(lat_s, r)[0, 1])
        straight = np.abs(r) < STRAIGHT_YAW_RATE
        if straight.sum() > 10:
            hx = fs[straight, 0] - fs[straight, 0].mean()
            hy = lat_s[straight] - lat_s[straight].mean()
            report.straight_lateral_share = float((hy @ hy) / max(hx @ hx + hy @ hy, 1e-12))
        deg = np.degrees(np.mod(phi - psi + math.pi, 2 * math.pi) - math.pi)
        report.heading_deg = (float(deg.min()), float(deg.max()))
    if bias_tau_s or vibration_hz:
        try:
            cond = InputConditioner(1.0 / rate_hz, bias_tau_s, vibration_hz)
        except ValueError as exc:
            raise RecordingError(f"invalid value at --bias-tau-s/--vibration-hz: {exc}") from None
        f, w = cond.run(f, w)
        report.notes.append(
            f"conditioned: bias time constant {bias_tau_s:g} s, vibration low-pass "
            f"{vibration_hz:g} Hz (controllers.conditioning)"
        )
    tel = Telemetry(t=t - t[0], f=f, w=w, source=rec.source)
    return tel, report
