"""Command-line interface: argument parsing only; the work lives in library modules."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from ikbench import commands
from ikbench.errors import IkbenchError


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (the usage is in ``--help``)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """Build the ``ikbench`` parser with every subcommand found in :mod:`ikbench.commands`."""
    parser = _Parser(
        prog="ikbench",
        description=(
            "Generate robot-arm trajectories of a required shape (NICO right arm) and compare "
            "kinematics methods on them. Poses are in motor degrees, reports in mm and degrees."
        ),
    )
    from ikbench import __version__

    parser.add_argument("--version", action="version", version=f"ikbench {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ikbench`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
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
