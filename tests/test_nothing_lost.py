"""Nothing lost: ``--out`` never deletes a user's files.

* a folder is replaced only if it carries simpro-sim's result marker of the
  same kind; any other non-empty folder, the working folder (or one above
  it) and a folder holding the scenario are refused with exit 2, one line,
  and every file in them left byte-identical (run, compare, batch);
* two writers of one folder: the second is refused (a lock held by another
  process, which signals readiness through a file);
* an interrupted re-run keeps the previous complete result and writes the
  partial one beside it;
* a failing write names the user's folder, never the hidden temporary one;
* ``--resume`` uses :func:`simpro_mj.report.marker.is_complete` only.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from simpro_mj.commands.main import main
from simpro_mj.config.scenario import load_scenario, scenarios_dir
from simpro_mj.report import marker, results

ROOT = Path(__file__).resolve().parents[1]
SHORT = ["--set", "duration_s=1.1", "--no-plots"]


def _snapshot(folder: Path) -> dict:
    """Every file under ``folder`` (relative path -> bytes)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return lines[0]


def _user_folder(tmp_path: Path) -> Path:
    user = tmp_path / "thesis"
    (user / "figures").mkdir(parents=True)
    (user / "chapter1.tex").write_text("\\chapter{Results}\n")
    (user / "figures" / "fig1.png").write_bytes(b"\x89PNG not really")
    return user


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "step_pitch", *SHORT],
        ["compare", "step_pitch", *SHORT],
        ["batch", "step_pitch", "--jobs", "1", *SHORT],
    ],
    ids=["run", "compare", "batch"],
)
def test_a_users_folder_is_refused_and_untouched(tmp_path, capsys, argv):
    user = _user_folder(tmp_path)
    before = _snapshot(user)
    rc = main([*argv, "--out", str(user)])
    line = _one_error_line(capsys.readouterr().err)
    assert rc == 2
    assert str(user) in line and "not a simpro-sim result" in line and "nothing was touched" in line
    assert _snapshot(user) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thesis"]  # no lock, no temp left


def test_the_scenario_s_own_folder_and_the_working_folder_are_refused(
    tmp_path, capsys, monkeypatch
):
    proj = tmp_path / "proj"
    proj.mkdir()
    mine = proj / "mine.yaml"
    mine.write_text((scenarios_dir() / "step_pitch.yaml").read_text())
    before = _snapshot(tmp_path)
    assert main(["run", str(mine), "--out", str(proj), *SHORT]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert "holds the input" in line and str(mine) in line
    monkeypatch.chdir(proj)
    for out in (".", "..", str(tmp_path)):
        assert main(["run", "step_pitch", "--out", out, *SHORT]) == 2
        assert "working folder" in _one_error_line(capsys.readouterr().err)
    assert _snapshot(tmp_path) == before


def _exit_of(folder) -> int:
    """``run``'s exit status for the result in ``folder``: 0 ok, 1 not (a short run may
    end before its pose settles: not_settled)."""
    status = json.loads((folder / "metrics.json").read_text())["status"]
    assert status in ("ok", "not_settled", "limit_cycle")
    return 0 if status == "ok" else 1


def test_a_result_folder_is_replaced_and_an_empty_one_used(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["run", "step_pitch", "--out", str(empty), *SHORT]) == _exit_of(empty)
    assert marker.result_kind(empty) == "run" and marker.is_complete(empty)
    mask = os.umask(0o022)
    os.umask(mask)
    assert (empty.stat().st_mode & 0o777) == 0o777 & ~mask  # not mkdtemp's 0700
    first = (empty / "timeseries.csv").read_bytes()
    assert main(["run", "step_pitch", "--out", str(empty), "--set", "duration_s=1.2",
                 "--no-plots"]) == _exit_of(empty)  # fmt: skip
    assert len((empty / "timeseries.csv").read_bytes()) > len(first)  # replaced: 300 rows
    # a batch folder is not a run's to replace, nor a run folder a batch's
    batch = tmp_path / "b"
    assert main(["batch", "step_pitch", "--jobs", "1", "--out", str(batch), *SHORT]) == 0
    capsys.readouterr()
    assert marker.result_kind(batch) == "batch"
    assert main(["run", "step_pitch", "--out", str(batch), *SHORT]) == 2
    assert "simpro-sim batch result" in _one_error_line(capsys.readouterr().err)
    assert main(["batch", "step_pitch", "--jobs", "1", "--out", str(empty), *SHORT]) == 2
    _one_error_line(capsys.readouterr().err)


@contextlib.contextmanager
def _lock_held(out: Path, ready: Path):
    """Another process holding ``out``'s write lock (as a running ``run`` does from its
    first check to its last write); it says so by creating ``ready``."""
    code = (
        "import sys; from pathlib import Path; from simpro_mj.report import folders\n"
        f"with folders.locked({str(out)!r}):\n"
        f"    Path({str(ready)!r}).touch()\n"
        "    sys.stdin.readline()\n"
    )
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    holder = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, env=env)
    try:
        while not ready.exists():  # readiness signal, no fixed sleep
            assert holder.poll() is None, "lock holder died"
            time.sleep(0.01)  # poll interval only: the wait ends on the signal
        yield holder
    finally:
        holder.communicate(b"\n", timeout=30)
    assert holder.returncode == 0


