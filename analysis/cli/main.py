"""The ``merge-irl`` command line.

Every subcommand lives in its own module under ``analysis/cli/commands/`` and is a thin layer over
the Python API. A command module defines ``register(subparsers)``, which adds its parser and
sets ``func`` (called with the parsed arguments; returns the exit status). The modules are
loaded lazily: :func:`build_parser` lists the commands of
:data:`analysis.cli.commands.COMMANDS` with their help line, and imports a command's module
(which imports its API at its top) only when the command line chooses it, or for every command
with ``build_parser(load_all=True)`` (the whole parser tree, as the tests walk it). The shared
options are in :mod:`analysis.cli.options`.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading
import warnings
from typing import cast

from analysis.cli.commands import COMMANDS, module_name
from irl.errors import IRLError
from merge_irl.provenance import version_line
from scenarios.errors import ScenarioError
from sim.errors import SimError, out_of_memory

#: Errors that are the user's input at fault: printed as one line, exit status 2 (SimError
#: includes analysis' own, :class:`analysis.errors.AnalysisError`).
USER_ERRORS: tuple[type[BaseException], ...] = (IRLError, ScenarioError, SimError, FileNotFoundError)

#: What to do when a command runs out of memory (one line, as the other errors).
_MEMORY_ADVICE = "free memory or raise the limit (ulimit -v), or give smaller inputs"


def build_parser(*, load_all: bool = False) -> argparse.ArgumentParser:
    """The ``merge-irl`` parser; a command's own parser is built when the command is parsed, or at
    once for every command with ``load_all``."""
    parser = argparse.ArgumentParser(
        prog="merge-irl",
        description="Learn merge-driving reward weights with model-free IRL and test them in SUMO.",
    )
    parser.add_argument("--version", action=_VersionAction, help="print the package, SUMO and git versions and exit")
    sub = cast(LazyCommands, parser.add_subparsers(dest="command", metavar="COMMAND", action=LazyCommands))
    sub.required = True
    for name, line in COMMANDS.items():
        sub.add_lazy(name, line)
    if load_all:
        for name in COMMANDS:
            sub.load(name)
    return parser


class LazyCommands(argparse._SubParsersAction):
    """The subcommands, each a placeholder (its name and help line) until chosen: then its module
    is imported and its ``register`` builds the real parser in the placeholder's place."""

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self._lazy: set[str] = set()

    def add_lazy(self, name: str, help: str) -> None:
        """A placeholder parser for ``name``, listed in ``--help`` with ``help``."""
        self.add_parser(name, help=help, add_help=False)
        self._lazy.add(name)

    def add_parser(self, name, **kw):
        if name in self._lazy:  # the real parser replaces the placeholder; the help line stays listed once
            self._lazy.discard(name)
            del self._name_parser_map[name]
            kw.pop("help", None)
        return super().add_parser(name, **kw)

    def load(self, name: str) -> None:
        """Build ``name``'s real parser (nothing when it is built already or not a command)."""
        if name in self._lazy:
            importlib.import_module(module_name(name)).register(self)
            if name in self._lazy:
                raise RuntimeError(f"{module_name(name)}.register added no parser named {name!r}")

    def __call__(self, parser, namespace, values, option_string=None):
        self.load(values[0])
        super().__call__(parser, namespace, values, option_string)


class _VersionAction(argparse.Action):
    """``--version``: :func:`merge_irl.provenance.version_line`, computed only when asked for."""

    def __init__(self, option_strings, dest, **kw):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_line())
        parser.exit()


def _terminate_as_interrupt(signum, frame) -> None:
    """SIGTERM handler: stop like Ctrl-C (finished work stored, workers stopped, nothing half
    published)."""
    raise KeyboardInterrupt(f"signal {signal.Signals(signum).name}")


def os_error_line(e: OSError) -> str:
    """One line for an OS error: what failed and on which path (``[Errno 13] ...`` without
    the number)."""
    what = e.strerror or type(e).__name__
    paths = [str(p) for p in (e.filename, e.filename2) if p is not None]
    return f"{what}: {' -> '.join(paths)}" if paths else str(e) or what


def _warning_line(command: str):
    """A ``warnings.formatwarning`` that writes one line, as the errors are (not the source file
    and line of the code that warned, which reads like a traceback to a user)."""
    def fmt(message, category, filename, lineno, line=None) -> str:
        return f"merge-irl {command}: warning: {message}\n"
    return fmt


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    warnings.formatwarning = _warning_line(args.command)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminate_as_interrupt)
    try:
        return int(args.func(args) or 0)
    except USER_ERRORS as e:
        print(f"merge-irl {args.command}: error: {e}", file=sys.stderr)
        return 2
    except MemoryError as e:  # not raised as InputTooLargeError naming its input: name the command
        print(f"merge-irl {args.command}: error: {out_of_memory(e, 'this run', _MEMORY_ADVICE)}", file=sys.stderr)
        return 2
    except OSError as e:  # permission, full disk, a path that is a file, a locked output folder
        print(f"merge-irl {args.command}: error: {os_error_line(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"merge-irl {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
