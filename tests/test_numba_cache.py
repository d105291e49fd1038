"""numba's cache of the compiled step: a damaged file is deleted with a notice when
it is loaded, and its function compiled again; an unusable ``NUMBA_CACHE_DIR`` is said
and another folder used."""

from __future__ import annotations

import importlib
import os
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from simpro_mj.sim import numba_cache


def test_a_truncated_cache_file_is_deleted_and_said(tmp_path):
    good_index = tmp_path / "f-1.py311.nbi"
    with open(good_index, "wb") as fh:
        pickle.dump("0.61", fh)
        fh.write(pickle.dumps(("stamp", {"key": "f-1.py311.1.nbc"})))
    good = tmp_path / "f-1.py311.1.nbc"
    good.write_bytes(pickle.dumps(("code", b"\x00" * 1000)))
    bad = tmp_path / "sub" / "g-2.py311.1.nbc"
    bad.parent.mkdir()
    bad.write_bytes(pickle.dumps(("code", b"\x00" * 1000))[:100])  # truncated
    empty = tmp_path / "g-2.py311.nbi"
    empty.write_bytes(b"")
    mine = tmp_path / "notes.txt"
    mine.write_text("not numba's\n")
    said: list[str] = []
    removed = numba_cache.heal(tmp_path.rglob("*"), said.append)
    assert sorted(removed) == sorted([bad, empty])
    assert good.exists() and good_index.exists() and mine.exists()
    assert len(said) == 2 and all(s.startswith("notice: numba cache file ") for s in said)


class _ImportsOnLoad:
    """Unpickles by importing a module, as numba's object files rebuild their environment."""

    def __reduce__(self):
        return importlib.import_module, ("probe_mod_for_heal",)


def test_healing_parses_an_object_file_without_importing_its_module(tmp_path, monkeypatch):
    """Loading numba's object file imports the module that defined its function; the MuJoCo
    callback's module asks for the compiled step at import, so a heal that loaded it under
    the compile lock waited on itself forever. Healing parses the file instead."""
    (tmp_path / "probe_mod_for_heal.py").write_text("import sys\nsys.probe_imported = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    obj = tmp_path / "nb" / "callback.entry-1.py311.1.nbc"
    obj.parent.mkdir()
    obj.write_bytes(pickle.dumps(("object code", _ImportsOnLoad())))
    pickle.loads(obj.read_bytes())  # loading it imports the module
    assert sys.modules.pop("probe_mod_for_heal") and sys.__dict__.pop("probe_imported") == 1
    assert numba_cache.heal([obj], print) == []
    assert obj.exists() and "probe_mod_for_heal" not in sys.modules
    assert not hasattr(sys, "probe_imported")


def test_an_unusable_numba_cache_dir_is_said_and_another_used(tmp_path, monkeypatch):
    afile = tmp_path / "afile"
    afile.write_text("x")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(afile))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    said: list[str] = []
    base = numba_cache.cache_base(str(tmp_path / "pkg"), said.append)
    assert base == str(tmp_path / "xdg" / "simpro-sim")
    assert said == [f"notice: NUMBA_CACHE_DIR={afile} is not a writable folder; the compiled "
                    f"step is cached in {base}"]  # fmt: skip
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "new"))  # made when missing
    assert numba_cache.cache_base(str(tmp_path / "pkg"), said.append) == str(tmp_path / "new")
    assert len(said) == 1


