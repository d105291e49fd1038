"""The ``simpro-sim`` command line: it only wires.

Every subcommand lives in its own module ``simpro_mj.commands.<name>`` exposing

* ``HELP``: one-line description,
* ``add_arguments(parser)``: its own options,
* ``run(args) -> int``: the job (exit code).

and, when it takes fewer than all of the shared options, ``COMMON_OPTIONS``.

Shared options (added here, to the commands where they mean something):
``--set KEY=VALUE`` (dotted path, repeatable) overrides any parameter, ``--json``
prints exactly one JSON object on stdout and nothing else there, ``--quiet`` draws
no progress bar and prints no warnings; ``--out DIR`` chooses where files go. A
user's mistake exits 2 with one line ``error: ...`` on stderr.

``simpro-sim --help`` and a mistake in the command's name import no command
module: each command's one-line ``HELP`` is read from its source. A command's own
``--help`` imports its module only, whose heavy imports wait for ``run``.

Exit codes: 0 done, 1 the simulation diverged, 2 a user's mistake (bad
scenario, ``--set``, arguments, a file that cannot be read or written),
3 an internal error (a bug: one line on stderr; ``SIMPRO_DEBUG=1`` shows the
traceback), 130 interrupted (Ctrl-C, SIGTERM, SIGHUP), 141 stdout closed.
docs/robustness.md lists the messages.
"""

from __future__ import annotations

import argparse
import ast
import functools
import gc
import importlib.util
import os
import sys
from pathlib import Path

from controllers.errors import DesignError, KinematicsError
from simpro_mj.core.cache import notice
from simpro_mj.core.environment import environment_problem, matplotlib_home
from simpro_mj.core.errors import PhysicsError, UserInputError
from simpro_mj.core.interrupts import Interrupted, held_signals, import_module, interruptible
from simpro_mj.core.messages import MAX_MESSAGE_CHARS, one_line
from simpro_mj.core.streams import StreamError, standard_streams

#: an error line of this command line: one line, at most MAX_MESSAGE_CHARS
_one_line = functools.partial(one_line, max_chars=MAX_MESSAGE_CHARS)

#: subcommand -> module; a module that does not exist yet is simply not offered.
COMMANDS = {
    "run": "simpro_mj.commands.run",
    "compare": "simpro_mj.commands.compare",
    "validate-ik": "simpro_mj.commands.validate_ik",
    "check-plant": "simpro_mj.commands.check_plant",
    "workspace": "simpro_mj.commands.workspace",
    "identify": "simpro_mj.commands.identify",
    "calibrate": "simpro_mj.commands.calibrate",
    "analyze": "simpro_mj.commands.analyze",
    "batch": "simpro_mj.commands.batch",
    "bench": "simpro_mj.commands.bench",
    "render": "simpro_mj.commands.render",
    "view": "simpro_mj.commands.view",
    "manoeuvre": "simpro_mj.commands.manoeuvre",
    "telemetry": "simpro_mj.commands.telemetry",
    "response": "simpro_mj.commands.response",
    "omct": "simpro_mj.commands.omct",
    "live": "simpro_mj.commands.live",
    "send": "simpro_mj.commands.send",
    "list": "simpro_mj.commands.listing",
    "show": "simpro_mj.commands.show",
}


#: The shared options (:func:`build_parser`) a command takes unless it names fewer.
COMMON_OPTIONS = ("set", "json", "quiet")


class _Parser(argparse.ArgumentParser):
    """argparse that reports mistakes on one line with exit status 2."""

    def error(self, message: str):  # noqa: D401 - argparse API
        sys.stderr.write(f"error: {self.prog}: {message}\n")
        raise SystemExit(2)


def _available(only: str | None = None) -> dict:
    """The command modules, or only the one named (so that a command starts, or
    refuses a mistake, without importing every other command's dependencies)."""
    mods = {}
    for name, path in COMMANDS.items():
        if only is not None and name != only:
            continue
        try:
            mods[name] = import_module(path)
        except ModuleNotFoundError as exc:
            if exc.name != path:
                raise
    return mods


def command_help(path: str) -> str | None:
    """A command module's ``HELP`` read from its source without importing it (None: no
    such module)."""
    spec = importlib.util.find_spec(path)
    if spec is None or not spec.origin:
        return None
    tree = ast.parse(Path(spec.origin).read_text(encoding="utf-8"))
    for node in tree.body:
        if (
            isinstance(node, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id == "HELP" for t in node.targets)
            and isinstance(node.value, ast.Constant)
        ):
            return str(node.value.value)
    return ""


def build_parser(
    only: str | None = None, *, every: bool = False
) -> tuple[argparse.ArgumentParser, dict]:
    """The parser of the command named by ``only`` (a COMMANDS key), or of every
    command with ``every``.

    Otherwise the commands are listed by their ``HELP`` (read from the source,
    :func:`command_help`) and no module is imported: enough for ``simpro-sim --help``
    and for refusing an unknown command. Returns ``(parser, modules imported)``.
    """
    mods = _available(None) if every else _available(only) if only is not None else {}
    parser = _Parser(
        prog="simpro-sim",
        description="Co-simulation of the SIMPRO 3-DOF pneumatic motion platform (MuJoCo).",
    )
    parser.add_argument("--version", action="version", version=_version())
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name, path in COMMANDS.items():
        mod = mods.get(name)
        if mod is None:
            text = command_help(path) if only is None and not every else None
            if text is not None:
                sub.add_parser(name, help=text, description=text)
            continue
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP)
        common = getattr(mod, "COMMON_OPTIONS", COMMON_OPTIONS)
        if "set" in common:
            p.add_argument(
                "--set",
                dest="sets",
                action="append",
                default=[],
                metavar="KEY=VALUE",
                help="override a parameter by dotted path (repeatable)",
            )
        if "json" in common:
            p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
        mod.add_arguments(p)
        if "quiet" in common and "--quiet" not in p._option_string_actions:
            p.add_argument(
                "--quiet", action="store_true", help="no progress bar and no warnings on stderr"
            )
        # an option the command does not take reads as its neutral value
        p.set_defaults(_run=mod.run, sets=[], json=False, quiet=False)
    return parser, mods


