"""Imports run one way: no cycle among the project's own modules.

The graph is read from the source with :mod:`ast`, not by importing: every
``import`` and ``from ... import`` of ``simpro_mj`` and ``controllers``,
at module level and inside functions alike (an import hidden in a function
still makes the two modules depend on each other; it only hides the cycle
from the interpreter until the function runs). ``if TYPE_CHECKING:`` blocks
are skipped (they never run). A module's implicit import of its own parent
package (``simpro_mj/__init__.py``, run first by Python) is not an edge; an
explicit ``from simpro_mj import run`` is.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("simpro_mj", "controllers")

#: Edges allowed although they close a cycle, with the reason. Empty today:
#: optional extras (numba kernels, imageio, pandas, dask) are third-party and
#: are not nodes of this graph, so they need no exception here.
ALLOWED: dict[tuple[str, str], str] = {}


def _modules() -> dict[str, Path]:
    mods = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            mods[".".join(parts)] = path
    return mods


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the statements inside ``if TYPE_CHECKING:`` blocks."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            test = node.test
            name = test.id if isinstance(test, ast.Name) else getattr(test, "attr", None)
            if name == "TYPE_CHECKING":
                for stmt in node.body:
                    skip.update(id(n) for n in ast.walk(stmt))
    return skip


def _targets(module: str, is_package: bool, node: ast.AST, mods: dict[str, Path]) -> set[str]:
    """The project modules one import statement loads."""
    out: set[str] = set()
    if isinstance(node, ast.Import):
        for alias in node.names:
            parts = alias.name.split(".")
            for i in range(1, len(parts) + 1):  # import a.b.c loads a, a.b and a.b.c
                name = ".".join(parts[:i])
                if name in mods:
                    out.add(name)
        return out
    assert isinstance(node, ast.ImportFrom)
    if node.level:
        here = module.split(".") if is_package else module.split(".")[:-1]
        base_parts = here[: len(here) - (node.level - 1)]
        base = ".".join(base_parts + ([node.module] if node.module else []))
    else:
        base = node.module or ""
    if base in mods:
        out.add(base)
    for alias in node.names:  # from pkg import submodule
        sub = f"{base}.{alias.name}"
        if sub in mods:
            out.add(sub)
    return out


@functools.cache
def _tree(path: Path) -> ast.Module:
    """A module's syntax tree, parsed once per test process (the tests only read it)."""
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def import_graph() -> dict[str, set[str]]:
    """``module -> {modules it imports}`` over simpro_mj and controllers (any level): a
    fresh copy of :func:`_graph`, which is read once per test process."""
    return {name: set(targets) for name, targets in _graph().items()}


@functools.cache
def _graph() -> dict[str, set[str]]:
    mods = _modules()
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        tree = _tree(path)
        skip = _type_checking_nodes(tree)
        edges: set[str] = set()
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in skip:
                edges |= _targets(name, path.stem == "__init__", node, mods)
        edges.discard(name)
        graph[name] = {t for t in edges if (name, t) not in ALLOWED}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _path_in(comp: list[str], graph: dict[str, set[str]]) -> str:
    """One closed walk through a component, for the failure message."""
    members = set(comp)
    start = comp[0]
    walk, seen, v = [start], {start}, start
    while True:
        nxt = sorted(graph[v] & members)
        back = [w for w in nxt if w in seen]
        new = [w for w in nxt if w not in seen]
        if start in nxt and len(walk) > 1:
            return " -> ".join(walk + [start])
        if not new:
            return " -> ".join(walk + [back[0]]) if back else " -> ".join(walk)
        v = new[0]
        walk.append(v)
        seen.add(v)


def test_the_graph_is_read():
    """The walker sees module-level, function-level and relative imports (not a vacuous graph)."""
    graph = import_graph()
    assert "simpro_mj.config.scenario" in graph and "controllers.joint" in graph
    # cmd_run wires the runner (module level, relative)
    assert "simpro_mj.report.runner" in graph["simpro_mj.commands.run"]
    # the controllers' design imports its errors (module level)
    assert "controllers.errors" in graph["controllers.design"]
    # a function-level import counts: the API builds the runner lazily
    assert "simpro_mj.report.runner" in graph["simpro_mj.api"]


def test_a_cycle_is_found():
    """The detector flags a two-module and a three-module cycle and leaves a chain alone."""
    assert cycles({"a": {"b"}, "b": {"a"}}) == [["a", "b"]]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_no_import_cycle():
    graph = import_graph()
    found = cycles(graph)
    if found:
        pytest.fail(
            "import cycle(s) among the project's modules (module or function level): "
            + "; ".join(_path_in(c, graph) for c in found)
        )


