"""Ctrl-C and SIGTERM are never lost inside an import (simpro_mj.core.interrupts).

A compiled module built with pybind11 (MuJoCo's bindings, parts of SciPy and
Matplotlib) turns an exception raised during its initialisation into
``ImportError: initialization failed``. A Ctrl-C whose handler ran there was
lost: a batch reported its first variant ``failed`` and ran the next one to
its end, and a run ended as an "internal error". These tests put the signal
inside an import deterministically: the process sends it to itself from code
that runs while the import is in progress, and a stand-in for pybind11
converts the interrupt as pybind11 does (``catch (error_already_set&)`` ->
``ImportError``). No test waits for time to pass.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
linux = pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="POSIX signals")

# A meta-path finder that, the first time the module named by ``sys.argv[2]`` is
# imported (``mujoco`` unless given), sends the
# signal to this process and then runs Python code as an extension's
# initialisation would, converting an exception the way pybind11 does. It finds
# nothing itself: the real import proceeds afterwards.
_TRAP = textwrap.dedent(
    """
    import os, signal, sys

    class Trap:
        def find_spec(self, name, path=None, target=None):
            if name != (sys.argv[2] if len(sys.argv) > 2 else "mujoco"):
                return None
            sys.meta_path.remove(self)
            try:  # the extension's init: the signal's handler runs in this code
                os.kill(os.getpid(), getattr(signal, sys.argv[1]))
                total = 0
                for i in range(100000):
                    total += i
            except BaseException as exc:
                raise ImportError("initialization failed") from exc
            return None

    sys.meta_path.insert(0, Trap())
    """
)


def _script(body: str) -> str:
    return _TRAP + textwrap.dedent(body)


def _default_sigint() -> None:
    """In the child before exec: SIGINT to its default, so that Python installs its own
    handler whatever this process inherited (nohup, or a runner that starts its jobs
    with SIGINT ignored, which Python then keeps ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _python(tmp_path: Path, body: str, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT))
    env.pop("MUJOCO_GL", None)  # else main imports MuJoCo to check the backend, first
    return subprocess.run(
        [sys.executable, "-c", _script(body), *args],
        cwd=tmp_path,
        env=env,
        preexec_fn=_default_sigint,
        capture_output=True,
        text=True,
        timeout=600,  # a bound against a broken build, not a timing assumption
    )


@linux
@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_signal_inside_an_import_is_raised_when_the_import_ends(tmp_path, sig):
    """An import inside held_signals (as main imports a command's modules and a run its
    simulation's): the import completes (the module is usable), the interrupt follows
    it, and the process exits with the status the program chose, not from SIGINT."""
    body = """
    from simpro_mj.core.interrupts import held_signals, interruptible
    with interruptible():
        try:
            with held_signals():
                import mujoco
            print("not interrupted")
        except KeyboardInterrupt as exc:
            mj = sys.modules["mujoco"]
            print("interrupted", repr(str(exc)), mj.MjModel.__name__, sep="|")
        except ImportError as exc:
            print("lost:", exc)
    sys.exit(7)
    """
    proc = _python(tmp_path, body, sig)
    assert proc.returncode == 7, proc.stderr
    expected = "''" if sig == "SIGINT" else "'signal SIGTERM'"
    assert proc.stdout.strip().split("|") == ["interrupted", expected, "MjModel"], proc.stdout


@linux
def test_without_the_guard_the_stand_in_loses_the_interrupt(tmp_path):
    """The other half of the experiment: with Python's own handler the same
    import fails with ImportError, so the test above can tell the difference."""
    body = """
    try:
        import mujoco
        print("imported")
    except KeyboardInterrupt:
        print("interrupted")
    except ImportError as exc:
        print("lost:", exc)
    """
    proc = _python(tmp_path, body, "SIGINT")
    assert proc.stdout.strip() == "lost: initialization failed", proc.stdout + proc.stderr


def test_held_signals_raise_at_the_end_and_restore_the_handlers():
    """Without interruptible (the Python API): a signal in the block is raised
    when the block ends, and the handlers in place before are back."""
    from simpro_mj.core.interrupts import held_signals

    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    reached_end = False
    with pytest.raises(KeyboardInterrupt, match="signal SIGTERM"):
        with held_signals():
            signal.raise_signal(signal.SIGTERM)
            signal.raise_signal(signal.SIGINT)  # the first one held is the one raised
            reached_end = True
    assert reached_end
    assert {s: signal.getsignal(s) for s in before} == before


#: The module a run imports when it starts stepping (it loads MuJoCo): the signal
#: comes inside the variant, after the batch has planned and written its marker.
LOOP = "simpro_mj.sim.loop"


def _long_sweep(tmp_path: Path, duration_s: float) -> Path:
    doc = {"name": "long", "duration_s": duration_s, "sweep": {"grid": {"seed": [1, 2]}}}
    path = tmp_path / "long.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@linux
def test_ctrl_c_while_a_variant_imports_the_loop_stops_the_batch(tmp_path):
    """Without the hold the first variant would read ``failed: ImportError`` and the
    second run to its end; the batch stops with both cancelled, exit 130."""
    sweep = _long_sweep(tmp_path, 30.0)
    body = f"""
    from simpro_mj.commands.main import main
    sys.exit(main(["batch", {str(sweep)!r}, "--jobs", "1", "--out", "out", "--no-plots"]))
    """
    proc = _python(tmp_path, body, "SIGINT", LOOP)
    assert proc.returncode == 130, proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("error: batch stopped: interrupted; 0 variant(s) finished"), last
    assert "Traceback" not in proc.stderr
    doc = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert [v["status"] for v in doc["variants"]] == ["cancelled", "cancelled"]


@linux
def test_sigterm_while_a_run_imports_the_loop_exits_130(tmp_path):
    """Before the fix: ``error: internal error ... ImportError`` and exit 3."""
    body = """
    from simpro_mj.commands.main import main
    sys.exit(main(["run", "step_pitch.yaml", "--set", "duration_s=1", "--out", "out"]))
    """
    proc = _python(tmp_path, body, "SIGTERM", LOOP)
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("error: interrupted"), proc.stderr
    assert "internal error" not in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").iterdir())
