"""Hostile input is refused fast: the catalogue beside test_robustness's.

Every row is a class of hostile input with a case that hangs or crashes a naive
loader (and one more of the same class): through ``simpro_mj.commands.main.main``
it exits 2 with one line ``error: ... at <field>: ...; allowed: <bound>`` of readable length,
naming the field the user typed. A case that would hang fails through a 300 s
alarm instead of hanging the suite (a guard, not a timing assertion: the
refusals take milliseconds; docs/robustness.md states the figures).

Then a hypothesis fuzz of the YAML structure (anchors and aliases, nesting,
size, long numbers): the file loader returns a bounded mapping or raises
``UserInputError`` with one line, nothing else.
"""

from __future__ import annotations

import json
import signal
import sys
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simpro_mj.commands.main import main
from simpro_mj.config.scenario import load_scenario
from simpro_mj.config.sweep import MAX_VARIANTS
from simpro_mj.core import safe_yaml
from simpro_mj.core.errors import UserInputError

#: A readable error line: the 100,000-character key is cut (one line, < 400 chars).
READABLE = 400


@pytest.fixture(autouse=True)
def no_hang():
    """Fail a case that hangs instead of hanging the suite (SIGALRM, main thread)."""

    def hung(signum, frame):  # noqa: ARG001
        raise AssertionError("a hostile input was not refused (still running after 300 s)")

    # a hang guard, not a speed check: far above any case's run time even on a loaded
    # 2-core machine (a 0.5 s run took over 60 s at load 14 there)
    previous = signal.signal(signal.SIGALRM, hung)
    signal.alarm(300)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def _bomb(levels: int = 9, width: int = 9) -> str:
    """The "billion laughs": level k is a list of ``width`` aliases of level k - 1."""
    names = [f"l{k}" for k in range(levels)]
    lines = [f"{names[0]}: &{names[0]} [{', '.join(['x'] * width)}]"]
    for k in range(1, levels):
        lines.append(f"{names[k]}: &{names[k]} [{', '.join([f'*{names[k - 1]}'] * width)}]")
    return "\n".join(lines) + "\n"


def _alias_depth_chain(levels: int = 30, depth: int = 10) -> str:
    """Each anchor nests the previous one ``depth`` levels deeper: shallow in the
    file (under 50), deep once expanded (levels * depth)."""
    lines = ["a0: &a0 1"]
    for k in range(1, levels):
        lines.append(f"a{k}: &a{k} " + "[" * depth + f"*a{k - 1}" + "]" * depth)
    return "\n".join(lines) + "\n"


def _grid_of(n_paths: int, n_values: int) -> str:
    paths = ["controller.outer.gains", "controller.outer.pi_zero", "plant.payload.mass_kg",
             "seed", "sensors.imu.noise_deg", "plant.platform_mass_kg"]  # fmt: skip
    grid = {p: list(range(1, n_values + 1)) for p in paths[:n_paths]}
    return yaml.safe_dump({"duration_s": 2.0, "sweep": {"grid": grid}})


#: name -> file content (str) or size (int: a sparse file of that many bytes)
FILES = {
    "bomb.yaml": _bomb(),
    "bomb_small.yaml": _bomb(levels=7, width=10),  # 10^7: the same class, other numbers
    "recursive.yaml": "a: &a [1, *a]\n",
    "alias_deep.yaml": _alias_depth_chain(),
    "brackets.yaml": "a: " + "[" * 5000 + "]" * 5000 + "\n",
    "braces.yaml": "a: " + "{b: " * 300 + "1" + "}" * 300 + "\n",
    "huge.yaml": 60_000_000,
    "just_over.yaml": safe_yaml.MAX_FILE_BYTES + 1,
    "int401.yaml": "duration_s: " + "9" * 401 + "\n",
    "float_long.yaml": "duration_s: 1." + "0" * 80 + "1\n",
    "empty.yaml": "",
    "comments.yaml": "# a scenario\n\n# nothing else\n",
    "longkey.yaml": "? " + "k" * 100_000 + "\n: 1\n",  # an explicit key: no 1024 limit
    "grid1e6.yaml": _grid_of(4, 32),
    "grid_over.yaml": _grid_of(2, 101),  # 10,201 > 10,000
}


