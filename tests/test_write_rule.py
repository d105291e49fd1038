"""The write rule: simpro-sim writes a path only if it does not exist, or every
file in it is listed in the marker of the folder it went to (size and SHA-256
as written) and unchanged; otherwise exit 2, one line naming what would be
lost, and every file of the user byte-identical (hashes before and after).

Result folders are made with :func:`simpro_mj.report.results.write_results`
(no simulation): each refusal comes before any work, so no case here runs one.
"""

from __future__ import annotations

import hashlib
import os
import time
from pathlib import Path

import numpy as np
import pytest

from simpro_mj.commands.main import main
from simpro_mj.config.scenario import load_scenario
from simpro_mj.report import folders, marker, results, single_files

SHORT = ["--set", "duration_s=1.1", "--no-plots"]


def _hashes(root: Path) -> dict:
    """Every entry under ``root``: relative path -> SHA-256 of a file, or its kind."""
    out = {}
    for p in sorted(root.rglob("*")):
        rel = str(p.relative_to(root))
        if p.is_symlink():
            out[rel] = "link -> " + os.readlink(p)
        elif p.is_file():
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[rel] = "dir"
    return out


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    return lines[0]


def _result(folder: Path, name: str = "step_pitch") -> Path:
    sc = load_scenario(name, ["duration_s=0.2"])
    t = np.arange(5) * 1e-3
    arrays = {"qpos.npz": {"time_s": t, "qpos": np.zeros((5, 13)), "qpos_names": np.array(["a"])}}
    results.write_results(folder, {"time_s": t}, {}, sc, {"plots": False}, arrays=arrays)
    return folder


def test_a_result_folder_the_user_added_to_is_refused_by_run(tmp_path, capsys):
    out = _result(tmp_path / "r")
    (out / "notes.txt").write_text("my notes\n")
    (out / "my_plots").mkdir()
    (out / "my_plots" / "a.png").write_bytes(b"png")
    before = _hashes(tmp_path)
    assert main(["run", "step_pitch", "--out", str(out), *SHORT]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "my_plots/a.png" in line and "notes.txt" in line and "nothing was touched" in line
    assert _hashes(tmp_path) == before
    # a file of ours changed by the user is the user's too
    (out / "notes.txt").unlink()
    (out / "my_plots" / "a.png").unlink()
    (out / "my_plots").rmdir()
    (out / "metrics.json").write_text('{"status": "ok", "mine": 1}\n')
    before = _hashes(tmp_path)
    assert main(["run", "step_pitch", "--out", str(out), *SHORT]) == 2
    assert "metrics.json (changed since simpro-sim wrote it)" in _one_line(capsys.readouterr().err)
    assert _hashes(tmp_path) == before


def test_a_folder_of_ours_is_replaced_whole(tmp_path):
    out = _result(tmp_path / "r")
    assert marker.foreign(out) == []
    _result(out, "step_roll")  # ours: replaced, no hidden folder left
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]
    assert marker.is_complete(out)


def test_batch_resume_never_deletes_a_file_it_did_not_write(tmp_path, capsys):
    out = tmp_path / "b"
    out.mkdir()
    marker.record(out, [], "batch")
    variant = _result(out / "step_pitch" / "base")
    (variant / "my_comment.txt").write_text("keep me\n")
    before = _hashes(tmp_path)
    rc = main(["batch", "step_pitch", "--jobs", "1", "--resume", "--out", str(out), *SHORT])
    captured = capsys.readouterr()
    assert rc == 1
    assert "my_comment.txt" in (out / "summary.csv").read_text()
    after = _hashes(tmp_path)
    ours = {"b/.simpro-result", "b/summary.csv", "b/summary.json", "b/plots"}  # the batch's
    assert {k: v for k, v in after.items() if k not in ours} == {
        k: v for k, v in before.items() if k not in ours
    }, captured


def test_a_summary_the_user_edited_is_not_overwritten(tmp_path, capsys):
    out = tmp_path / "b"
    out.mkdir()
    (out / "summary.csv").write_text("mine\n")
    marker.record(out, [], "batch")
    before = _hashes(tmp_path)
    assert main(["batch", "step_pitch", "--jobs", "1", "--out", str(out), *SHORT]) == 2
    assert "summary.csv" in _one_line(capsys.readouterr().err)
    assert _hashes(tmp_path) == before


