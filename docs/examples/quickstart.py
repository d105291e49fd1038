"""simpro-sim from Python: run, read, plot, compare and sweep.

Run it from any folder::

    python docs/examples/quickstart.py [OUT_DIR]

It writes its figures and a small sweep file into OUT_DIR (default: a new
temporary folder) and nothing anywhere else. ``tests/test_api.py`` runs it.
"""

import sys
import tempfile
from pathlib import Path

import simpro_mj as s

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="simpro-"))
out.mkdir(parents=True, exist_ok=True)

# 1. One run: the shipped 3 deg pitch step (the paper's Fig. 16), shortened to 5 s
#    (it settles in about 1.5 s; a run that ends before is "not_settled").
#    Overrides are dotted keys, the command line's --set.
r = s.run("step_pitch", {"duration_s": 5.0})
pitch = r.metrics["axes"]["pitch"]
print(
    f"step_pitch: {r.status}, overshoot {pitch['overshoot_pct']:.1f} %, "
    f"settling {pitch['settling_time_s']} s"
)
t, y = r.columns["time_s"], r.columns["pitch_rad"]  # the 1 ms log, SI units
print(f"pitch at t = {t[-1]:.1f} s: {y[-1] * 57.29578:.3f} deg")
r.plot("task_space", out / "step_pitch.png")  # Fig. 16's layout; a matplotlib Figure

# 2. The scenario is data: read it, change it, run it.
scenario = s.load_scenario("step_pitch", {"duration_s": 2.0})  # typed, validated
print(f"K K_I per axis: {scenario.controller.outer.gains}")
slower = s.run(scenario, {"controller.outer.gains": [2.0, 2.0, 2.0]})
print(f"K K_I = 2: overshoot {slower.metrics['axes']['pitch']['overshoot_pct']:.1f} %")

# 3. Joint-only against task-space control, same plant and seed (Fig. 15).
both = s.compare("step_pitch", {"duration_s": 2.0})
for mode, res in both.items():
    err = res.metrics["axes"]["pitch"]["steady_state_error"]
    print(f"{mode}: pitch steady-state error {err * 57.29578:.4f} deg")

# 4. A sweep: a scenario file with a sweep block, one run per variant.
sweep_file = out / "gains.yaml"
sweep_file.write_text(
    "name: gains\n"
    "duration_s: 3.0\n"
    "setpoint:\n  pitch_deg:\n    - {type: step, time_s: 0.2, value: 3.0}\n"
    "sweep:\n  grid:\n    controller.outer.gains: [2, 3]   # K K_I on every axis\n"
)
swept = s.sweep(sweep_file)
for row in swept.rows():
    print(row["variant"], row["status"], f"pitch overshoot {row['pitch_overshoot_pct']:.1f} %")

try:  # pandas is optional (pip install "simpro-sim[frame]")
    frame = r.to_frame()
    print(frame[["pitch_ref_rad", "pitch_rad"]].describe().loc[["min", "max"]])
except ImportError:
    pass
print(f"figures in {out}")