def test_controllers_import_no_simulation_module():
    """controllers stand alone: no import of simpro_mj or MuJoCo anywhere in their source."""
    bad = []
    for name, path in _modules().items():
        if not name.startswith("controllers"):
            continue
        for node in ast.walk(_tree(path)):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                names = [node.module or ""]
            bad += [f"{name}: {n}" for n in names if n.split(".")[0] in ("simpro_mj", "mujoco")]
    assert not bad, bad


#: The rooms of ``simpro_mj`` from the bottom up (docs/architecture.md): a room
#: imports only the rooms before it. ``api`` sits on top of all of them.
ROOMS = (
    "core",
    "plant",
    "config",
    "identification",
    "sim",
    "analysis",
    "job",
    "report",
    "batch",
    "commands",
    "api",
)


def _room(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "simpro_mj" or len(parts) == 1:
        return None
    return parts[1]


def test_every_module_is_in_a_room():
    """No module left in the flat folder: each sits in one of the rooms."""
    stray = [m for m in _modules() if m.startswith("simpro_mj.") and _room(m) not in ROOMS]
    assert not stray, f"modules outside the rooms {ROOMS}: {stray}"


#: Upward imports made on purpose, each inside one function, with the reason.
UPWARD = {
    # the Fig. 12 experiment runs on the run's own step (one source, one numba
    # compilation and cache for both), imported when it runs
    ("simpro_mj.identification.identify", "simpro_mj.sim.experiment"),
    # the reduced experiment binds the step's own compiled pneumatics and law (one
    # source) into its stepper, and keeps its numba cache as the step does
    ("simpro_mj.identification.reduced_experiment", "simpro_mj.sim.step"),
    ("simpro_mj.identification.reduced_experiment", "simpro_mj.sim.numba_cache"),
    # the sensitivity fit's compiled pass keeps its numba cache beside the step's
    ("simpro_mj.identification.sensitivity_fit", "simpro_mj.sim.step"),
    ("simpro_mj.identification.sensitivity_fit", "simpro_mj.sim.numba_cache"),
}


def test_rooms_import_one_way():
    """A room imports only the rooms below it (core < plant < config < identification <
    sim < analysis < report < batch < commands < api), at module or function level,
    but for the few of :data:`UPWARD`, each named with its reason."""
    rank = {r: i for i, r in enumerate(ROOMS)}
    bad = []
    for src, targets in import_graph().items():
        a = _room(src)
        if a is None:
            continue
        for dst in targets:
            b = _room(dst)
            if b is not None and rank[b] > rank[a] and (src, dst) not in UPWARD:
                bad.append(f"{src} -> {dst}")
    assert not bad, "imports against the rooms' order: " + "; ".join(sorted(bad))


def _commands_importing_commands(graph: dict[str, set[str]]) -> list[str]:
    """``src -> dst`` for every command module importing another (``main`` excepted)."""
    commands = {m for m in graph if m.startswith("simpro_mj.commands.")}
    return sorted(
        f"{src} -> {dst}"
        for src in commands
        if src != "simpro_mj.commands.main"
        for dst in graph[src]
        if dst in commands
    )


def test_commands_import_no_other_command():
    """Commands only wire: a command module imports no other command module (what two
    commands share lives in a room below, e.g. ``report.video_options``); only
    ``commands.main`` knows them all, by name (``importlib`` through ``COMMANDS``)."""
    graph = import_graph()
    bad = _commands_importing_commands(graph)
    assert not bad, "a command imports another command: " + "; ".join(bad)
    # the check flags a command importing another, and lets main import them all
    fake = {
        "simpro_mj.commands.main": {"simpro_mj.commands.a"},
        "simpro_mj.commands.a": {"simpro_mj.commands.b", "simpro_mj.report.x"},
        "simpro_mj.commands.b": set(),
    }
    assert _commands_importing_commands(fake) == ["simpro_mj.commands.a -> simpro_mj.commands.b"]
    # main loads every command by name: each is a module of this room, and every
    # module of the room but main is a command
    from simpro_mj.commands.main import COMMANDS

    commands = {m for m in graph if m.startswith("simpro_mj.commands.")}
    assert set(COMMANDS.values()) == commands - {"simpro_mj.commands.main"}


def test_every_project_import_resolves():
    """Every import of simpro_mj or controllers names a module that exists (a relative
    import left pointing into a moved package fails only when its function runs)."""
    mods = _modules()
    bad = []
    for name, path in mods.items():
        is_package = path.stem == "__init__"
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    here = name.split(".") if is_package else name.split(".")[:-1]
                    parts = here[: len(here) - (node.level - 1)]
                    base = ".".join(parts + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                if base.split(".")[0] in PACKAGES and base not in mods:
                    bad.append(f"{name}:{node.lineno}: from {base}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.split(".")[0] in PACKAGES and alias.name not in mods:
                        bad.append(f"{name}:{node.lineno}: import {alias.name}")
    assert not bad, "imports of modules that do not exist: " + "; ".join(bad)
