"""Writing a run's results folder, atomically, and printing its summary.

A results folder holds:

* ``timeseries.csv``: one row per logged sample, a header of column names
  with their units (``time_s``, ``roll_rad``, ``p1a_pa``, ...), SI values with
  12 significant digits;
* ``metrics.json``: ``status`` (ok | limit_cycle | not_settled | diverged |
  interrupted), ``reason``, the scenario's
  name and hash, ``axes`` and ``joints`` (:func:`simpro_mj.analysis.metrics.compute_metrics`),
  the metric ``definitions``, a ``sim`` block (deterministic figures, with the
  wall-clock ones such as ``realtime_factor`` apart under ``sim.wall_clock``)
  and ``versions``;
* ``scenario.yaml``: the resolved scenario (loads back to the same hash);
* the PNG figures of :func:`simpro_mj.report.plots.plot_run`;
* ``PARTIAL`` (only for status ``interrupted``): one line saying the run was
  stopped before its end and how far it got;
* ``.simpro-result`` (:data:`RESULT_MARKER`): one JSON line ``{"kind": "run",
  "simpro-sim": version, "files": {name: {size, sha256}}}`` listing what
  simpro-sim wrote, so that it replaces the folder only while nothing else is
  in it (the write rule of :mod:`simpro_mj.report.folders`).

Where and how the folder is written (whose it is, the lock, the atomic install,
what *complete* means): :mod:`simpro_mj.report.folders`.
"""

from __future__ import annotations

import json
import math
import os
import platform
import sys
import warnings
from collections.abc import Mapping
from dataclasses import asdict, is_dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import yaml

from simpro_mj import __version__
from simpro_mj.analysis.verdict import FINISHED_STATUSES
from simpro_mj.config.models import Scenario, as_tree
from simpro_mj.config.scenario import scenario_hash
from simpro_mj.core.cache import file_digest
from simpro_mj.core.shipped import model_path
from simpro_mj.plant import kernels
from simpro_mj.report.folders import install_folder, locked, partial_sibling
from simpro_mj.report.machine import dist_version, fingerprint_id
from simpro_mj.report.marker import PARTIAL_MARKER, TIMESERIES_WRITTEN, is_complete

#: ``ok``: ran to the end and settled; ``limit_cycle`` / ``not_settled``: ran to
#: the end, but the pose still oscillates or drifts there
#: (:mod:`simpro_mj.analysis.verdict`); ``diverged``: stopped by the divergence
#: checks (the folder holds everything up to that point); ``interrupted``:
#: stopped by the user (Ctrl-C, SIGTERM), marked with a ``PARTIAL`` file.
STATUSES = (*FINISHED_STATUSES, "interrupted")
#: ``extra["sim"]`` keys that depend on the machine, not on the scenario.
WALL_CLOCK_KEYS = (
    "realtime_factor",
    "wall_time_s",
    "wall_s",
    "elapsed_s",
    "steps_per_s",
    "host",
    # the compiled step loaded before the clock started (simpro_mj.sim.compiling)
    "kernel_load_s",
    "kernel_compiled",
)
_RESERVED = {"status", "reason", "scenario", "axes", "joints", "metrics", "sim", "versions"}


def versions(resolved: Mapping | None = None) -> dict:
    """Versions of simpro-sim and its numerical dependencies (and the scenario hash)."""
    model = model_path()
    out = {
        "simpro-sim": __version__,
        "mujoco": dist_version("mujoco"),
        "numpy": np.__version__,
        "python-control": dist_version("control"),
        "python": platform.python_version(),
        "kernels": kernels.kernel_label(),  # what ran: pneumatics + sensors
        # what the environment chose: SIMPRO_KERNEL as set (docs/performance.md), and the
        # MJCF compiled (SIMPRO_MODEL, else the shipped one) with the digest of its bytes
        "SIMPRO_KERNEL": os.environ.get("SIMPRO_KERNEL", "auto"),
        "model": {"file": str(model), "sha256": file_digest(model)},
        # results are bit-identical only under one fingerprint (simpro_mj.report.machine)
        "machine": fingerprint_id(),
    }
    if resolved is not None:
        out["scenario_hash"] = scenario_hash(resolved)
    return out


def jsonable(obj: Any) -> Any:
    """Plain JSON types: numpy scalars/arrays converted, NaN and inf as null, a typed
    record by its ``to_json()``, else a dataclass by its fields."""
    if callable(getattr(obj, "to_json", None)):
        return jsonable(obj.to_json())
    if is_dataclass(obj) and not isinstance(obj, type):
        return jsonable(asdict(obj))
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if math.isfinite(x) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj


