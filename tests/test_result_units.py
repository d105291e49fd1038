"""Result folders as units: a result never inside another, temporaries ours only by
name, a folder another process writes inside refused, ``X.partial`` never taken for
ours unless its marker says so, and a run never silently replacing another's
results. Every refusal leaves every file byte-identical."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_nothing_lost import _lock_held  # another process holding a lock

from simpro_mj.commands.main import main
from simpro_mj.core.errors import UserInputError
from simpro_mj.report import folders, marker

ROOT = Path(__file__).resolve().parents[1]


def _snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def _result(folder: Path, kind: str = "run", files=("metrics.json",)) -> Path:
    folder.mkdir(parents=True)
    for name in files:
        (folder / name).write_text(f"{name} of {folder.name}\n")
    marker.write_marker(folder, kind)
    return folder


def test_a_result_inside_a_result_is_refused_both_ways(tmp_path):
    outer = _result(tmp_path / "r")
    with pytest.raises(UserInputError, match="inside the simpro-sim run result"):
        with folders.claim(outer / "sub"):
            pass
    assert not (outer / "sub").exists()
    inner = _result(outer / "sub")
    before = _snapshot(tmp_path)
    with pytest.raises(UserInputError, match=r"sub/ \(a simpro-sim result of its own\)"):
        folders.check_out(outer)
    assert not marker.is_complete(outer)
    assert _snapshot(tmp_path) == before and marker.result_kind(inner) == "run"


def test_a_users_hidden_files_in_a_result_are_not_taken_for_ours(tmp_path):
    r = _result(tmp_path / "r")
    (r / ".env.lock").write_text("user\n")
    (r / ".thesis.old-v2").mkdir()
    (r / ".thesis.old-v2" / "thesis.tex").write_text("\\chapter{}\n")
    before = _snapshot(tmp_path)
    with pytest.raises(UserInputError) as err:
        folders.install_folder(r, lambda tmp: (tmp / "metrics.json").write_text("{}"))
    assert ".env.lock" in str(err.value) and ".thesis.old-v2/thesis.tex" in str(err.value)
    assert _snapshot(tmp_path) == before


def test_a_folder_another_process_writes_inside_is_busy(tmp_path):
    q = tmp_path / "q"
    with _lock_held(q / "sub", tmp_path / "ready") as holder:
        (q / "sub").mkdir()
        (q / "sub" / "timeseries.csv").write_text("time_s\n0\n")
        for out in (q, q / "sub"):
            with pytest.raises(UserInputError, match=f"busy at .*pid {holder.pid}"):
                with folders.claim(out):
                    pass
        assert (q / "sub" / "timeseries.csv").exists()


def test_a_complete_result_named_partial_is_kept(tmp_path):
    r = _result(tmp_path / "r")
    mine = _result(tmp_path / "r.partial")  # a user's complete run named so
    assert folders.partial_sibling(r) == tmp_path / "r.partial-2"
    ours = _result(tmp_path / "s.partial", files=("metrics.json", marker.PARTIAL_MARKER))
    assert folders.partial_sibling(tmp_path / "s") == ours
    assert marker.result_kind(mine) == "run"


def test_a_long_legal_name_leaves_room_for_our_temporaries(tmp_path):
    out = tmp_path / ("n" * 250)
    folders.install_folder(out, lambda tmp: (tmp / "metrics.json").write_text("{}\n"))
    folders.install_folder(out, lambda tmp: (tmp / "metrics.json").write_text("{ }\n"))
    assert (out / "metrics.json").read_text() == "{ }\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]  # no temp, no lock left


def test_two_runs_with_different_overrides_keep_both_results(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    args = ["run", "step_pitch.yaml", "--no-plots", "--set"]
    main([*args, "duration_s=0.3"])
    first = capsys.readouterr()
    main([*args, "duration_s=0.4"])
    second = capsys.readouterr()
    a, b = (tmp_path / "results" / f"step_pitch+duration_s={d}" for d in ("0.3", "0.4"))
    assert marker.result_kind(a) == marker.result_kind(b) == "run"
    assert f"results: {a}" in first.out and f"results: {b}" in second.out
    assert "replacing" not in second.err
    main([*args, "duration_s=0.4"])  # the same parameters again: replaced, said in one line
    said = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("replacing")]
    assert said == [f"replacing the previous run result in {b.relative_to(tmp_path)} "
                    "(the same scenario)"]  # fmt: skip
    # a folder of that name holding something else: the next number, nothing touched
    (tmp_path / "results" / "step_pitch").mkdir()
    (tmp_path / "results" / "step_pitch" / "notes.txt").write_text("mine\n")
    main(["run", "step_pitch.yaml", "--no-plots"])
    assert "step_pitch-2" in capsys.readouterr().out
    assert (tmp_path / "results" / "step_pitch" / "notes.txt").read_text() == "mine\n"
