"""Which file a scenario argument names, and that the output says so.

A path that does not exist is refused as such (not as an unknown shipped name); a
file here with a shipped scenario's name is used and named on stderr; ``run`` prints
the file it runs.
"""

from __future__ import annotations

import pytest

from simpro_mj.commands.main import main
from simpro_mj.config.scenario import find_scenario, scenarios_dir

LOCAL = "name: step_pitch\nduration_s: 0.3\n"


def _one_error_line(capsys) -> str:
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    return lines[0]


def test_a_missing_path_says_no_such_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "./my/step_pitch.yaml", "--no-plots"]) == 2
    line = _one_error_line(capsys)
    assert "no such file at './my/step_pitch.yaml'" in line
    assert str(tmp_path / "my" / "step_pitch.yaml") in line  # where it was looked for
    assert "unknown scenario" not in line


def test_a_folder_is_not_a_scenario_file(tmp_path, monkeypatch, capsys):
    (tmp_path / "my").mkdir()
    monkeypatch.chdir(tmp_path)
    assert main(["run", "./my", "--no-plots"]) == 2
    assert "a folder at './my'" in _one_error_line(capsys)


def test_an_unknown_bare_name_suggests_the_shipped_one(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "step_pich.yaml", "--no-plots"]) == 2
    line = _one_error_line(capsys)
    assert "unknown scenario at 'step_pich.yaml'" in line and "'step_pitch'" in line


@pytest.mark.parametrize("given", ["step_pitch.yaml", "step_pitch"])
def test_the_shipped_scenario_is_found_by_name(tmp_path, monkeypatch, given):
    monkeypatch.chdir(tmp_path)
    assert find_scenario(given) == scenarios_dir() / "step_pitch.yaml"


def test_a_local_file_shadowing_a_shipped_one_is_named(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "step_pitch.yaml").write_text(LOCAL)
    out = tmp_path / "r"
    assert main(["run", "step_pitch.yaml", "--no-plots", "--quiet", "--out", str(out)]) in (0, 1)
    captured = capsys.readouterr()
    here = (tmp_path / "step_pitch.yaml").resolve()
    assert captured.out.splitlines()[0] == f"scenario: {here}"  # the file that ran
    notes = [ln for ln in captured.err.splitlines() if ln.startswith("note: running")]
    assert len(notes) == 1 and str(here) in notes[0]
    assert str(scenarios_dir() / "step_pitch.yaml") in notes[0]  # and the one it shadows


def test_one_number_sets_each_element_of_a_list():
    from simpro_mj.config.scenario import load_scenario

    sc = load_scenario("step_pitch", ["controller.outer.gains=30"])
    assert sc.controller.outer.gains == [30.0, 30.0, 30.0]