def test_functions_are_cached_in_the_folder_passed_to_them(tmp_path, monkeypatch):
    """The step's functions get their cache folder passed: numba's process-wide
    ``config.CACHE_DIR`` stays as it was, and a second compile loads from the folder."""
    numba = pytest.importorskip("numba")
    (tmp_path / "probe_mod_for_jit.py").write_text(
        "def twice(x):\n    return 2.0 * x\n\ndef one():\n    return 1.0\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    probe = importlib.import_module("probe_mod_for_jit")
    before = numba.config.CACHE_DIR
    folder = str(tmp_path / "nb")
    assert numba_cache.jit(folder)(probe.twice)(3.0) == 6.0
    assert numba_cache.cfunc(numba.types.float64(), folder)(probe.one).ctypes() == 1.0
    assert numba.config.CACHE_DIR == before
    names = sorted(p.name for p in Path(folder).rglob("*.nbi"))
    assert [n.split("-")[0] for n in names] == ["probe_mod_for_jit.one", "probe_mod_for_jit.twice"]
    again = numba_cache.jit(folder)(probe.twice)
    assert again(4.0) == 8.0 and sum(again.stats.cache_hits.values()) == 1
    sys.modules.pop("probe_mod_for_jit")


def test_a_truncated_function_is_healed_where_it_is_loaded(tmp_path, monkeypatch, capsys):
    """A function whose object file was cut short: its load deletes the file, says so
    in one line and compiles the function again (saved anew); a function whose files
    are sound loads without a word, and another function's damaged file is not read."""
    numba = pytest.importorskip("numba")
    (tmp_path / "probe_mod_for_heal2.py").write_text(
        "def twice(x):\n    return 2.0 * x\n\ndef one():\n    return 1.0\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    probe = importlib.import_module("probe_mod_for_heal2")
    folder = str(tmp_path / "nb")
    assert numba_cache.jit(folder)(probe.twice)(3.0) == 6.0
    assert numba_cache.cfunc(numba.types.float64(), folder)(probe.one).ctypes() == 1.0
    (obj,) = Path(folder).rglob("*twice*.nbc")
    (other,) = Path(folder).rglob("*one*.nbc")
    obj.write_bytes(obj.read_bytes()[:64])
    other.write_bytes(other.read_bytes()[:64])
    capsys.readouterr()
    again = numba_cache.jit(folder)(probe.twice)
    assert again(4.0) == 8.0 and sum(again.stats.cache_misses.values()) == 1
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"notice: numba cache file {obj} is damaged (")
    assert line.endswith("); the step is compiled again")
    assert len(obj.read_bytes()) > 64  # saved anew: the next load is a hit
    third = numba_cache.jit(folder)(probe.twice)
    assert third(5.0) == 10.0 and sum(third.stats.cache_hits.values()) == 1
    assert capsys.readouterr().err == "" and len(other.read_bytes()) == 64
    sys.modules.pop("probe_mod_for_heal2")


def test_a_load_that_fails_on_sound_files_is_not_hidden(tmp_path, monkeypatch):
    """A failure of numba's load with every file of the function sound is numba's:
    raised, and no file deleted."""
    pytest.importorskip("numba")
    (tmp_path / "probe_mod_for_heal3.py").write_text("def twice(x):\n    return 2.0 * x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    probe = importlib.import_module("probe_mod_for_heal3")
    folder = str(tmp_path / "nb")
    assert numba_cache.jit(folder)(probe.twice)(3.0) == 6.0
    files = sorted(Path(folder).rglob("*.nb[ci]"))
    again = numba_cache.jit(folder)(probe.twice)

    def fail(sig, target_context):
        raise RuntimeError("numba's own")

    monkeypatch.setattr(again._cache, "_load_overload", fail)
    with pytest.raises(RuntimeError, match="numba's own"):
        again(4.0)
    assert sorted(Path(folder).rglob("*.nb[ci]")) == files
    sys.modules.pop("probe_mod_for_heal3")


@pytest.mark.slow
def test_a_run_after_its_cache_file_was_truncated_heals(tmp_path):
    """A run fills (or finds) the step's cache; a copy of it under ``NUMBA_CACHE_DIR``
    gets the object file of the profiler clock's callback (small, and loaded by every
    run) truncated, and a run on the copy says so, compiles that function again and
    gives the first run's time series byte for byte."""
    cmd = [sys.executable, "-m", "simpro_mj.commands.main", "run", "step_pitch.yaml",
           "--no-plots", "--set", "duration_s=0.2"]  # fmt: skip
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    first = subprocess.run([*cmd, "--out", str(tmp_path / "a")], env=env, capture_output=True,
                           text=True, timeout=900)  # fmt: skip
    assert first.returncode in (0, 1), first.stderr
    where = [sys.executable, "-c", "from simpro_mj.sim import step; print(step._cache_dir())"]
    folder = Path(subprocess.run(where, env=env, capture_output=True, text=True,
                                 check=True).stdout.strip())  # fmt: skip
    copy = tmp_path / "nb" / folder.name
    shutil.copytree(folder, copy)
    files = sorted(copy.rglob("callback.frozen_clock-*.nbc"))
    assert len(files) == 1
    files[0].write_bytes(files[0].read_bytes()[:64])
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "nb")
    again = subprocess.run([*cmd, "--out", str(tmp_path / "b")], env=env, capture_output=True,
                           text=True, timeout=900)  # fmt: skip
    assert again.returncode == first.returncode, again.stderr
    assert f"notice: numba cache file {files[0]} is damaged" in again.stderr
    a = (tmp_path / "a" / "timeseries.csv").read_bytes()
    assert (tmp_path / "b" / "timeseries.csv").read_bytes() == a


def test_a_second_process_waits_for_the_first_compile_and_says_so(tmp_path):
    """While one process holds a folder for its first compile, another says it waits
    and enters only when the first is done; the folder is then marked complete and
    nobody waits for it again."""
    import threading

    fcntl = pytest.importorskip("fcntl")
    folder = tmp_path / "nb"
    folder.mkdir()
    holder = open(folder / ".compile-lock", "a")  # another process's open file: its own lock
    fcntl.flock(holder, fcntl.LOCK_EX)
    said: list[str] = []
    waiting, entered = threading.Event(), threading.Event()

    def say(line):
        said.append(line)
        waiting.set()

    def second():
        with numba_cache.first_compile(str(folder), say):
            entered.set()

    t = threading.Thread(target=second, daemon=True)
    t.start()
    assert waiting.wait(60)  # the readiness signal: it said it waits
    assert not entered.is_set() and not (folder / numba_cache.COMPLETE).exists()
    holder.close()  # the first one's compile ends (a dead process's lock goes the same way)
    t.join(60)
    assert entered.is_set() and said == [numba_cache.WAIT_NOTE]
    assert (folder / numba_cache.COMPLETE).exists()
    # complete: entered at once even while someone holds the lock, nothing said
    holder = open(folder / ".compile-lock", "a")
    fcntl.flock(holder, fcntl.LOCK_EX)
    with numba_cache.first_compile(str(folder), say):
        pass
    holder.close()
    assert said == [numba_cache.WAIT_NOTE]


def test_a_failed_compile_leaves_the_folder_incomplete(tmp_path):
    folder = tmp_path / "nb"
    with pytest.raises(RuntimeError, match="no compile"):
        with numba_cache.first_compile(str(folder)):
            raise RuntimeError("no compile")
    assert folder.is_dir() and not (folder / numba_cache.COMPLETE).exists()
    with numba_cache.first_compile(str(folder)):  # the lock was released with the failure
        pass
    assert (folder / numba_cache.COMPLETE).exists()


def test_a_run_marks_the_steps_cache_complete(monkeypatch):
    from simpro_mj.sim import compiling, step

    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    compiling.prepare_step()
    assert (Path(step.compiled().cache_folder) / numba_cache.COMPLETE).exists()


def test_registering_without_a_run_shares_the_first_compile(monkeypatch):
    """The identification experiment registers its arrays without a run: its callback
    is loaded through prepare_step too, so it waits for another process's compile
    instead of compiling the same step beside it."""
    from simpro_mj.sim import compiling, registration

    monkeypatch.setenv("SIMPRO_KERNEL", "numba")
    calls = []
    real = compiling.prepare_step
    monkeypatch.setattr(compiling, "prepare_step", lambda *a, **k: calls.append(1) or real())
    control, clock = registration._make_callback()
    assert calls == [1] and control and clock
