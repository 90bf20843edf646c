"""Command-line interface: argument parsing only; the work lives in library modules.

Every module in :mod:`ikbench.cli.commands` defines ``HELP`` (one line) and
``register(subparsers)``. Only the invoked subcommand is registered in full (its options may
list the methods, which imports their modules); the others appear with their ``HELP`` line,
so ``ikbench fk`` imports no method and bad input is refused before anything heavy loads.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import re
import sys

from ikbench.cli import commands
from ikbench.core.errors import IkbenchError

#: Options that name a file or folder to write. An empty value would write into the working
#: directory (``run --output ""`` wrote ./ours-lm/ into the checkout), so it is refused.
OUTPUT_OPTIONS = ("output", "out", "record", "log")
#: A word argparse takes for an option although it is a value: ``-24.9,81.5`` (a negative
#: number followed by more values is not what argparse recognises as a negative number).
_NEGATIVE_VALUE = re.compile(r"-\.?\d")


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (the usage is in ``--help``)."""

    _words: list[str] = []  # the words this parser was given (for the hint in ``error``)

    def parse_known_args(self, args=None, namespace=None):
        self._words = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}{self._hint(message)} "
                  f"(see {self.prog} --help)\n")

    def _hint(self, message: str) -> str:
        """``; write --pose=-24.9,...`` when an option's value starts with a minus sign:
        argparse took the value for an option and says only "expected one argument"."""
        found = re.fullmatch(r"argument (\S+): expected one argument", message)
        if not found:
            return ""
        flags = found[1].split("/")
        for word, value in zip(self._words, self._words[1:]):
            if word in flags and _NEGATIVE_VALUE.match(value):
                return (f"; a value that starts with '-' must be attached with '=': "
                        f"write {word}={value}")
        return ""


def _empty_output(args) -> str | None:
    """The error for an empty file or folder option (:data:`OUTPUT_OPTIONS`), else None."""
    for dest in OUTPUT_OPTIONS:
        value = getattr(args, dest, None)
        if isinstance(value, str) and not value.strip():
            return (f"argument --{dest}: {value!r} is empty; name a file or folder (e.g. "
                    f"--{dest} runs/mine)")
    return None


def command_modules() -> dict[str, str]:
    """subcommand name -> module name, for every module in :mod:`ikbench.cli.commands`."""
    return {info.name: f"{commands.__name__}.{info.name}"
            for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name)}


def _invoked(argv: list[str], names) -> str | None:
    """The subcommand named in ``argv`` (the first word that is one), else None."""
    return next((word for word in argv if word in names), None)


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The ``ikbench`` parser: the subcommand in ``argv`` in full, the others as stubs
    (``argv=None`` registers every subcommand in full, e.g. for documentation)."""
    parser = _Parser(
        prog="ikbench",
        description=(
            "Generate robot-arm trajectories of a required shape and compare kinematics "
            "methods and libraries on them (default robot: the NICO right arm of Lucny et "
            "al.). Poses are in the robot's units (motor degrees for NICO), reports in mm and "
            "degrees."),
    )
    from ikbench import __version__

    parser.add_argument("--version", action="version", version=f"ikbench {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    modules = command_modules()
    invoked = None if argv is None else _invoked(argv, modules)
    for name, module_name in modules.items():
        module = importlib.import_module(module_name)
        if argv is None or name == invoked:
            module.register(sub)
        else:
            sub.add_parser(name, help=module.HELP, add_help=False)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ikbench`` console script; returns the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        parser = build_parser(argv)
        args = parser.parse_args(argv)
    except IkbenchError as exc:  # e.g. a broken robot or method while building options
        print(f"ikbench: error: {exc}", file=sys.stderr)
        return exc.exit_code
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    empty = _empty_output(args)
    if empty:
        prog = f"{parser.prog} {args.command}"
        print(f"{prog}: error: {empty} (see {prog} --help)", file=sys.stderr)
        return 2
    try:
        code = args.func(args)
    except IkbenchError as exc:
        print(f"ikbench: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("ikbench: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `ikbench plan X | head`: the reader went away
        sys.stderr.close()
        return 0
    except OSError as exc:  # a file or folder the user named that cannot be used
        where = f" {exc.filename}" if exc.filename else ""
        print(f"ikbench: error:{where}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    return int(code or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