#: ``timeseries.csv``'s number format (12 significant digits: a 1 mm stroke
#: to 1e-15 m, a 6 bar pressure to 1 µPa; every logged value round-trips to
#: well below its sensor's resolution)
NUMBER_FORMAT = "%.12g"


#: rows formatted by one ``%`` (a block's lines at once: the per-row calls of
#: ``numpy.savetxt`` cost a third of its time; a larger block only holds more
#: Python floats at once)
ROWS_PER_FORMAT = 256


def write_timeseries(path, columns: Mapping[str, np.ndarray]) -> Path:
    """Write columns as CSV: header of names, :data:`NUMBER_FORMAT` values, as
    ``numpy.savetxt`` writes them, byte for byte: each value ``NUMBER_FORMAT % x``
    of its Python float, :data:`ROWS_PER_FORMAT` rows to one ``%``.

    Raises
    ------
    ValueError
        If the columns differ in length, are not 1-D, or a name contains a comma.
    """
    path = Path(path)
    names = list(columns)
    if "time_s" in names:  # time first
        names.remove("time_s")
        names.insert(0, "time_s")
    for name in names:
        if "," in name or "\n" in name:
            raise ValueError(f"column name {name!r} cannot go into a CSV header")
    arrays = [np.asarray(columns[n], dtype=float) for n in names]
    lengths = {a.shape for a in arrays}
    if len(lengths) > 1 or (arrays and arrays[0].ndim != 1):
        shapes = {n: a.shape for n, a in zip(names, arrays, strict=True)}
        raise ValueError(f"columns must be 1-D and of equal length, got {shapes}")
    data = np.column_stack(arrays) if arrays else np.empty((0, 0))
    line = ",".join([NUMBER_FORMAT] * data.shape[1]) + "\n"
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(",".join(names) + "\n")
        for i in range(0, data.shape[0] if data.size else 0, ROWS_PER_FORMAT):
            block = data[i : i + ROWS_PER_FORMAT]
            fh.write((line * block.shape[0]) % tuple(block.ravel().tolist()))
    return path


#: Largest ``timeseries.csv`` read back (bytes): an hour at 1 kHz is about 1 GB.
MAX_TIMESERIES_BYTES = 2_000_000_000
#: Longest header line of a ``timeseries.csv`` (characters).
MAX_HEADER_CHARS = 100_000


def read_timeseries(path, required=()) -> dict[str, np.ndarray]:
    """Read a ``timeseries.csv`` back into columns, validated as an input.

    Opened without blocking, a regular file of at most
    :data:`MAX_TIMESERIES_BYTES` (:mod:`simpro_mj.core.safe_files`); the header
    must name distinct columns, among them ``time_s`` and every name in
    ``required``; every row must hold one finite-or-NaN number per column.

    Raises
    ------
    UserInputError
        One line naming the file and what is wrong.
    """
    from simpro_mj.core.errors import UserInputError
    from simpro_mj.core.safe_files import open_regular

    path = Path(path)
    allowed = "allowed: a timeseries.csv written by simpro-sim run"
    with open_regular(path, MAX_TIMESERIES_BYTES, "timeseries", binary=True) as fh:
        head = fh.readline(MAX_HEADER_CHARS + 1)
        names = head.decode("utf-8", "replace").strip().split(",")
        missing = [n for n in ("time_s", *required) if n not in names]
        if len(head) > MAX_HEADER_CHARS or len(set(names)) != len(names) or missing:
            what = f"missing columns {missing}" if missing else "a malformed header"
            raise UserInputError(f"unreadable result at {path}: {what}; {allowed}")
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # an empty body: handled below
                data = np.loadtxt(fh, delimiter=",", ndmin=2, dtype=float)
        except ValueError as exc:
            text = " ".join(str(exc).split())[:160]
            raise UserInputError(f"unreadable result at {path}: {text}; {allowed}") from None
    if data.size == 0:
        return {n: np.empty(0) for n in names}
    if data.shape[1] != len(names):
        raise UserInputError(
            f"unreadable result at {path}: {data.shape[1]} values per row for {len(names)} "
            f"columns; {allowed}"
        )
    return {n: data[:, i] for i, n in enumerate(names)}


def _sim_block(sim: Mapping | None) -> dict:
    sim = dict(sim or {})
    wall = dict(sim.pop("wall_clock", {}) or {})
    wall.update({key: sim.pop(key) for key in list(sim) if key in WALL_CLOCK_KEYS})
    sim["wall_clock"] = wall
    # metrics.json's first layout named sim.realtime_factor; it is a wall-clock figure, so it
    # is also kept under sim.wall_clock with the others (compare runs without both)
    if "realtime_factor" in wall:
        sim["realtime_factor"] = wall["realtime_factor"]
    return sim