def _version() -> str:
    from simpro_mj import __version__

    return f"simpro-sim {__version__}"


def _check_gl_backend() -> str | None:
    """The one-line message when MuJoCo cannot load the ``MUJOCO_GL`` backend, else None
    (with ``MUJOCO_GL`` unset nothing is imported: no GL library is loaded then)."""
    if not os.environ.get("MUJOCO_GL"):
        return None
    try:
        import mujoco  # noqa: F401
    except Exception as exc:  # noqa: BLE001 - only MUJOCO_GL can break this import
        # only when MUJOCO_GL is broken: every command starts without the render room
        from simpro_mj.report.render import GL_LIBRARIES

        gl = os.environ.get("MUJOCO_GL", "")
        lib = GL_LIBRARIES.get(gl.strip().lower(), "its OpenGL library")
        return (
            f"cannot load MuJoCo with MUJOCO_GL={gl!r} (needs {lib}): {type(exc).__name__}: "
            f"{_one_line(exc)}; allowed: MUJOCO_GL unset, or a backend whose library is installed"
        )
    return None


def main(argv=None) -> int:
    os.environ.setdefault("MPLBACKEND", "Agg")
    matplotlib_home()  # HOME a file or read-only: no warnings from matplotlib
    # One BLAS thread: the analyses' matrices are small (the preflight's lifted outer
    # loop has at most 65 states) and BLAS threads only contend for the cores. step_all's
    # preflight on a loaded 2-core machine (load average 9): 54.8 s with OpenBLAS's
    # default threads, 0.64 s with one. Read when numpy loads, which no module imported
    # so far does; a user's own setting wins.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    try:
        # Ctrl-C and SIGTERM raise KeyboardInterrupt, held while the command's modules
        # are imported so that no extension turns them into ImportError (core.interrupts)
        with interruptible(), standard_streams():
            return _main(argv)
    except KeyboardInterrupt:  # while the command's modules were imported
        notice("error: interrupted")
        return 130


def cli() -> int:
    """The ``simpro-sim`` console script: :func:`main` on the process's command line,
    then the objects left frozen (:func:`gc.freeze`) for the process's end.

    At exit Python clears every module and collects reference cycles over all
    the objects still alive (about 10^5 after a run: numba's types, the
    scenario's models, MuJoCo's bindings), several times: about 0.25 s of CPU
    after ``run step_pitch.yaml --no-plots`` has written its result, for memory
    the process's end returns anyway. Frozen objects are left out of those
    collections; the streams are still flushed, and ``atexit`` handlers and
    ``weakref.finalize`` callbacks still run.
    """
    code = main()
    gc.freeze()
    return code


def _main(argv) -> int:
    words = sys.argv[1:] if argv is None else list(argv)
    # the command's own module only (the first word, when it names one); --help
    # and mistakes in the command name see them all
    only = words[0] if words and words[0] in COMMANDS else None
    with held_signals():  # the imports first: a signal meanwhile is raised after them
        # help needs no MuJoCo: the backend is checked for the commands that run
        problem = None if {"-h", "--help"} & set(words) else _check_gl_backend()
        problem = problem or environment_problem()
        if problem:
            sys.stderr.write(f"error: {problem}\n")
            return 2
        if words == ["--version"]:  # without importing the commands
            print(_version())
            return 0
        parser, _ = build_parser(only)
    try:
        args = parser.parse_args(words)
    except SystemExit as exc:  # argparse: --help (0) or a misuse (2, one line already)
        return exc.code if isinstance(exc.code, int) else 2
    try:
        code = int(args._run(args) or 0)
        getattr(sys.stdout, "check", sys.stdout.flush)()  # a failed stdout, named
        return code
    except (UserInputError, KinematicsError, DesignError) as exc:
        # KinematicsError/DesignError reach here only from a check that did not
        # wrap them with a field path; their messages still name the limit
        notice(f"error: {_one_line(exc)}")
        return 2
    except PhysicsError as exc:
        notice(f"error: simulation diverged: {exc}")
        return 1
    except KeyboardInterrupt as exc:  # Interrupted: during a write, which it names
        notice("error: interrupted" + (f"; {exc}" if isinstance(exc, Interrupted) else ""))
        return 130
    except BrokenPipeError:
        # stdout closed by a reader such as `| head`: results are already on disk
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except StreamError as exc:  # the files are written; the printing failed
        notice(
            f"error: cannot write at {exc.filename}: {exc.strerror}; allowed: a writable "
            "standard output (the command's files are written)"
        )
        return 2
    except OSError as exc:
        # a folder or file the user named that cannot be written or read
        where = exc.filename if exc.filename is not None else "--out"
        sys.stderr.write(
            f"error: cannot access at {where}: {exc.strerror or _one_line(exc)}; "
            "allowed: a readable input and a writable output folder\n"
        )
        return 2
    except Exception as exc:
        if os.environ.get("SIMPRO_DEBUG"):
            raise
        sys.stderr.write(
            f"error: internal error in simpro-sim {args.command}: "
            f"{type(exc).__name__}: {_one_line(exc)} (a bug, please report it with the "
            "command line; SIMPRO_DEBUG=1 shows the traceback)\n"
        )
        return 3


if __name__ == "__main__":  # pragma: no cover
    sys.exit(cli())