@pytest.fixture(scope="module")
def hostile(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("hostile")
    for name, content in FILES.items():
        if isinstance(content, int):
            with (d / name).open("wb") as fh:
                fh.truncate(content)
        else:
            (d / name).write_text(content, encoding="utf-8")
    return d


RUN = ["run", "step_pitch", "--no-plots", "--out", "{tmp}/out"]


def _set(*exprs: str) -> list[str]:
    return [a for e in exprs for a in ("--set", e)]


CASES = [
    # --- file size, aliases, depth, number length, empty (the file loader) ---
    ("alias bomb 9^9", ["run", "{tmp}/bomb.yaml"], "bomb.yaml line", ["at most 200,000 values"]),
    ("alias bomb 10^7", ["run", "{tmp}/bomb_small.yaml"], "bomb_small.yaml", ["200,000 values"]),
    ("recursive alias", ["run", "{tmp}/recursive.yaml"], "recursive.yaml", ["own anchor"]),
    ("alias depth", ["run", "{tmp}/alias_deep.yaml"], "alias_deep.yaml", ["50 levels"]),
    ("5000 brackets", ["run", "{tmp}/brackets.yaml"], "brackets.yaml line 1", ["50 levels"]),
    ("300 braces", ["run", "{tmp}/braces.yaml"], "braces.yaml line 1", ["50 levels"]),
    ("60 MB file", ["run", "{tmp}/huge.yaml"], "huge.yaml", ["at most 500,000 bytes"]),
    ("file 1 byte over", ["batch", "{tmp}/just_over.yaml", "--strict"], "just_over", ["bytes"]),
    ("401-digit int", ["run", "{tmp}/int401.yaml"], "int401.yaml line 1", ["40 characters"]),
    ("83-char float", ["run", "{tmp}/float_long.yaml"], "float_long.yaml", ["40 characters"]),
    ("empty file", ["run", "{tmp}/empty.yaml"], "empty.yaml", ["a mapping of scenario keys"]),
    ("comments only", ["run", "{tmp}/comments.yaml"], "comments.yaml", ["scenario keys"]),
    ("100k-char key in a file", ["run", "{tmp}/longkey.yaml"], "kkkk", ["allowed keys"]),
    # --- --set values: the same bounds ---
    ("5000-digit seed", [*RUN, *_set("seed=" + "9" * 5000)], "seed", ["40 characters"]),
    ("300-digit duration", [*RUN, *_set("duration_s=" + "9" * 300)], "duration_s", ["40"]),
    ("deep --set", [*RUN, *_set("faults=" + "[" * 2000 + "]" * 2000)], "faults", ["50 levels"]),
    ("alias --set", [*RUN, *_set("faults=[&a [1,1], *a]")], "faults", ["allowed"]),
    ("100k-char --set key", [*RUN, *_set("a" * 100_000 + "=1")], "aaaa", ["allowed keys"]),
    ("100k-char --set value", [*RUN, *_set("name=" + "n" * 100_000)], "name", ["letters"]),
    # --- upper bounds: periods, rates, durations, counts ---
    (
        "period 1e8 ms",
        [*RUN, *_set("controller.outer.period_ms=1e8")],
        "controller.outer.period_ms",
        ["<= 10000 ms"],
    ),  # fmt: skip
    ("period 20 s", [*RUN, *_set("controller.outer.period_ms=20000")], "period_ms", ["10000"]),
    (
        "sensor rate 1e7 ms",
        [*RUN, *_set("sensors.imu.rate_ms=1e7")],
        "sensors.imu.rate_ms",
        ["<= 10000 ms"],
    ),  # fmt: skip
    (
        "decimation 1e12",
        [*RUN, *_set("logging.decimation=1000000000000")],
        "logging.decimation",
        ["1..10000"],
    ),  # fmt: skip
    ("duration 1e-9", [*RUN, *_set("duration_s=1e-9")], "duration_s", [">= 0.01 s"]),
    ("duration 1e300", [*RUN, *_set("duration_s=1e300")], "duration_s", ["<= 3600 s"]),
    (
        "sine period 1e-300",
        [*RUN, *_set("setpoint.pitch_deg=[{type: sine, amplitude: 1, period_s: 1e-300}]")],
        "setpoint.pitch_deg[0].period_s",
        ["0.002 s"],
    ),  # fmt: skip
    (
        "sine period 1e300",
        [*RUN, *_set("setpoint.pitch_deg=[{type: sine, amplitude: 1, period_s: 1e300}]")],
        "period_s",
        ["1e+06 s"],
    ),  # fmt: skip
    (
        "payload 1e6 kg",
        [*RUN, *_set("plant.payload.mass_kg=1e6")],
        "plant.payload.mass_kg",
        ["0..5000 kg", "3,750 kg"],
    ),  # fmt: skip
    (
        "grid of 10^6 (run)",
        ["run", "{tmp}/grid1e6.yaml"],
        "sweep",
        ["32 x 32 x 32 x 32 = 1,048,576", f"at most {MAX_VARIANTS:,}"],
    ),  # fmt: skip
    (
        "grid over (batch)",
        ["batch", "{tmp}/grid_over.yaml", "--strict", "--out", "{tmp}/b"],
        "grid_over.yaml",
        ["10,201", "at most 10,000"],
    ),  # fmt: skip
    (
        "jobs 100000",
        ["batch", "step_pitch", "--jobs", "100000", "--out", "{tmp}/b2"],
        "--jobs",
        ["1..256"],
    ),  # fmt: skip
    ("bench repeats 1e8", ["bench", "--repeats", "100000000"], "--repeats", ["1..100"]),
    ("bench repeats 1e8 (text)", ["bench", "--repeats", "1e8"], "--repeats", ["1..100"]),
    ("bench repeats 5000 digits", ["bench", "--repeats", "9" * 5000], "--repeats", ["1..100"]),
    ("bench batch-runs 1e6", ["bench", "--batch-runs", "1000000"], "--batch-runs", ["1..64"]),
    # --- the misleading messages: the field typed, numbers as numbers, 'allowed:' ---
    (
        "validate-ik -1e9",
        ["validate-ik", *_set("trajectory.duration_s=-1e9")],
        "trajectory.duration_s",
        ["-1000000000.0", "allowed: "],
    ),  # fmt: skip
    ("workspace -1e9", ["workspace", *_set("margin_mm=-1e9")], "margin_mm", ["allowed: "]),
    (
        "workspace wrong type",
        ["workspace", *_set("margin_mm=abc")],
        "margin_mm",
        ["allowed: a number"],
    ),  # fmt: skip
]


@pytest.mark.parametrize(("argv", "field", "expected"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])  # fmt: skip
def test_hostile_input_is_one_line_exit_2(hostile, capsys, argv, field, expected):
    argv = [a.replace("{tmp}", str(hostile)) for a in argv]
    rc = main(argv)
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert rc == 2, captured.err[-2000:]
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err[:2000]
    line = lines[0]
    assert len(line) < READABLE, line[:READABLE]
    assert field in line, line
    assert "allowed" in line, line
    for text in expected:
        assert text in line, line
    assert "Traceback" not in captured.err


def test_a_set_point_after_the_end_is_warned_and_recorded(tmp_path, capsys):
    """Not refused (a short run of a shipped scenario cuts its steps off on purpose),
    never silent: one warning line per component, recorded in metrics.json."""
    out = tmp_path / "r"
    sine = "setpoint.roll_deg=[{type: sine, amplitude: 1, period_s: 2, start_s: 9}]"
    argv = ["run", "step_pitch", "--no-plots", "--out", str(out), *_set("duration_s=0.5", sine)]
    code = main(argv)
    assert code == (0 if json.loads((out / "metrics.json").read_text())["status"] == "ok" else 1)
    lines = [x for x in capsys.readouterr().err.splitlines() if x.startswith("warning: ")]
    assert lines == [
        "warning: setpoint.roll_deg[0].start_s = 9 s is after the end of the run "
        "(duration_s = 0.5 s): this sine never acts",
        "warning: setpoint.pitch_deg[0].time_s = 1 s is after the end of the run "
        "(duration_s = 0.5 s): this step never acts",
    ]
    doc = json.loads((out / "metrics.json").read_text())
    assert [f"warning: {w}" for w in doc["warnings"]] == lines


def test_a_grid_of_a_million_is_counted_not_expanded(hostile, monkeypatch):
    """Without --strict the file is an invalid row of the batch; nothing is expanded."""
    import simpro_mj.config.variants as variants

    def never(spec):
        raise AssertionError("expanded")

    monkeypatch.setattr(variants, "expand", never)
    from simpro_mj.batch.plan import plan

    p = plan([str(hostile / "grid1e6.yaml")])
    assert len(p.jobs) == 1 and "1,048,576" in p.jobs[0].error


def test_local_dask_starts_no_more_workers_than_tasks(monkeypatch, tmp_path):
    distributed = pytest.importorskip("distributed")
    started = {}

    class Refuse(Exception):
        pass

    def fake_cluster(**kw):
        started.update(kw)
        raise Refuse

    monkeypatch.setattr(distributed, "LocalCluster", fake_cluster)
    from simpro_mj.batch.worker import run_variant
    from simpro_mj.sim import executors

    with pytest.raises(Refuse):
        executors.run_dask([(0, {})], "local", 12, lambda k, r: None, fn=run_variant)
    assert started["n_workers"] == 1


def test_a_legit_large_table_is_read(tmp_path):
    """The bounds leave room: a 10,000-point table set-point loads."""
    n = 10_000
    times = ", ".join(f"{i * 1e-3:.3f}" for i in range(n))
    values = ", ".join("0.5" for _ in range(n))
    text = (
        "duration_s: 12\nsetpoint:\n  pitch_deg:\n"
        f"    - {{type: table, times_s: [{times}], values: [{values}]}}\n"
    )
    path = tmp_path / "table.yaml"
    path.write_text(text)
    assert path.stat().st_size < safe_yaml.MAX_FILE_BYTES
    sc = load_scenario(str(path))
    assert len(sc.setpoint.pitch_deg[0].times_s) == n


def test_anchors_within_the_bounds_still_work(tmp_path):
    path = tmp_path / "anchors.yaml"
    path.write_text(
        "duration_s: 2\ncontroller:\n  outer:\n    gains: &g [0.5, 0.5, 0.5]\n"
        "sensors:\n  potentiometer:\n    gain_error_pct: *g\n"
    )
    sc = load_scenario(str(path))
    assert sc.sensors.potentiometer.gain_error_pct == [0.5, 0.5, 0.5]


# ------------------------------------------------------------------ YAML structure fuzz

_leaf = st.one_of(
    st.integers(-(10**60), 10**60).map(str),
    st.floats(allow_nan=False).map(repr),
    st.sampled_from(["x", "1e9", "-1e9", ".inf", "~", "true", "'a'", '"b"', "1e99999"]),
)


#: Nodes drawn per document, beyond which every value is a plain ``0``: room for each
#: shape a naive loader breaks on (five anchors of 12 aliases, each of the one before,
#: expand past ``safe_yaml.MAX_NODES``: 12**5 > 200,000; a ``deep`` node nests past
#: ``MAX_DEPTH``; the repeats give size and duplicate keys). Without the bound, trees 12
#: wide and 5 deep overrun Hypothesis's buffer (the example is thrown away) and the
#: test's time goes into drawing their leaves. The catalogue above has one case of each.
_NODES = 80


@st.composite
def yaml_structures(draw):
    """YAML text with anchors, aliases (to finished anchors, to unfinished ones),
    nesting of random depth and repeated blocks: the shapes that break naive loaders."""
    anchors: list[str] = []
    drawn = [0]

    def node(depth: int) -> str:
        if drawn[0] >= _NODES:
            return "0"
        drawn[0] += 1
        kind = draw(st.sampled_from(["leaf", "list", "map", "alias", "deep"]))
        if kind == "alias" and anchors:
            return "*" + draw(st.sampled_from(anchors))
        if kind == "deep":
            n = draw(st.integers(1, 120))
            return "[" * n + draw(_leaf) + "]" * n
        if kind == "leaf" or depth > 4:
            return draw(_leaf)
        items = [node(depth + 1) for _ in range(draw(st.integers(0, 12)))]
        if draw(st.booleans()):
            name = f"a{len(anchors)}"
            anchors.append(name)
            if draw(st.integers(0, 9)) == 0:  # an alias inside its own anchor
                items.append("*" + name)
            prefix = f"&{name} "
        else:
            prefix = ""
        if kind == "list":
            return prefix + "[" + ", ".join(items) + "]"
        return prefix + "{" + ", ".join(f"k{i}: {v}" for i, v in enumerate(items)) + "}"

    keys = draw(st.lists(st.sampled_from(["duration_s", "seed", "description", "faults",
                                          "controller", "zz", "k" * 300]),  # fmt: skip
                         min_size=1, max_size=4, unique=True))  # fmt: skip
    lines = [f"{k}: {node(0)}" for k in keys]
    text = "\n".join(lines) + "\n"
    return text * draw(st.sampled_from([1, 1, 1, 2, 500]))  # repeats: duplicate keys, size


def _expanded_size(obj, seen_depth: int = 0) -> int:
    if seen_depth > safe_yaml.MAX_DEPTH + 1:
        raise AssertionError("deeper than the bound")
    if isinstance(obj, dict):
        return 1 + sum(_expanded_size(v, seen_depth + 1) + 1 for v in obj.values())
    if isinstance(obj, list):
        return 1 + sum(_expanded_size(v, seen_depth + 1) for v in obj)
    return 1


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(yaml_structures())
def test_yaml_structure_is_bounded_or_refused(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("fuzz") / "fuzz.yaml"
    path.write_text(text, encoding="utf-8")
    try:
        doc = safe_yaml.read_file(path)
    except yaml.YAMLError as exc:
        assert str(exc)
    else:
        assert _expanded_size(doc) <= 2 * safe_yaml.MAX_NODES
    try:
        load_scenario(str(path))
    except UserInputError as exc:
        message = str(exc)
        assert "\n" not in message and len(message) < 2000 and " at " in message
    except RecursionError:  # pragma: no cover - the bug class this fuzzer guards
        raise AssertionError(f"RecursionError on {text[:200]!r}") from None
    assert sys.getrecursionlimit() >= 1000
