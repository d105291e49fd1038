"""The behaviour lock of the shipped scenarios: ``reference_metrics.json``.

Per shipped co-simulation scenario (:data:`SCENARIOS`) the file stores

* ``metrics``: the metrics document of :func:`simpro_mj.analysis.metrics.compute_metrics`;
* ``sim``: the deterministic part of ``SimResult.sim`` (steps, worst loop closure);
* ``stats``: per logged column its mean, RMS, minimum, maximum and final value
  over the full 1 ms series;
* ``samples``: the compared columns sampled every :data:`SAMPLE_EVERY_S`;

and, under ``bits``, per machine fingerprint (:mod:`simpro_mj.report.machine`) the
SHA-256 of every logged column's raw float64 bytes.

``tests/test_reference_metrics.py`` compares a new run with the stored figures
at the tolerances of :data:`COLUMN_TOL` on any machine, and bit for bit where
the machine's fingerprint has an entry under ``bits``.

Run from the repository root::

    python tests/data/make_reference.py            # after an intended, reviewed
                                                   # change of behaviour: everything
                                                   # anew, other machines' bits dropped
    python tests/data/make_reference.py --add-bits # this machine's bits, after
                                                   # checking it agrees with the file
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import re
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
OUT = Path(__file__).resolve().parent / "reference_metrics.json"

#: The shipped co-simulation scenarios of ``scenarios/`` that are locked.
SCENARIOS = ("step_all", "step_heave", "step_pitch", "step_roll", "track_cues", "track_sines")

#: Period of the stored samples (s). The comparison is pointwise at these
#: instants and, through ``stats``, over the whole 1 ms series.
SAMPLE_EVERY_S = 0.2

# ---------------------------------------------------------------- tolerances
#
# What differs between two machines is the last bit of a floating-point
# operation (numpy's SIMD dispatch, MuJoCo's code paths, FMA). The closed loop
# feeds back quantised sensors, so such a difference can flip one ADC count,
# which the stable loop then damps: the runs stay close, not identical.
#
# Measured on the shipped scenarios (MuJoCo 4.0.0, numpy 2.4.6), largest
# pointwise difference over all five runs:
#
# | perturbation                              | roll/pitch  | heave, q_i  | pressures |
# |-------------------------------------------|-------------|-------------|-----------|
# | payload mass x (1 + 1e-12) ("last bits")  | 2.4e-6 rad  | 1.4e-6 m    | 14 Pa     |
# | payload mass x (1 + 1e-8)                 | 8.2e-6 rad  | 6.1e-6 m    | 36 Pa     |
# | payload mass x 1.01 (a real change)       | 1.1e-4 rad  | 9.7e-5 m    | 850 Pa    |
#
# and the metrics of an AVX-512 machine against an AVX2 one differed by at
# most 1.9e-6 rad·s (IAE) and 1.4e-6 m (max error), between the 1e-12 and the
# 1e-8 rows. The tolerances pass every scenario under the 1e-12, 1e-10 and
# 1e-8 perturbations (a margin of 10^8 over a difference in the last bit) and
# fail every scenario, with 58 to 72 differences each, under the 1 % one:
#
# * angles: 2e-5 rad (0.0011 deg), the IMU's steady-state floor (0.005 deg RMS
#   noise averaged over 1 s at 200 Hz, times 3: 1.9e-5 rad);
# * lengths: 1e-5 m, one count of the 10 um height encoder, a sixth of one
#   potentiometer count (1.22 mV at 20 V/m: 61 um);
# * pressures: 100 Pa (1 mbar, 0.03 % of the 3-4 bar chamber pressures; a
#   force of 1.2 N on the 125 mm piston);
# * forces: 2 N (0.04 % of the 5330 N the legs hold at rest; the Coulomb
#   friction's tanh(v / 5 mm/s) turns a 1 um/s velocity difference into 4 mN);
# * measured (quantised) signals: one quantisation step more than the true
#   signal's tolerance, since a true difference below the step can flip at
#   most one count;
# * set-points (:data:`SET_POINT_COLUMNS`): functions of time only, 1e-12.
#
# The step's arithmetic (simpro_mj.sim.step) calls libm (atan2, tanh, cos,
# sin) and sums in a fixed order. Numpy's SIMD kernels and BLAS products in
# their place, a last-bit change of every step, move the series by at most
# 0.86 of these tolerances (one potentiometer count in q_meas, 4.6 um in q,
# 78 Pa, 1.5 N), as the last-bit perturbations above do.
#
# The valve voltages are not compared pointwise: one potentiometer count
# times k_p moves them by 0.015 V in every perturbation above, the same as a
# real change does; they are covered by the bit check and by the pose they
# produce.

ANGLE_TOL = 2e-5
LENGTH_TOL = 1e-5
PRESSURE_TOL = 100.0
FORCE_TOL = 2.0
POT_LSB_M = 2 * 10.0 / 2**14 / 20.0  # 14 bits over +-10 V, 20 V/m: 61 um
ENCODER_LSB_M = 1e-5
EXACT_TOL = 1e-12
#: Columns that are functions of time only (the scenario's set-points and faults).
SET_POINT_COLUMNS = (
    "time_s", "roll_ref_rad", "pitch_ref_rad", "heave_ref_m", "supply_pa", "fault_flags",
)  # fmt: skip
#: The pose column of each task axis.
POSE_COLUMNS = {"roll": "roll_rad", "pitch": "pitch_rad", "heave": "heave_m"}


def column_tolerance(col: str) -> float | None:
    """Absolute tolerance of a logged column (SI), None if not compared."""
    if col in SET_POINT_COLUMNS:
        return EXACT_TOL
    if col.startswith("u") and col.endswith("_v"):
        return None
    if col.endswith("_rad"):
        return ANGLE_TOL
    if col == "heave_meas_m":
        return ENCODER_LSB_M + LENGTH_TOL
    if col.endswith("_meas_m"):
        return POT_LSB_M + LENGTH_TOL
    if col == "loop_closure_m":
        return 1e-9  # a constraint residual: 1 nm is nothing physical
    if col.endswith("_m"):
        return LENGTH_TOL
    if col.endswith("_pa"):
        return PRESSURE_TOL
    if col.endswith("_n"):
        return FORCE_TOL
    raise KeyError(f"no tolerance stated for logged column {col!r}: add it to column_tolerance")


def axis_tolerance(axis: str) -> float:
    return LENGTH_TOL if axis == "heave" else ANGLE_TOL


def metric_tolerance(axis: str, key: str, metrics_axis: dict, duration_s: float) -> float | None:
    """Tolerance of one step/tracking metric, derived from the series' tolerance.

    A pointwise difference of at most ``e`` between two responses bounds the
    difference of their maximum error, RMS error and steady-state error by
    ``e``, of their IAE by ``e`` times the duration, and of their overshoot by
    ``100 e / |step|`` percent. Times (rise, settling) have no such bound —
    a response that grazes the band edge can move its settling time by an
    oscillation period. The rise time is compared at 20 ms (measured spread
    between two CPUs: 1e-6 s); the settling time by :func:`settling_windows`.
    """
    e = axis_tolerance(axis)
    if key in ("max_abs_error", "rms_error", "steady_state_error"):
        return e
    if key == "steady_state_error_measured":
        return e + (ENCODER_LSB_M if axis == "heave" else 0.0)
    if key == "iae":
        return e * duration_s
    if key == "overshoot_pct":
        step = (metrics_axis.get("step") or {}).get("reference_change") or 0.0
        return 100.0 * e / abs(step) if step else None
    if key == "rise_time_s":
        return 0.02
    return None


def settling_windows(res, metrics: dict) -> dict:
    """Per stepped axis, where the settling time of a response within tolerance can fall.

    The settling time is the last exit of ``|y - y_final|`` from the band. For
    a response that differs by at most ``e`` at every instant (and so its
    final mean by at most ``e``), that exit lies between the last exit of this
    response from the band widened by ``2 e`` and from the band narrowed by
    ``2 e``, computed here on the full 1 ms series. A clean crossing gives a
    window of milliseconds; a response that grazes the band edge, one that
    spans the graze.
    """
    from simpro_mj.analysis.metrics import final_window

    t = np.asarray(res.columns["time_s"])
    out = {}
    for axis, col in POSE_COLUMNS.items():
        m = metrics["axes"].get(axis, {})
        step = m.get("step") or {}
        band, t_step = step.get("settling_band"), step.get("time_s")
        if band is None or t_step is None or m.get("settling_time_s") is None:
            continue
        y = np.asarray(res.columns[col])
        t0, _ = final_window(t)
        dev = np.abs(y - y[t >= t0].mean())
        after = t >= t_step
        e = 2 * axis_tolerance(axis)

        def last_exit(b: float, dev=dev, after=after, t_step=t_step) -> float:
            out_ = np.flatnonzero(after & (dev > b))
            return float(t[min(out_[-1] + 1, t.size - 1)]) - t_step if out_.size else 0.0

        out[axis] = [last_exit(band + e) - 1e-3, last_exit(max(band - e, 0.0)) + 1e-3]
    return out


# ---------------------------------------------------------------- runs


def run_scenario(name: str):
    """Run one shipped scenario: ``(scenario, SimResult, metrics as stored)``."""
    sys.path.insert(0, str(ROOT))
    from simpro_mj.analysis.metrics import compute_metrics
    from simpro_mj.analysis.verdict import verdict
    from simpro_mj.config.scenario import load_scenario
    from simpro_mj.sim.build import simulate

    scenario = load_scenario(name)
    res = simulate(scenario)
    metrics = compute_metrics(res.columns, res.scenario)
    # the run's status as simpro-sim run reports it: a run to its end judged by its end
    metrics["status"] = (
        verdict(res.columns, res.sensor_floor)["status"] if res.status == "ok" else res.status
    )
    return scenario, res, json.loads(json.dumps(metrics))  # the stored float/None forms


def sample_every(res) -> int:
    dt = float(res.columns["time_s"][1] - res.columns["time_s"][0])
    return max(1, round(SAMPLE_EVERY_S / dt))


def digest(res) -> dict:
    """``stats``, ``samples`` and ``bits`` of one run."""
    k = sample_every(res)
    stats, samples, bits = {}, {}, {}
    for col, v in res.columns.items():
        v = np.ascontiguousarray(v, dtype=np.float64)
        bits[col] = hashlib.sha256(v.tobytes()).hexdigest()
        if column_tolerance(col) is None:
            continue
        stats[col] = {
            "mean": float(v.mean()),
            "rms": float(math.sqrt(float(np.dot(v, v)) / v.size)),
            "min": float(v.min()),
            "max": float(v.max()),
            "final": float(v[-1]),
        }
        samples[col] = [float(f"{x:.13g}") for x in v[::k]]  # 13 digits: < 1e-13 rel
    return {"stats": stats, "samples": samples, "bits": bits}


def entry(name: str) -> tuple[dict, dict]:
    """The stored entry of one scenario and its column hashes."""
    _, res, metrics = run_scenario(name)
    d = digest(res)
    return (
        {
            "sample_every_s": SAMPLE_EVERY_S,
            "metrics": metrics,
            "settling_windows": settling_windows(res, metrics),
            "sim": {
                "steps": res.sim["steps"],
                "max_loop_closure_error_m": res.sim["max_loop_closure_error_m"],
            },
            "stats": d["stats"],
            "samples": d["samples"],
        },
        d["bits"],
    )


def dumps(doc: dict) -> str:
    """JSON with one line per value, a list of numbers on one line (diffable, compact)."""
    text = json.dumps(doc, indent=1, sort_keys=True)
    return re.sub(r"\[\s*([-0-9.eE+,\s]+?)\s*\]", lambda m: "[" + "".join(m[1].split()) + "]", text)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--add-bits",
        action="store_true",
        help="add this machine's column hashes to the existing file (behaviour unchanged)",
    )
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from simpro_mj.report.machine import fingerprint_id, machine_fingerprint

    fp = machine_fingerprint()
    fid = fingerprint_id(fp)
    results = {name: entry(name) for name in SCENARIOS}
    bits = {name: b for name, (_, b) in results.items()}
    if args.add_bits:
        doc = json.loads(OUT.read_text(encoding="utf-8"))
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from test_reference_metrics import differences

        for name, (got, _) in results.items():
            bad = differences(got, doc["scenarios"][name])
            if bad:
                print(f"{name}: this machine disagrees with the file: {bad[:3]}", file=sys.stderr)
                return 1
    else:
        import mujoco

        doc = {
            "generated_with": {"numpy": np.__version__, "mujoco": mujoco.__version__},
            "sample_every_s": SAMPLE_EVERY_S,
            "scenarios": {name: e for name, (e, _) in results.items()},
            "bits": {},
        }
    doc["bits"][fid] = {"fingerprint": fp, "scenarios": bits}
    OUT.write_text(dumps(doc), encoding="utf-8")
    print(f"wrote {OUT} (bits for machine {fid})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