def write_results(
    out_dir,
    columns: Mapping[str, np.ndarray],
    metrics: Mapping,
    scenario: Scenario | Mapping,
    extra: Mapping | None = None,
    arrays: Mapping[str, Mapping[str, np.ndarray]] | None = None,
) -> Path:
    """Write a complete results folder atomically and return its path.

    Parameters
    ----------
    out_dir : path
        The folder to create (replaced if it exists; its parent is created).
    columns : mapping of str to ndarray
        Logged time series, SI, names with units (``time_s``, ``roll_rad``, ...).
    metrics : mapping
        :func:`simpro_mj.analysis.metrics.compute_metrics` output.
    scenario : Scenario or mapping
        The resolved scenario, typed or its dict.
    extra : mapping, optional
        ``status`` (one of :data:`STATUSES`; default ``metrics["status"]``, else
        "ok"), ``reason`` (why it diverged or stopped; default ``metrics["reason"]``),
        ``sim`` (figures of the simulation: steps, physics step, ...; wall-clock
        keys go to ``sim.wall_clock``), ``plots`` (False: no PNGs). Any other
        key is copied into ``metrics.json`` as is; ``timeseries_written`` False
        (:data:`~simpro_mj.report.marker.TIMESERIES_WRITTEN`, a batch's
        ``--timeseries``) leaves ``timeseries.csv`` (and a cueing run's
        ``perceived.csv``) out, and the folder is complete without it
        (:func:`~simpro_mj.report.marker.is_complete`).
    arrays : mapping, optional
        File name -> named arrays, each written with ``numpy.savez`` (stored: joint
        angles sampled finely deflate by only about a sixth, for six times the time)
        (``qpos.npz``: the recorded joint positions that ``simpro-sim render`` replays).

    Returns
    -------
    Path
        Where the folder went (absolute): ``out_dir``, or for an interrupted
        run whose ``out_dir`` holds a complete result, ``<out_dir>.partial``.

    Raises
    ------
    UserInputError
        If ``out_dir`` exists and is not a folder, is not simpro-sim's to
        replace, or is being written by another process.
    ValueError
        Unknown status, or unequal column lengths.
    """
    return write_folder(out_dir, columns, metrics, scenario, extra, arrays)[0]


def _plain_text(data) -> bool:
    """Every string of ``data`` (keys and values, nested) printable ASCII, non-empty."""
    if isinstance(data, str):
        return bool(data) and data.isascii() and data.isprintable()
    if isinstance(data, dict):
        return all(_plain_text(k) and _plain_text(v) for k, v in data.items())
    if isinstance(data, list):
        return all(_plain_text(v) for v in data)
    return True


def dump_yaml(data, fh: TextIO) -> None:
    """``yaml.safe_dump(data, fh, sort_keys=False, default_flow_style=None)``, byte for
    byte, by libyaml's emitter where that gives the same text.

    PyYAML's pure-Python emitter costs about 0.1 s of CPU for a resolved scenario,
    a third of a 15 s run's stepping; libyaml's (``yaml.CSafeDumper``, the same
    representer) a tenth of that. The two quote and fold double-quoted strings (text
    with escapes: non-ASCII, control characters) and empty keys differently, so a tree
    with such a string is written by the pure-Python emitter. On plain text they agree
    (``tests/test_results_yaml.py``: every shipped scenario and sweep variant, and
    random trees of printable ASCII).
    """
    fast = getattr(yaml, "__with_libyaml__", False) and _plain_text(data)
    dumper: type = yaml.CSafeDumper if fast else yaml.SafeDumper
    yaml.dump(data, fh, Dumper=dumper, sort_keys=False, default_flow_style=None)


