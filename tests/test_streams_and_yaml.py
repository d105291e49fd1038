"""Output streams that name themselves, a signal during a write that says what was
kept, and YAML numbers read as YAML 1.2 writes them (or refused)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import pytest
import yaml

from simpro_mj.core import safe_yaml
from simpro_mj.core.interrupts import Interrupted, interruptible, writing

RUN = [sys.executable, "-m", "simpro_mj.commands.main", "run", "step_pitch.yaml", "--no-plots",
       "--set", "duration_s=0.2"]  # fmt: skip


def test_a_full_stdout_is_blamed_not_the_out_folder(tmp_path):
    with open("/dev/full", "w") as full:
        r = subprocess.run([*RUN, "--out", str(tmp_path / "r")], stdout=full,
                           stderr=subprocess.PIPE, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 2
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("error: cannot write at <stdout>: No space left on device")
    assert (tmp_path / "r" / "metrics.json").is_file()  # the result is written


def test_a_closed_stderr_is_not_a_crash(tmp_path):
    r = subprocess.run([*RUN, "--out", str(tmp_path / "r")], stdout=subprocess.PIPE,
                       stderr=subprocess.DEVNULL, text=True, timeout=120,
                       pass_fds=(), close_fds=True,
                       preexec_fn=lambda: os.close(2))  # fmt: skip
    assert r.returncode in (0, 1), r.stdout  # ok or not settled after 0.2 s: not 3
    assert f"results: {tmp_path / 'r'}" in r.stdout
    r = subprocess.run([*RUN[:4], "nosuch"], capture_output=False, stdout=subprocess.PIPE,
                       preexec_fn=lambda: os.close(2), timeout=60)  # fmt: skip
    assert r.returncode == 2


def test_a_signal_during_a_write_says_what_was_kept():
    with interruptible(), pytest.raises(Interrupted, match="the ok result in r is kept"):
        with writing(lambda: "the ok result in r is kept, written whole"):
            os.kill(os.getpid(), signal.SIGINT)  # held: the write goes on
            done = True
    assert done


@pytest.mark.parametrize("text", ["0_3", "0x1F", "010", "1:30", "1_000.5"])
def test_yaml_1_1_numbers_are_refused_not_misread(text):
    with pytest.raises(safe_yaml.YAMLLimitError, match="written the YAML 1.1 way"):
        safe_yaml.load(f"duration_s: {text}\n")


def test_yaml_1_2_numbers_and_merge_keys_read():
    doc = safe_yaml.load("a: 0\nb: -3\nc: 0.3\nd: 1.5e3\ne: .inf\nf: '0x1F'\n")
    assert doc == {"a": 0, "b": -3, "c": 0.3, "d": 1500.0, "e": float("inf"), "f": "0x1F"}
    doc = safe_yaml.load("base: &b {x: 1, y: 2}\nother:\n  <<: *b\n  y: 3\n")
    assert doc["other"] == {"x": 1, "y": 3}
    with pytest.raises(yaml.YAMLError, match="duplicate key"):
        safe_yaml.load("a: 1\na: 2\n")
