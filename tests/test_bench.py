"""``simpro-sim bench``: structure and internal consistency.

No speed thresholds here: speed is what the command measures, on the machine
it runs on (docs/performance.md). These tests use short runs.
"""

from __future__ import annotations

import json
import math

import pytest

from simpro_mj.commands.bench import harness
from simpro_mj.commands.main import main
from simpro_mj.config.scenario import load_scenario
from simpro_mj.core.errors import UserInputError

#: benchmarks/step_cost.py, as the command loads it
bench = harness()
STAGES, measure = bench.STAGES, bench.measure


@pytest.fixture(scope="module")
def short():
    scenario = load_scenario("step_pitch", ["duration_s=0.5"]).model_dump()  # the harness's dict
    return measure(scenario, repeats=2, batch=False, run_durations=(0.6, 0.3))


def test_keys_and_consistency(short):
    r = short
    for key in ("bare_step_us", "full_step_us", "ratio", "realtime_factor", "stages_us",
                "throughput", "repeats", "machine", "interpreted_step_us"):  # fmt: skip
        assert key in r
    assert set(r["stages_us"]) == set(STAGES)
    assert r["timeseries_write_s"] > 0
    assert r["timeseries_rows"] == r["steps"] // r["logging_decimation"] + 1
    assert set(r["machine"]) >= {"cpu", "cores", "python", "mujoco", "numpy"}
    assert r["repeats"] == 2 and r["steps"] == 500
    assert r["throughput"] is None  # batch=False
    assert r["full_step_us"] > 0 and r["bare_step_us"] > 0
    assert math.isclose(r["ratio"], r["full_step_us"] / r["bare_step_us"], rel_tol=1e-12)
    assert math.isclose(r["realtime_factor"], 1e3 / r["full_step_us"], rel_tol=1e-12)
    ratio = r["interpreted_step_us"] / r["bare_step_us"]
    assert math.isclose(r["interpreted_ratio"], ratio, rel_tol=1e-12)
    # medians of the per-repeat samples
    assert r["full_step_us"] == pytest.approx(sum(r["samples"]["full_step_us"]) / 2)
    assert r["run_command_durations_s"] == [0.6, 0.3]
    assert len(r["samples"]["run_command_us"]) == 2
    assert math.isclose(r["run_command_ratio"], r["run_command_us"] / r["bare_step_us"])
    # the compiled run freezes MuJoCo's profiler clock: the like-for-like bare figure
    frozen = r["bare_frozen_clock_us"]
    assert frozen > 0 and len(r["samples"]["bare_frozen_clock_us"]) == 2
    assert math.isclose(r["ratio_frozen_clock"], r["full_step_us"] / frozen, rel_tol=1e-12)


def test_run_command_figure_is_null_when_the_scenario_cannot_last():
    """A ramp reachable over 0.5 s but not over 41 s: no run-command figure, said so."""
    scenario = load_scenario("step_pitch", [
        "duration_s=0.5", "setpoint.pitch_deg=[]",
        "setpoint.heave_mm=[{type: ramp, start_s: 0.2, end_s: 40, value: 400}]"])  # fmt: skip
    r = measure(scenario.model_dump(), repeats=1, batch=False)
    assert r["run_command_us"] is None and r["run_command_ratio"] is None
    table = bench.table

    assert "cannot last 41 s" in table(r)


def test_bare_replays_the_same_trajectory(short):
    """mj_step from the run's initial state with its recorded forces ends where the run did."""
    assert short["bare_same_trajectory"] is True


def test_stages_sum_within_the_instrumented_step(short):
    """The stages are timed inside one run: their sum cannot exceed that run's time per
    step (the remainder is the loop's own bookkeeping), and they cover most of it."""
    total = sum(short["stages_us"].values())
    instrumented = short["instrumented_step_us"]
    assert all(v > 0 for v in short["stages_us"].values())
    assert total <= instrumented * 1.0001
    assert total >= 0.5 * instrumented


@pytest.mark.slow  # the batch throughput runs the scenario 2 x 2 more times on threads
def test_cli_json_and_throughput(capsys):
    code = main(["bench", "--json", "--duration", "0.2", "--repeats", "1", "--batch-runs", "2"])
    assert code == 0
    r = json.loads(capsys.readouterr().out)
    tp = r["throughput"]
    assert set(tp) >= {"workers_1", "workers_2", "speedup"}
    assert tp["identical"] is True  # threaded runs equal a serial one bit for bit
    assert tp["workers_1"] > 0 and tp["workers_2"] > 0
    assert math.isclose(tp["speedup"], tp["workers_2"] / tp["workers_1"], rel_tol=1e-12)
    # bare mj_step's own scaling: the same replay on 1 and 2 threads
    assert tp["bare_workers_1"] > 0 and tp["bare_workers_2"] > 0
    assert math.isclose(tp["bare_speedup"], tp["bare_workers_2"] / tp["bare_workers_1"])
    assert all(s is None or 0.0 <= s <= 1.0 for s in tp["others_share"])


