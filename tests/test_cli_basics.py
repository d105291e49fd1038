"""The command line a newcomer meets first: --version, list, one-line mistakes, quiet
progress, and the warnings where a unit mistake is likely."""

from __future__ import annotations

import numpy as np
import pytest

from simpro_mj import __version__
from simpro_mj.analysis.sanity import (
    FIT_WARN_PERCENT,
    fit_warnings,
    radians_warnings,
    telemetry_warnings,
)
from simpro_mj.commands.main import main
from simpro_mj.config.presets import shipped_presets
from simpro_mj.config.scenario import load_scenario, shipped_scenarios


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"simpro-sim {__version__}"


def test_list_names_every_shipped_file_on_one_line(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    for name in shipped_scenarios() + shipped_presets() + ["braking_100kmh.csv"]:
        (line,) = [ln for ln in lines if ln.split()[:1] == [name]]
        assert len(line.split()) > 2, line  # a description follows the name
    assert "issue" not in out  # what the files are, not how they came to be
    assert main(["list", "presets", "--json"]) == 0
    import json

    doc = json.loads(capsys.readouterr().out)
    assert [p["name"] for p in doc["presets"]] == shipped_presets()


def test_batch_bad_set_is_one_line_exit_2(tmp_path, capsys):
    code = main(["batch", "sweep_outer_gain.yaml", "--set", "foo.bar=1", "--out",
                 str(tmp_path / "b")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error: unknown key at foo")
    assert not (tmp_path / "b").exists()


def test_every_command_takes_the_shared_options_that_mean_something_to_it():
    from simpro_mj.commands.main import COMMANDS, build_parser

    parser, mods = build_parser(every=True)
    for name in COMMANDS:
        sub = parser._subparsers._group_actions[0].choices[name]
        assert "--json" in sub._option_string_actions, name
        if name not in ("list", "send"):
            assert "--quiet" in sub._option_string_actions, name
    for name in ("list", "send", "render", "telemetry"):  # nothing to override: no --set
        sub = parser._subparsers._group_actions[0].choices[name]
        assert "--set" not in sub._option_string_actions, name
    for name in set(COMMANDS) - {"list", "send", "render", "telemetry"}:
        sub = parser._subparsers._group_actions[0].choices[name]
        assert "--set" in sub._option_string_actions, name
    for name in ("identify", "validate-ik", "run", "compare", "batch", "response"):
        sub = parser._subparsers._group_actions[0].choices[name]
        assert "--no-plots" in sub._option_string_actions, name  # one spelling everywhere


def test_progress_only_on_a_terminal(monkeypatch):
    import argparse

    from simpro_mj.core.progress import show_progress

    monkeypatch.setattr("sys.stderr.isatty", lambda: True)
    assert show_progress(argparse.Namespace(quiet=False, json=False))
    assert not show_progress(argparse.Namespace(quiet=True, json=False))
    assert not show_progress(argparse.Namespace(quiet=False, json=True))
    monkeypatch.setattr("sys.stderr.isatty", lambda: False)  # piped
    assert not show_progress(argparse.Namespace(quiet=False, json=False))


@pytest.mark.parametrize(
    ("value", "warned"), [(0.0524, True), (-0.15, True), (0.5, False), (3.0, False)]
)
def test_radians_in_a_degrees_key(value, warned):
    sc = load_scenario(
        "step_pitch", [f"setpoint.pitch_deg=[{{type: step, time_s: 1, value: {value}}}]"]
    )
    lines = radians_warnings(sc.model_dump())
    assert bool(lines) == warned
    if warned:
        assert "setpoint.pitch_deg" in lines[0] and "rad" in lines[0]
    # the shipped steps: degrees
    assert radians_warnings(load_scenario("step_all").model_dump()) == []


def _telemetry(path, fz):
    t = np.arange(0.0, 5.0, 0.01)
    cols = [t, 0.5 * np.sin(t), 0 * t, fz + 0 * t, 0 * t, 0 * t, 0 * t]
    np.savetxt(path, np.column_stack(cols), delimiter=",", comments="",
               header="time_s,fx_mps2,fy_mps2,fz_mps2,wx_rad_s,wy_rad_s,wz_rad_s")  # fmt: skip
    return path


@pytest.mark.parametrize(("fz", "warned"), [(0.0, True), (1.0, True), (9.81, False), (11.0, False)])
def test_telemetry_without_gravity(tmp_path, fz, warned):
    sc = {"setpoint": {"cueing": {"telemetry": str(_telemetry(tmp_path / "t.csv", fz))}}}
    lines = telemetry_warnings(sc)
    assert bool(lines) == warned
    if warned:
        assert "fz_mps2" in lines[0] and "gravity" in lines[0]


def test_shipped_telemetry_has_gravity():
    sc = load_scenario("cue_braking").model_dump()
    assert telemetry_warnings(sc) == []


def test_identification_fit_below_80_percent():
    lines = fit_warnings({"actuator1": {"fit_percent": 55.0}, "actuator2": {"fit_percent": 96.0}})
    assert len(lines) == 1 and lines[0].startswith("actuator1") and "55 %" in lines[0]
    assert fit_warnings({"a": {"fit_percent": FIT_WARN_PERCENT}}) == []
