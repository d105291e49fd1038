"""The README stays true: short, no history, its commands parse, its example runs as a
script, and its figures are what the commands it names print."""

from __future__ import annotations

import io
import math
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", README, flags=re.S)


def test_short_and_without_history():
    assert len(README.splitlines()) < 200
    for pattern in (r"\bissue \d+", r"\b[0-9a-f]{7,40}\b", r"\bpreviously\b", r"\bthe old\b"):
        assert not re.search(pattern, README), pattern


def test_links_point_to_files():
    for path in re.findall(r"`((?:docs|tests)/[\w./-]+\.(?:md|py|png))`", README):
        assert (ROOT / path).is_file(), path
    for path in re.findall(r"\]\(([\w./-]+)\)", README):
        assert (ROOT / path).is_file(), path


def test_every_command_line_parses():
    from simpro_mj.commands.main import build_parser

    parser, _ = build_parser(every=True)
    lines = [ln.split("#")[0].strip() for b in _blocks("bash") for ln in b.splitlines()]
    commands = []
    for line in lines:
        for part in line.split("&&"):
            words = shlex.split(part)
            if words and words[0].endswith("simpro-sim"):
                commands.append(words[1:])
    assert len(commands) >= 6
    for argv in commands:
        args = parser.parse_args(argv)  # exits 2 on an unknown command or option
        if getattr(args, "scenario", None):
            from simpro_mj.config.scenario import load_scenario

            load_scenario(args.scenario, args.sets)


def test_printed_run_summary_is_what_run_prints():
    import simpro_mj as s
    from simpro_mj.report.results import print_summary

    (shown,) = [b for b in _blocks("text") if b.startswith("status:")]
    r = s.run("step_pitch")
    buf = io.StringIO()
    print_summary({**r.metrics, "status": r.status}, file=buf)
    assert buf.getvalue().strip() == shown.strip()
    floor = math.degrees(r.metrics["sensor_floor"]["pitch"])
    assert f"pitch sensor's floor is {floor:.4f}°" in " ".join(README.split())


def test_compare_table_is_what_compare_prints():
    import simpro_mj as s

    table = README.split("<!-- checked by tests/test_readme.py -->")[1].split("\n\n")[0]
    both = s.compare("step_all")
    for axis, scale, unit in (("roll", 180 / math.pi, "°"), ("pitch", 180 / math.pi, "°"),
                              ("heave", 1e3, " mm")):  # fmt: skip
        (row,) = [ln for ln in table.splitlines() if ln.startswith(f"| {axis} |")]
        cells = [c.strip() for c in row.strip("|").split("|")][1:]
        for cell, mode in zip(cells, ("joint_only", "task_space"), strict=True):
            value = abs(both[mode].metrics["axes"][axis]["steady_state_error"]) * scale
            digits = len(cell.removesuffix(unit).split(".")[1])
            shown = f"{value:.{digits}f}{unit}"
            assert cell == shown, (axis, mode)


def test_python_example_runs_as_a_script(tmp_path):
    (code,) = _blocks("python")
    script = tmp_path / "example.py"
    script.write_text(code, encoding="utf-8")
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("ok pitch overshoot")
    assert len(lines) == 4 and all(ln.endswith(" ok") for ln in lines[1:])  # once, not per worker
    assert (tmp_path / "step_pitch.png").stat().st_size > 10_000


def test_unguarded_parallel_sweep_runs_the_script_once(tmp_path):
    """The spawned workers do not import the calling script (sim.workers.main_not_imported):
    an unguarded script's body runs once, not once more per worker."""
    script = tmp_path / "unguarded.py"
    script.write_text(
        "import simpro_mj as s\n"
        "print('body')\n"
        "sw = s.sweep('track_cues', {'duration_s': 0.5}, jobs=2, processes=True)\n"
        "print(*[r['status'] for r in sw.rows()])\n",
        encoding="utf-8",
    )
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    body, statuses = proc.stdout.splitlines()
    assert body == "body"
    # every variant ran (0.5 s: the verdict may find a sine not yet tracked to its floor)
    assert len(statuses.split()) == 3
    assert set(statuses.split()) <= {"ok", "not_settled"}, statuses


def test_a_sweep_with_no_variant_run_raises(monkeypatch):
    """Every variant failed (a broken pool): SweepError naming why, not rows of failures."""
    import simpro_mj as s
    from simpro_mj import api

    def broken(task):
        return {"status": "failed", "reason": "BrokenProcessPool: a worker died", "metrics": None}

    monkeypatch.setattr(api, "_measured", broken)
    with pytest.raises(s.SweepError, match="every variant failed: BrokenProcessPool"):
        s.sweep("track_cues", {"duration_s": 0.5})