def test_a_second_writer_is_refused_while_the_first_holds_the_folder(tmp_path, capsys):
    out = tmp_path / "r"
    with _lock_held(out, tmp_path / "ready") as holder:
        assert main(["run", "step_pitch", "--out", str(out), *SHORT]) == 2
        line = _one_error_line(capsys.readouterr().err)
        assert f"busy at {out}" in line and f"pid {holder.pid}" in line
        assert not out.exists()
        # a folder inside it (run --out OUT/x while a batch writes OUT): busy too
        inner = out / "swh" / "gains=2"
        assert main(["run", "step_pitch", "--out", str(inner), *SHORT]) == 2
        line = _one_error_line(capsys.readouterr().err)
        assert f"busy at {inner}" in line and f"is writing {out}, which holds it" in line
        assert not out.exists()
    assert main(["run", "step_pitch", "--out", str(out), *SHORT]) == 0  # released


def test_a_batch_does_not_run_a_variant_another_process_writes(tmp_path):
    """``batch --resume OUT`` while ``run --out OUT/step_pitch/base`` writes: the
    variant is reported busy before it runs, never replaced silently."""
    from simpro_mj.batch.runner import run_batch

    out = tmp_path / "b"
    out.mkdir()
    marker.record(out, [], "batch")  # an earlier batch's folder
    variant = out / "step_pitch" / "base"
    with _lock_held(variant, tmp_path / "ready") as holder:
        rows = run_batch(["step_pitch"], out, sets=["duration_s=1.1"], jobs=1, resume=True,
                         plots=False, summary_plots=False).rows  # fmt: skip
        assert rows[0].status == "invalid" and f"pid {holder.pid}" in rows[0].reason
        assert not variant.exists()


def test_an_interrupted_rerun_keeps_the_complete_result(tmp_path):
    sc = load_scenario("step_pitch", ["duration_s=1.1"])
    cols = {"time_s": np.arange(5) * 1e-3, "heave_m": np.zeros(5)}
    out = tmp_path / "r"
    assert results.write_results(out, cols, {}, sc, {"plots": False}) == out
    before = _snapshot(out)
    short = {k: v[:2] for k, v in cols.items()}
    extra = {"status": "interrupted", "reason": "SIGINT", "plots": False}
    where = results.write_results(out, short, {}, sc, dict(extra))
    assert where == tmp_path / "r.partial"
    assert _snapshot(out) == before and marker.is_complete(out)
    assert (where / marker.PARTIAL_MARKER).is_file() and not marker.is_complete(where)
    # a second interrupted run replaces the partial one, not the complete one
    assert results.write_results(out, short, {}, sc, dict(extra)) == where
    # a partial result is replaced in place by the next one (nothing complete lost)
    assert results.write_results(where, short, {}, sc, dict(extra)) == where
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r", "r.partial"]