def write_folder(out_dir, columns, metrics, scenario, extra=None, arrays=None) -> tuple[Path, dict]:
    """:func:`write_results`, returning where the folder went and the ``metrics.json``
    document as written (JSON types), so that nothing reads the file back."""
    scenario = as_tree(scenario)  # the record of the scenario, typed or not
    extra = dict(extra or {})
    out_dir = Path(out_dir).expanduser().absolute()
    status = extra.pop("status", metrics.get("status", "ok"))
    if status not in STATUSES:
        raise ValueError(f"status must be one of {STATUSES}, got {status!r}")
    reason = extra.pop("reason", metrics.get("reason"))
    make_plots = bool(extra.pop("plots", True))
    doc: dict = {
        "status": status,
        "reason": reason,
        "scenario": {"name": scenario.get("name"), "hash": scenario_hash(scenario)},
        "axes": metrics.get("axes", {}),
        "joints": metrics.get("joints", {}),
        "metrics": {k: v for k, v in metrics.items() if k not in _RESERVED},
        "sim": _sim_block(extra.pop("sim", None)),
        "versions": versions(scenario),
    }
    for key, value in extra.items():
        doc[key if key not in _RESERVED else f"extra_{key}"] = value
    doc = jsonable(doc)

    def fill(tmp: Path) -> None:
        if status == "interrupted":
            (tmp / PARTIAL_MARKER).write_text(
                f"partial results: the run was interrupted ({reason}); "
                "see metrics.json (status interrupted)\n",
                encoding="utf-8",
            )
        series = doc.get(TIMESERIES_WRITTEN, True)  # false: not asked for (a batch's)
        if series:
            write_timeseries(tmp / "timeseries.csv", columns)
        if series and "head_fx_mps2" in columns and "veh_fx_mps2" in columns:
            # a cueing run: what the driver perceives, from the logged head signals
            from simpro_mj.analysis.cue_metrics import perceived_columns

            write_timeseries(tmp / "perceived.csv", perceived_columns(columns))
        for name, named in (arrays or {}).items():
            np.savez(tmp / name, **named)
        text = json.dumps(doc, indent=2, allow_nan=False)
        (tmp / "metrics.json").write_text(text + "\n", encoding="utf-8")
        with (tmp / "scenario.yaml").open("w", encoding="utf-8") as fh:
            fh.write(f"# resolved scenario, sha256 {doc['scenario']['hash']}\n")
            dump_yaml(jsonable(scenario), fh)
        if make_plots:
            # matplotlib only when figures are drawn (a run with --no-plots, the API)
            from simpro_mj.report.plots import plot_run

            plot_run(columns, scenario, tmp)

    with locked(out_dir):
        target = out_dir
        if status == "interrupted" and is_complete(out_dir):
            # never replace a complete result with a partial one: write it beside
            target = partial_sibling(out_dir)
        return install_folder(target, fill), doc


def _fmt(value, scale: float = 1.0, digits: int = 3, unit: str = "") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value * scale:.{digits}f}{unit}"


def print_summary(metrics: Mapping, out_dir=None, file: TextIO | None = None) -> None:
    """Print a short table of the figures per axis and where the files are.

    Parameters
    ----------
    metrics : mapping
        :func:`simpro_mj.analysis.metrics.compute_metrics` output or a loaded ``metrics.json``.
    out_dir : path, optional
        The results folder (listed if given).
    file : text stream, optional
        Default ``sys.stdout``.
    """
    file = sys.stdout if file is None else file
    axes = metrics.get("axes", {})
    status = metrics.get("status")
    if status:
        reason = metrics.get("reason")
        print(f"status: {status}" + (f" ({reason})" if reason else ""), file=file)
    cue = metrics.get("cueing") or (metrics.get("metrics") or {}).get("cueing")
    if cue and cue.get("channels"):
        # a cueing run: what the driver perceives, not a step response
        from simpro_mj.analysis.cue_summary import print_cue_summary

        print_cue_summary(cue, file=file)
        _list_files(out_dir, file)
        return
    header = f"{'axis':<6} {'ss error':>14} {'rise [s]':>9} {'settling [s]':>13} {'overshoot':>10}"
    print(header, file=file)
    print("-" * len(header), file=file)
    for axis, unit, scale in (
        ("roll", "deg", 180.0 / math.pi),
        ("pitch", "deg", 180.0 / math.pi),
        ("heave", "mm", 1e3),
    ):
        m = axes.get(axis)
        if not m:
            continue
        sse = _fmt(m.get("steady_state_error"), scale, 4, f" {unit}")
        over = _fmt(m.get("overshoot_pct"), 1.0, 1, " %")
        print(
            f"{axis:<6} {sse:>14} {_fmt(m.get('rise_time_s')):>9} "
            f"{_fmt(m.get('settling_time_s')):>13} {over:>10}",
            file=file,
        )
    window = metrics.get("final_window_s") or metrics.get("metrics", {}).get("final_window_s")
    if window:
        print(f"(ss error: mean of reference - true pose over {window[0]:.2f}..{window[1]:.2f} s)",
              file=file)  # fmt: skip
    _list_files(out_dir, file)


def _list_files(out_dir, file) -> None:
    if out_dir is not None:
        out_dir = Path(out_dir)
        listing = out_dir.iterdir() if out_dir.is_dir() else ()
        files = sorted(p.name for p in listing if not p.name.startswith("."))
        print(f"results: {out_dir}", file=file)
        if files:
            print("  " + ", ".join(files), file=file)