@pytest.mark.parametrize(
    "argv",
    [
        ["analyze", "--set", "outer.period_s=0.02"],
        ["validate-ik"],
        ["identify", "--duration", "1"],
        ["compare", "step_pitch", *SHORT],
        ["response", "step_pitch", "--axes", "pitch", "--freq-hz", "1"],
    ],
    ids=["analyze", "validate-ik", "identify", "compare", "response"],
)
def test_every_folder_writer_refuses_a_users_folder_before_working(tmp_path, capsys, argv):
    user = tmp_path / "mine"
    user.mkdir()
    (user / "validate_ik.png").write_bytes(b"my figure")
    (user / "root_locus_outer.png").write_bytes(b"my figure")
    (user / "comparison.txt").write_text("my table\n")
    before = _hashes(tmp_path)
    t0 = time.process_time()  # CPU time, whatever else the machine runs
    assert main([*argv, "--out", str(user)]) == 2
    assert time.process_time() - t0 < 2.0  # refused before the work (each takes seconds)
    assert str(user) in _one_line(capsys.readouterr().err)
    assert _hashes(tmp_path) == before


def test_compare_checks_its_run_folders_before_running(tmp_path, capsys):
    out = tmp_path / "c"
    out.mkdir()
    marker.record(out, [], "compare")
    _result(out / "joint_only")
    (out / "joint_only" / "notes.txt").write_text("mine\n")
    before = _hashes(tmp_path)
    assert main(["compare", "step_pitch", "--out", str(out), *SHORT]) == 2
    assert "joint_only/notes.txt" in _one_line(capsys.readouterr().err)
    assert _hashes(tmp_path) == before


def test_single_files_calibrate_render_manoeuvre(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.yaml").write_text("mine: 1\n")
    (tmp_path / "dir.yaml").mkdir()
    run = _result(tmp_path / "r")
    (tmp_path / "notes.mp4").write_bytes(b"my video")
    (tmp_path / "brake.csv").write_text("mine\n")
    os.symlink(tmp_path / "nowhere.yaml", tmp_path / "dangling.yaml")
    before = _hashes(tmp_path)
    cases = [
        (["calibrate", "--out", "mine.yaml"], "did not write it"),
        (["calibrate", "--out", "dir.yaml"], "it is a folder"),
        (["calibrate", "--out", "dangling.yaml"], "does not exist"),
        (["calibrate", "--name", "../cal_trav"], "no path separator"),
        (["calibrate", "--name", "a/b"], "no path separator"),
        (["render", str(run), "--out", "notes.mp4"], "did not write it"),
        (["manoeuvre", "braking", "--out", "brake.csv"], "did not write it"),
    ]
    for argv, said in cases:
        t0 = time.process_time()  # CPU time, whatever else the machine runs
        assert main(argv) == 2, argv
        assert time.process_time() - t0 < 2.0, argv
        assert said in _one_line(capsys.readouterr().err), argv
    assert _hashes(tmp_path) == before


def test_a_file_we_wrote_is_ours_to_replace_and_listed(tmp_path):
    path = tmp_path / "new" / "cal.yaml"
    single_files.write_file(path, "a: 1\n")
    assert marker.result_kind(path.parent) == "files"
    single_files.write_file(path, "a: 2\n")  # ours, unchanged: replaced
    path.write_text("a: 3\n")  # the user's edit
    with pytest.raises(folders.UserInputError, match="did not write it"):
        single_files.write_file(path, "a: 4\n")
    assert path.read_text() == "a: 3\n"
    single_files.write_file(path, "a: 4\n", overwrite=True)
    # a user's folder is never given a marker
    user = tmp_path / "user"
    user.mkdir()
    single_files.write_file(user / "x.yaml", "a: 1\n")
    assert sorted(p.name for p in user.iterdir()) == ["x.yaml"]


def test_out_links(tmp_path, capsys):
    dangling = tmp_path / "dangling"
    os.symlink(tmp_path / "gone", dangling)
    before = _hashes(tmp_path)
    assert main(["run", "step_pitch", "--out", str(dangling), *SHORT]) == 2
    assert "symbolic link" in _one_line(capsys.readouterr().err)
    assert _hashes(tmp_path) == before
    # a link to a result folder: the folder is written, the link kept, nothing left over
    target = _result(tmp_path / "target")
    link = tmp_path / "link"
    os.symlink(target, link)
    _result(link, "step_roll")
    assert link.is_symlink() and marker.is_complete(target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dangling", "link", "target"]