def test_the_interrupted_message_names_both_folders(tmp_path):
    from simpro_mj.report.runner import interrupted_message
    from simpro_mj.sim.result import SimResult

    res = SimResult({}, "interrupted", "SIGINT", {"simulated_s": 1.5}, {"duration_s": 10.0})
    res.folder = tmp_path / "r.partial"
    msg = interrupted_message(res, tmp_path / "r")
    assert f"partial results in {tmp_path / 'r.partial'}" in msg
    assert f"the complete result in {tmp_path / 'r'} is kept" in msg


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS], ids=["full", "read-only"])
def test_a_failing_write_names_the_users_folder(tmp_path, capsys, monkeypatch, code):
    def failing(path, columns, rows=None):
        raise OSError(code, os.strerror(code), str(path))

    monkeypatch.setattr(results, "write_timeseries", failing)
    out = tmp_path / "r"
    assert main(["run", "step_pitch", "--out", str(out), *SHORT]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert f"cannot access at {out}: {os.strerror(code)}" in line
    assert ".simpro-tmp-" not in line
    assert list(tmp_path.iterdir()) == []


def test_is_complete_is_the_one_check_and_resume_uses_it(tmp_path):
    from simpro_mj.batch.runner import run_batch

    out = tmp_path / "b"
    argv = dict(sets=["duration_s=1.1"], jobs=1, plots=False, summary_plots=False)
    first = run_batch(["step_pitch"], out, **argv)
    folder = out / first.rows[0].folder
    assert marker.is_complete(folder)
    # a PARTIAL marker and a 0-byte time series written by hand: not complete, and
    # not simpro-sim's to replace either (a changed file may be the user's edit)
    (folder / marker.PARTIAL_MARKER).write_text("partial\n")
    (folder / "timeseries.csv").write_bytes(b"")
    assert not marker.is_complete(folder)
    before = _snapshot(folder)
    row = run_batch(["step_pitch"], out, resume=True, **argv).rows[0]
    assert row.status == "invalid" and "timeseries.csv (changed since" in row.reason
    assert "PARTIAL" in row.reason and _snapshot(folder) == before
    # the same state as simpro-sim leaves it (listed in its marker): re-run
    marker.record(folder, ["PARTIAL", "timeseries.csv"], "run")
    again = run_batch(["step_pitch"], out, resume=True, **argv)
    assert again.skipped == 0 and again.rows[0].status == "ok"
    assert marker.is_complete(folder)
    assert run_batch(["step_pitch"], out, resume=True, **argv).skipped == 1  # intact: skipped
    # each condition alone makes a folder incomplete
    for breaking in ("empty", "status", "blocks", "marker"):
        run_batch(["step_pitch"], out, **argv)
        if breaking == "marker":
            (folder / marker.RESULT_MARKER).unlink()
        elif breaking == "empty":
            (folder / "timeseries.csv").write_bytes(b"")
        else:
            doc = json.loads((folder / "metrics.json").read_text())
            if breaking == "status":
                doc = dict(doc, status="interrupted")
            else:  # only status and hash: no row can be built from it
                doc = {"status": "ok", "scenario": doc["scenario"]}
            (folder / "metrics.json").write_text(json.dumps(doc))
        assert not marker.is_complete(folder), breaking
        if breaking != "marker":
            marker.record(folder, ["timeseries.csv", "metrics.json"], "run")
            assert not marker.is_complete(folder), breaking
    # a variant folder without the marker is not simpro-sim's: reported, not replaced
    before = _snapshot(folder)
    row = run_batch(["step_pitch"], out, resume=True, **argv).rows[0]
    assert row.status == "invalid" and "not a simpro-sim result" in row.reason
    assert _snapshot(folder) == before


def test_ctrl_c_during_a_rerun_keeps_the_complete_result(tmp_path):
    """End to end: a complete result, then a long re-run into the same --out
    interrupted once it steps (its readiness file): the complete result stays,
    the partial one is beside it and the message says where both are."""
    import signal

    out = tmp_path / "r"
    assert main(["run", "step_pitch", "--out", str(out), *SHORT]) == 0
    before = _snapshot(out)
    ready = tmp_path / "ready"
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT), SIMPRO_READY_FILE=str(ready))
    cmd = [sys.executable, "-m", "simpro_mj.commands.main", "run", "step_pitch", "--out", str(out),
           "--no-plots", "--set", "duration_s=600"]  # fmt: skip
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 300  # a guard against a broken build, not a timing
        while not ready.is_file():
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.02)
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, stderr
    partial = tmp_path / "r.partial"
    last = stderr.strip().splitlines()[-1]
    assert f"partial results in {partial}" in last
    assert f"the complete result in {out} is kept" in last
    assert _snapshot(out) == before and marker.is_complete(out)
    assert (partial / marker.PARTIAL_MARKER).is_file() and not marker.is_complete(partial)
