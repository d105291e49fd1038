"""A user's mistake or an unstable design gives a clear answer.

* a table of bad inputs through ``simpro_mj.commands.main.main`` for every subcommand:
  exit 2, one stderr line ``error: <what> at <field>: <allowed>``, no traceback;
* a hypothesis fuzz of the scenario loader: it accepts a document or raises
  :class:`~simpro_mj.core.errors.UserInputError`, nothing else;
* preflight: payload too heavy (error with the limit), gains above the
  analysed limit (warning, recorded);
* divergence through the CLI: exit 1, ``status: diverged`` with the reason,
  stopped early;
* interrupted runs (SIGINT, SIGTERM) in a subprocess: exit 130, a complete or
  clearly partial folder, nothing truncated, no temporary folder left;
* reproducibility: the same scenario twice gives byte-identical time series
  and equal metrics (wall-clock figures aside), with the versions recorded.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from simpro_mj.commands.main import main
from simpro_mj.config.models import DEFAULT_SCENARIO
from simpro_mj.config.scenario import (
    load_scenario,
    resolve_scenario,
    scenarios_dir,
    shipped_scenarios,
)
from simpro_mj.core.errors import UserInputError
from simpro_mj.report import marker, results

ROOT = Path(__file__).resolve().parents[1]
SHORT = ["--set", "duration_s=0.2", "--no-plots"]


def _cli(capsys, argv):
    rc = main(argv)
    err = capsys.readouterr().err
    return rc, err


# ------------------------------------------------------------------ the table

BAD_YAML = "name: broken\nduration_s: 5.0\ncontroller:\n  mode: [task_space\n"

# (argv, field that must be named, other words that must appear)
BAD_INPUTS = [
    # missing file / unknown shipped name (the message lists the shipped names)
    (["run", "{tmp}/no_such_file.yaml"], "no_such_file.yaml", ["step_pitch", "track_sines"]),
    (["run", "step_pich"], "step_pich", ["did you mean 'step_pitch'", "fault_supply_drop"]),
    (["compare", "nonexistent"], "nonexistent", ["step_pitch"]),
    # invalid YAML: line and column
    (["run", "{tmp}/broken.yaml"], "broken.yaml", ["line 5, column 1"]),
    # unknown key with the closest valid key (file and --set)
    (["run", "{tmp}/typo.yaml"], "controller.outer.gain", ["did you mean 'gains'"]),
    (["run", "step_pitch", "--set", "controler.mode=joint_only"], "controler", ["controller"]),
    # wrong types
    (["run", "step_pitch", "--set", "duration_s=abc"], "duration_s", ["wrong type", "number"]),
    (["run", "step_pitch", "--set", "controller.outer.gains=three"], "controller.outer.gains", []),
    (["run", "step_pitch", "--set", "seed=[1]"], "seed", ["wrong type"]),
    (["compare", "step_pitch", "--set", "controller.clamp_setpoints=1"], "clamp_setpoints", []),
    # zero, negative, non-finite, absurd durations
    (["run", "step_pitch", "--set", "duration_s=0"], "duration_s", ["0.01..3600 s"]),
    (["run", "step_pitch", "--set", "duration_s=-2"], "duration_s", ["0.01..3600 s"]),
    (["run", "step_pitch", "--set", "duration_s=.inf"], "duration_s", ["finite"]),
    (["run", "step_pitch", "--set", "duration_s=1e300"], "duration_s", ["<= 3600 s"]),
    (["compare", "step_pitch", "--set", "duration_s=0"], "duration_s", ["0.01..3600 s"]),
    # periods that are not a multiple of the 1 ms step
    (["run", "step_pitch", "--set", "controller.outer.period_ms=2.5"], "period_ms", ["1 ms"]),
    (["run", "step_pitch", "--set", "sensors.imu.rate_ms=0.5"], "sensors.imu.rate_ms", ["1 ms"]),
    # set-points outside the workspace, naming the limit
    (
        ["run", "step_pitch", "--set", "setpoint.heave_mm=[{type: step, time_s: 0.1, value: 400}]"],
        "setpoint",
        ["leg 1 stroke", "allowed 0.0..500.0 mm", "t = 0.100 s"],
    ),
    # a payload the cylinders cannot lift at the supply pressure
    (
        ["run", "step_pitch", "--set", "plant.payload.mass_kg=1500", *SHORT],
        "plant.payload.mass_kg",
        ["kN on cylinder 1", "at most 7.36 kN", "6 bar", "allowed: <= 1209 kg"],
    ),
    (
        ["compare", "step_pitch", "--set", "plant.payload.mass_kg=1500", *SHORT],
        "plant.payload.mass_kg",
        ["allowed: <= 1209 kg"],
    ),
    (
        [
            "run",
            "step_pitch",
            "--set",
            "actuator.pneumatics.supply_pressure_bar_gauge=1",
            "--set",
            "plant.preset=heavy_cabin",
            *SHORT,
        ],
        "plant.payload.mass_kg",
        ["1 bar", "allowed: <= 13 kg"],
    ),
    # pneumatic values are checked at load time with their scenario path
    (
        ["run", "step_pitch", "--set", "actuator.pneumatics.valve.underlap_fraction=abc"],
        "actuator.pneumatics.valve.underlap_fraction",
        ["wrong type"],
    ),
    (
        [
            "run",
            "step_pitch",
            "--set",
            "controller.inner.variant=redesigned",
            "--set",
            "controller.inner.zeta=1.9",
            "--set",
            "controller.inner.wn_rad_s=900",
        ],
        "controller.inner.wn_rad_s",
        ["infeasible"],
    ),  # fmt: skip
    # faults
    (
        ["run", "step_pitch", "--set", "faults=[{type: leak, time_s: 1}]"],
        "faults[0].type",
        ["supply_drop"],
    ),
    (
        [
            "run",
            "step_pitch",
            "--set",
            "faults=[{type: valve_stuck, time_s: 1, leg: 4, voltage_v: 5}]",
        ],
        "faults[0].leg",
        ["1, 2 or 3"],
    ),  # fmt: skip
    # malformed --set: no '=', unknown path, bad YAML value, empty key
    (["run", "step_pitch", "--set", "duration_s"], "'duration_s'", ["KEY=VALUE"]),
    (["run", "step_pitch", "--set", "a.b=1"], "unknown key at a", ["allowed keys"]),
    (["run", "step_pitch", "--set", "duration_s=[1"], "duration_s", ["not valid YAML"]),
    (["run", "step_pitch", "--set", "=3"], "'=3'", ["KEY=VALUE"]),
    (["run", "step_pitch", "--set", "duration_s.x=3"], "duration_s.x", ["no sub-keys"]),
    (["compare", "step_pitch", "--set", "nonsense"], "'nonsense'", ["KEY=VALUE"]),
    # an output path that is a file
    (["run", "step_pitch", "--out", "{tmp}/afile", *SHORT], "afile", ["folder"]),
    # the other subcommands
    (["workspace", "--set", "margin_mm=abc"], "margin_mm", ["wrong type"]),
    (["workspace", "--set", "margin_mm=.nan"], "margin_mm", ["finite"]),
    (["workspace", "--set", "heights=1.5"], "heights", ["integer"]),
    (["workspace", "--set", "marginmm=1"], "marginmm", ["did you mean 'margin_mm'"]),
    (["workspace", "--set", "bad"], "'bad'", ["KEY=VALUE"]),
    (["validate-ik", "--set", "trajectory.duration_s=0"], "trajectory.duration_s", ["> 0 s"]),
    (["validate-ik", "--set", "trajectory.duration_s=-1"], "trajectory.duration_s", ["> 0 s"]),
    (["validate-ik", "--set", "trajectory.duration_s=.nan"], "trajectory.duration_s", []),
    (["validate-ik", "--set", "trajectory.log_every_ms=0.5"], "log_every_ms", ["integer"]),
    (["validate-ik", "--set", "trajectory.durration_s=1"], "trajectory.durration_s", ["did you"]),
    (
        ["validate-ik", "--set", "trajectory.heave_mm=400", "--set", "trajectory.duration_s=10"],
        "trajectory",
        ["stroke", "unreachable"],
    ),
    (["validate-ik", "--set", "model.payload.mass_kg=abc"], "model.payload.mass_kg", []),
    (["identify", "--set", "identify.duration_s=0"], "identify.duration_s", [">= 0.5 s"]),
    (["identify", "--set", "identify.settle_s=-1"], "identify.settle_s", [">= 0"]),
    (["identify", "--set", "identify.prbs_bits=1"], "identify.prbs_bits", ["integer"]),
    (["identify", "--set", "identify.prbs_clock_ms=2.5"], "identify.prbs_clock_ms", ["1 ms"]),
    (["identify", "--set", "identify.seed=abc"], "identify.seed", ["wrong type"]),
    (["identify", "--duration", "-1"], "identify.duration_s", [">= 0.5 s"]),
    (
        [
            "identify",
            "--set",
            "model.payload.mass_kg=1500",
            "--duration",
            "0.5",
            "--no-plots",
            "--out",
            "{tmp}/id",
        ],
        "model.payload.mass_kg",
        ["allowed: <= 1066 kg"],
    ),  # fmt: skip
    (
        ["identify", "--set", "pneumatics.cylinder.bore_mm=abc"],
        "pneumatics.cylinder.bore_mm",
        ["wrong type"],
    ),
    (["analyze", "--set", "inner.dt_s=0", "--no-plots"], "inner.dt_s", [">= 1e-05"]),
    (["analyze", "--set", "outer.period_s=0.0605", "--no-plots"], "outer.period_s", ["multiple"]),
    (["analyze", "--set", "outer.gain=-1", "--no-plots"], "outer.gain", [">= 0"]),
    (["analyze", "--set", "inner.zeta=-1", "--no-plots"], "inner.zeta", ["> 0"]),
    (["analyze", "--set", "sweep.wn_rad_s=[0]", "--no-plots"], "sweep.wn_rad_s", ["item [0]"]),
    (["analyze", "--set", "outer.step_duration_s=-1", "--no-plots"], "step_duration_s", ["> 0"]),
    (["analyze", "--set", "outer.delay_samples=null", "--no-plots"], "outer.delay_samples", []),
    (["analyze", "--set", "outer.delay_samples=1.5", "--no-plots"], "outer.delay_samples", []),
    (["analyze", "--set", "inner.variant=best", "--no-plots"], "inner.variant", ["corrected"]),
    # argparse misuse: one line, exit 2
    (["run"], "scenario", ["required"]),
    (["run", "step_pitch", "--bogus"], "--bogus", ["unrecognized"]),
    (["frobnicate"], "frobnicate", ["invalid choice"]),
    ([], "COMMAND", ["required"]),
    (["identify", "--duration", "abc"], "--duration", ["invalid float"]),
    (["identify", "--actuators", "4"], "--actuators", ["invalid choice"]),
]

if importlib.util.find_spec("simpro_mj.commands.batch") is not None:
    BAD_INPUTS += [
        (["batch", "{tmp}/no_such_file.yaml", "--strict"], "no_such_file.yaml", []),
        # a path naming nothing is refused before anything runs, --strict or not
        (["batch", "step_roll", "{tmp}/no_such_file.yaml"], "no_such_file.yaml", []),
        (["batch", "step_pitch", "--set", "duration_s=0", "--strict"], "duration_s", []),
        (["batch", "step_pitch", "--set", "nonsense", "--strict"], "'nonsense'", []),
        (["batch", "step_pitch", "--jobs", "x"], "--jobs", []),
    ]


@pytest.fixture
def bad_files(tmp_path):
    (tmp_path / "broken.yaml").write_text(BAD_YAML)
    (tmp_path / "typo.yaml").write_text("duration_s: 1.0\ncontroller:\n  outer:\n    gain: [1]\n")
    (tmp_path / "afile").write_text("not a folder\n")
    return tmp_path


@pytest.mark.parametrize(
    "argv, field, words", BAD_INPUTS, ids=[" ".join(b[0])[:60] for b in BAD_INPUTS]
)
def test_bad_input_exits_2_with_one_line_naming_the_field(
    argv, field, words, bad_files, capsys, monkeypatch
):
    monkeypatch.chdir(bad_files)  # any file a case would write lands in tmp
    argv = [a.replace("{tmp}", str(bad_files)) for a in argv]
    rc, err = _cli(capsys, argv)
    lines = err.splitlines()
    assert rc == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    assert field in lines[0], lines[0]
    for word in words:
        assert word in lines[0], (word, lines[0])


def test_unknown_scenario_lists_every_shipped_name(capsys):
    rc, err = _cli(capsys, ["run", "nope"])
    assert rc == 2
    for name in shipped_scenarios():
        assert name in err


def test_help_exits_0(capsys):
    assert main(["run", "--help"]) == 0
    assert "scenario" in capsys.readouterr().out


def test_an_internal_error_is_one_line_exit_3(capsys, monkeypatch):
    import simpro_mj.commands.workspace as ws

    def boom(*a, **k):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(ws, "workspace_ranges", boom)
    monkeypatch.delenv("SIMPRO_DEBUG", raising=False)
    rc, err = _cli(capsys, ["workspace"])
    assert rc == 3 and len(err.splitlines()) == 1 and "internal error" in err
    assert "Traceback" not in err


# ------------------------------------------------------------------ loader fuzz

_SPECIAL = [0, -1, -1e-9, 1e308, -1e308, math.nan, math.inf, -math.inf, 2**63, 2**64, True, None]
_scalars = st.one_of(
    st.sampled_from(_SPECIAL),
    st.integers(-(10**20), 10**20),
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-100, 100),
    st.text(max_size=12),
    st.sampled_from(["", "5e-3", "1e6", "task_space", "I", "PI", "step", "yes", "~", "nan"]),
)
_garbage = st.recursive(
    _scalars,
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.dictionaries(st.text(max_size=8) | st.integers(), inner, max_size=4)
    ),
    max_leaves=8,
)


def _paths(tree, prefix=()):
    """Every (path tuple) of a nested dict/list document."""
    out = [prefix] if prefix else []
    if isinstance(tree, dict):
        for k, v in tree.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(tree, list):
        for i, v in enumerate(tree):
            out += _paths(v, prefix + (i,))
    return out


def _base_docs():
    docs = [{}, json.loads(json.dumps(DEFAULT_SCENARIO))]
    for name in shipped_scenarios():
        for ext in (".yaml", ".yml"):
            path = scenarios_dir() / f"{name}{ext}"
            if path.is_file():
                doc = yaml.safe_load(path.read_text())
                doc.pop("sweep", None)  # batch's block, read by load_scenario only
                doc.pop("monte_carlo", None)
                docs.append(doc)
    return docs


BASE_DOCS = _base_docs()


@st.composite
def mutated_docs(draw):
    doc = json.loads(json.dumps(draw(st.sampled_from(BASE_DOCS))))
    for _ in range(draw(st.integers(1, 4))):
        paths = _paths(doc)
        op = draw(st.sampled_from(["replace", "delete", "add", "add", "replace"]))
        if not paths or op == "add":
            parent = doc
            if paths:
                target = draw(st.sampled_from(paths))
                node = doc
                for p in target:
                    node = node[p]
                parent = node if isinstance(node, dict) else doc
            key = draw(st.text(max_size=10) | st.sampled_from(["faults", "setpoint", "typo_s"]))
            parent[key] = draw(_garbage)
            continue
        target = draw(st.sampled_from(paths))
        node = doc
        for p in target[:-1]:
            node = node[p]
        if op == "delete":
            del node[target[-1]]
        else:
            node[target[-1]] = draw(_garbage)
    return doc


def _fault_docs():
    fault = st.fixed_dictionaries(
        {"type": st.sampled_from(["supply_drop", "valve_stuck", "sensor_frozen",
                                  "sensor_dropout", "sensor_bias", "potentiometer_failure"])},
        optional={
            "time_s": _scalars, "end_s": _scalars, "leg": _scalars, "voltage_v": _scalars,
            "pressure_bar_gauge": _scalars, "ramp_s": _scalars, "sensor": st.sampled_from(
                ["imu", "potentiometer", "height_encoder", "gps"]) | _scalars,
            "axis": _scalars, "bias_mm": _scalars, "bias_deg": _scalars,
            "probability": _scalars, "mode": _scalars,
        },
    )  # fmt: skip
    return st.fixed_dictionaries(
        {"duration_s": st.just(5.0), "faults": st.lists(fault | _garbage, max_size=3)}
    )


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@example({"controller": {"outer": {"period_ms": float("inf")}}})  # round(inf) raised
@given(st.one_of(mutated_docs(), _fault_docs(), _garbage))
def test_loader_accepts_or_raises_user_input_error(doc):
    try:
        if isinstance(doc, dict):
            resolved = resolve_scenario(doc, default_name="fuzz")
        else:  # not a mapping at the top: the file loader's message
            with tempfile.TemporaryDirectory() as d:
                path = Path(d) / "fuzz.yaml"
                path.write_text(yaml.safe_dump(doc, allow_unicode=True))
                resolved = load_scenario(str(path)).model_dump()
    except UserInputError as exc:
        assert "\n" not in str(exc) and " at " in str(exc)
        return
    # accepted: a complete, JSON-clean scenario (the hash needs finite numbers)
    assert set(resolved) == set(DEFAULT_SCENARIO)
    json.dumps(resolved, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.text(max_size=80))
def test_loader_on_random_yaml_text(text):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "fuzz.yaml"
        path.write_text(text, encoding="utf-8")
        try:
            load_scenario(str(path))
        except UserInputError:
            pass


_SET_KEYS = ["duration_s", "seed", "controller.outer.gains", "controller.mode", "faults",
             "setpoint.pitch_deg", "actuator.pneumatics.valve", "plant.payload", "x.y"]  # fmt: skip


@settings(max_examples=100, deadline=None)
@example("0\n0=\x1b")  # found by exploring: a key with a newline in a YAML error message
@given(
    st.one_of(
        st.text(max_size=40),
        st.tuples(st.sampled_from(_SET_KEYS), st.text(max_size=30)).map("=".join),
    )
)
def test_set_expressions_accept_or_raise_user_input_error(expr):
    try:
        resolve_scenario({"duration_s": 2.0}, [expr], default_name="fuzz")
    except UserInputError as exc:
        assert "\n" not in str(exc)


def test_yaml_is_read_with_a_safe_loader(tmp_path):
    path = tmp_path / "evil.yaml"
    path.write_text("name: !!python/object/apply:os.system ['echo pwned']\n")
    with pytest.raises(UserInputError, match="invalid YAML at"):
        load_scenario(str(path))


# ------------------------------------------------------------------ preflight


def test_max_liftable_payload_is_stated_and_just_below_passes(tmp_path, capsys):
    from simpro_mj.analysis.preflight import check_payload

    info = check_payload(load_scenario("step_pitch"))
    assert 1150 < info["max_payload_kg"] < 1250  # 1209 kg (leg 1, as-built CoM 60 mm off)
    ok = load_scenario("step_pitch", ["plant.payload.mass_kg=1180", "duration_s=0.1"])
    assert check_payload(ok)["utilisation"][0] > 0.9  # warned, not refused
    with pytest.raises(UserInputError, match="allowed: <= 1209 kg"):
        check_payload(load_scenario("step_pitch", ["plant.payload.mass_kg=1220"]))


def test_gain_above_the_analysed_limit_is_warned_and_recorded(tmp_path, capsys):
    out = tmp_path / "r"
    rc = main(
        ["run", "step_pitch", "--out", str(out), "--no-plots", "--set", "duration_s=1.1",
         "--set", "controller.outer.gains=[1, 12, 1]"]
    )  # fmt: skip
    err = capsys.readouterr().err
    doc = json.loads((out / "metrics.json").read_text())
    assert rc == (0 if doc["status"] == "ok" else 1)  # 1.1 s: the verdict on a short run
    lines = [line for line in err.splitlines() if line.startswith("warning: ")]
    assert len(lines) == 1, err
    assert "controller.outer.gains[1] = 12 exceeds the analysed stability limit 11.8" in lines[0]
    assert "(I, T = 60 ms, real inner loops" in lines[0]
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["warnings"] == [lines[0].removeprefix("warning: ")]
    assert doc["preflight"]["stability"]["limit"] == pytest.approx(11.8447, abs=1e-3)
    # the shipped gains are inside the limit, on the linear plant too (limit 14.08)
    from simpro_mj.analysis.preflight import gain_warnings

    assert gain_warnings(load_scenario("step_pitch"))[0] == []
    w, info = gain_warnings(load_scenario("step_pitch", ["actuator.model=linear"]))
    assert w == [] and info["limit"] == pytest.approx(14.0843, abs=1e-3)
    # one gain on every axis above the limit: one line naming the value
    w, _ = gain_warnings(load_scenario("step_pitch", ["controller.outer.gains=[13, 13, 13]"]))
    assert len(w) == 1 and "gains = 13 on every axis exceeds" in w[0] and "11.8" in w[0]


# ------------------------------------------------------------------ divergence


def test_divergence_through_the_cli_exits_1_and_stops_early(tmp_path, capsys):
    """Loop-closure constraints 250x softer than shipped on the heavy cabin (joint loops
    designed on eqs. 34-37 in the metres reading): leg 1's loop opens past
    the 5 mm bound about 1 s in; the run stops there, writes what it had."""
    out = tmp_path / "div"
    rc = main(
        ["run", "step_pitch", "--out", str(out), "--no-plots", "--set", "duration_s=30",
         "--set", "plant.loop_timeconst_s=0.5", "--set", "plant.preset=heavy_cabin",
         "--set", "paper_units=metres", "--set", "controller.inner.design_plant=paper",
         "--set", "controller.outer.gains=2"]  # within 10x the analysed limit (0.3)
    )  # fmt: skip
    captured = capsys.readouterr()
    assert rc == 1
    assert "Traceback" not in captured.err
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["status"] == "diverged"
    assert "kinematic loop 'leg1_loop' opened" in doc["reason"] and "t = " in doc["reason"]
    assert doc["sim"]["steps"] < 3000  # stopped, not run to 30 s
    rows = (out / "timeseries.csv").read_text().count("\n") - 1
    assert 0 < rows <= doc["sim"]["steps"] + 1
    assert "DIVERGED" in captured.out


def test_non_finite_force_names_the_state(tmp_path, monkeypatch):
    """A NaN out of the actuator model stops the run naming what went non-finite."""
    import simpro_mj.plant.step_functions as psf

    real = psf.seal_friction
    calls = {"n": 0}

    def poisoned(*args):  # the friction law turns NaN after 200 steps
        calls["n"] += 1
        f = real(*args)
        return f * np.nan if calls["n"] > 3 * 200 else f

    monkeypatch.setenv("SIMPRO_KERNEL", "python")  # the interpreted step calls the module's law
    monkeypatch.setattr(psf, "seal_friction", poisoned)
    from simpro_mj.report.runner import execute

    res, doc = execute(load_scenario("step_pitch", ["duration_s=2"]), tmp_path / "nan", False)
    assert doc["status"] == "diverged"
    assert "non-finite" in doc["reason"]
    assert res.sim["steps"] < 400


# ------------------------------------------------------------------ nothing lost


def test_an_interrupt_while_writing_keeps_the_previous_folder(tmp_path, monkeypatch):
    from simpro_mj.report.runner import execute

    sc = load_scenario("step_pitch", ["duration_s=0.2"])
    out = tmp_path / "run"
    execute(sc, out, plots=False, quiet=True)
    before = (out / "timeseries.csv").read_bytes()
    real_rename = Path.rename

    def interrupted_rename(self, target):
        if ".simpro-tmp-" in self.name:  # between moving the old folder aside and the new in
            raise KeyboardInterrupt
        return real_rename(self, target)

    monkeypatch.setattr(Path, "rename", interrupted_rename)
    sc2 = load_scenario("step_pitch", ["duration_s=0.3"])
    with pytest.raises(KeyboardInterrupt):
        results.write_results(out, {"time_s": np.zeros(3)}, {}, sc2, {"plots": False})
    monkeypatch.undo()
    assert (out / "timeseries.csv").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    assert marker.is_complete(out)


def test_partial_marker_and_is_complete(tmp_path):
    sc = load_scenario("step_pitch", ["duration_s=0.2"])
    cols = {"time_s": np.arange(3) * 1e-3, "heave_m": np.zeros(3)}
    results.write_results(
        tmp_path / "p", cols, {}, sc, {"status": "interrupted", "reason": "SIGINT", "plots": False}
    )
    assert (tmp_path / "p" / marker.PARTIAL_MARKER).read_text().startswith("partial results")
    assert not marker.is_complete(tmp_path / "p")
    results.write_results(tmp_path / "d", cols, {}, sc, {"status": "diverged", "plots": False})
    assert marker.is_complete(tmp_path / "d")
    assert not marker.is_complete(tmp_path / "missing")


def _wait_ready(proc, ready: Path) -> bool:
    """Wait for the run's readiness file (SIMPRO_READY_FILE), not for a guessed delay.

    The bound only keeps a broken run from hanging the suite; it is not a timing
    assumption (the file appears after the first step, well before it).
    """
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        if ready.is_file():
            return True
        if proc.poll() is not None:
            return False
        time.sleep(0.02)
    return False


@pytest.mark.parametrize(
    "sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=["SIGINT", "SIGTERM", "SIGHUP"]
)
def test_interrupted_run_leaves_a_marked_partial_folder(tmp_path, sig):
    out = tmp_path / "long"
    ready = tmp_path / "ready"
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT), SIMPRO_READY_FILE=str(ready))
    cmd = [sys.executable, "-m", "simpro_mj.commands.main", "run", "step_pitch", "--out", str(out),
           "--no-plots", "--set", "duration_s=600"]  # fmt: skip
    proc = subprocess.Popen(
        cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert _wait_ready(proc, ready), proc.communicate()
        assert ready.read_text().split()[0] == "stepping"
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr
    assert stderr.strip().splitlines()[-1].startswith("error: ")
    assert not [p.name for p in tmp_path.iterdir() if re.search(r"\.simpro-(tmp|old)-", p.name)]
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(("ready.", ".ready."))]
    assert not [p.name for p in tmp_path.iterdir() if p.name.endswith(".simpro-lock")]
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["status"] == "interrupted" and doc["reason"]
    if sig != signal.SIGINT:  # the reason names the signal (a closed terminal: SIGHUP)
        assert f"signal ({sig.name})" in doc["reason"], doc["reason"]
    assert (out / marker.PARTIAL_MARKER).is_file() and not marker.is_complete(out)
    lines = (out / "timeseries.csv").read_text().splitlines()
    width = len(lines[0].split(","))
    assert all(len(line.split(",")) == width for line in lines[1:])  # nothing truncated
    steps = doc["sim"]["steps"]
    assert 0 < steps < 600_000
    assert steps <= len(lines) - 1 <= steps + 1
    t_last = float(lines[-1].split(",")[0])
    assert abs(t_last - steps * 1e-3) <= 1.5e-3


# ------------------------------------------------------------------ reproducible


def test_same_scenario_twice_gives_identical_files(tmp_path):
    from simpro_mj.report.runner import execute

    sc = load_scenario("step_all", ["duration_s=1.0"])
    _, a = execute(sc.model_dump(), tmp_path / "a", plots=False, quiet=True)
    # the second time typed: the same run, the same files
    _, b = execute(sc, tmp_path / "b", plots=False, quiet=True)
    ts_a = (tmp_path / "a" / "timeseries.csv").read_bytes()
    assert ts_a == (tmp_path / "b" / "timeseries.csv").read_bytes()
    assert (tmp_path / "a" / "scenario.yaml").read_bytes() == (
        tmp_path / "b" / "scenario.yaml"
    ).read_bytes()

    def deterministic(doc):
        doc = json.loads(json.dumps(doc))
        doc["sim"].pop("wall_clock")
        doc["sim"].pop("realtime_factor", None)  # wall-clock too (metrics.json's first name for it)
        return doc

    assert a["sim"]["wall_clock"]  # the wall-clock figures are there, kept apart
    assert deterministic(a) == deterministic(b)
    v = a["versions"]
    for key in ("simpro-sim", "mujoco", "numpy", "python-control", "scenario_hash"):
        assert v.get(key), key
    assert v["scenario_hash"] == a["scenario"]["hash"]
    # the written scenario loads back to the same hash
    again = load_scenario(str(tmp_path / "a" / "scenario.yaml"))
    assert again == sc