def test_human_table(capsys):
    assert main(["bench", "--duration", "0.1", "--repeats", "1", "--no-batch"]) == 0
    captured = capsys.readouterr()
    out = captured.out
    assert "bare mj_step" in out and "ratio full/bare" in out and "pneumatics" in out
    assert "clock frozen" in out
    assert "repeat 1/1" in captured.err  # progress, which --quiet silences
    assert main(["bench", "--duration", "0.1", "--repeats", "1", "--no-batch", "--quiet"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize(
    ("argv", "field"),
    [
        (["--repeats", "0"], "--repeats"),
        (["--repeats", "many"], "--repeats"),
        (["--duration", "-1"], "--duration"),
        (["--batch-runs", "0"], "--batch-runs"),
        (["--commands", "-3"], "--commands"),
    ],
)
def test_user_errors_are_one_line(argv, field, capsys):
    assert main(["bench", "--no-batch", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "\n" not in err and field in err


def test_separate_commands_time_whole_processes():
    """One pair of whole run commands (0.6 s and 0.3 s) after an untimed one: the
    per-step difference, wall and CPU, with their spread."""
    separate_commands = bench.separate_commands

    r = separate_commands("step_pitch", ["controller.mode=joint_only"], 1, [8.0, 10.0], (0.6, 0.3))
    assert r["pairs"] == 1 and r["durations_s"] == [0.6, 0.3]
    for key in ("wall_us", "cpu_us"):
        (x,) = r["samples"][key]
        assert r[key]["median"] == x and r[key]["range"] == [x, x]
    (long_s,), (short_s,) = r["samples"]["wall_s"]["0.6"], r["samples"]["wall_s"]["0.3"]
    assert r["min_us"] == pytest.approx((long_s - short_s) / 300 * 1e6)
    assert r["wall_us"]["median"] == pytest.approx(r["min_us"])  # one pair: the same
    # the median over the median bare sample, the fastest over the fastest
    assert r["ratio"] == pytest.approx(r["wall_us"]["median"] / 9.0)
    assert r["ratio_min"] == pytest.approx(r["min_us"] / 8.0)


def test_separate_commands_name_a_failing_command():
    separate_commands = bench.separate_commands

    with pytest.raises(UserInputError, match="the run command failed: .*no_such"):
        separate_commands("no_such_scenario", [], 1, [8.0], (0.6, 0.3))


def test_without_a_checkout_bench_refuses_in_one_line(tmp_path, monkeypatch, capsys):
    """An installed wheel carries no benchmarks/: bench names the folder it needs."""
    import simpro_mj.commands.bench as command

    monkeypatch.setattr(command, "HARNESS", tmp_path / "nowhere" / "step_cost.py")
    monkeypatch.delitem(command.sys.modules, command.HARNESS_MODULE)
    monkeypatch.chdir(tmp_path)
    assert main(["bench", "--duration", "0.1", "--repeats", "1", "--no-batch"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "step_cost.py" in err and "allowed: run it from a clone" in err


def _instructions_script():
    """benchmarks/step_instructions.py, loaded as a module."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "step_instructions.py"
    spec = importlib.util.spec_from_file_location("step_instructions", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_counted_replay_is_the_runs_trajectory(tmp_path, capsys):
    """The instruction count's bare replay (run natively here, not under valgrind) ends
    exactly where the recorded run did, at its full length and not before: the model it
    replays on carries the scenario's options (the seals' dry friction)."""
    script = _instructions_script()
    forces = str(tmp_path / "forces.npz")
    assert script.main(["--child", "record", "--duration", "0.3", "--forces", forces]) == 0
    script._frozen_clock(forces + ".clock.so")
    runs = [("bare", 0.3, True), ("bare", 0.2, None), ("bare_frozen_clock", 0.3, True)]
    for mode, duration, same in runs:
        argv = ["--child", mode, "--duration", str(duration), "--forces", forces]
        assert script.main(argv) == 0
        got = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        assert got == {"steps": round(duration / 1e-3), "same_trajectory": same}
    with pytest.raises(SystemExit):
        script.main(["--durations", "3", "1"])
    assert "the shorter first" in capsys.readouterr().err
