"""Command-line interface: argument parsing only; the work lives in library modules.

Every module in :mod:`ikbench.cli.commands` declares one subcommand (``HELP``,
``DESCRIPTION``, ``arguments``, ``run``: see there). Only the invoked subcommand is built in
full (its options may list the methods, which imports their modules); the others appear with
their ``HELP`` line, so ``ikbench fk`` imports no method and bad input is refused before
anything heavy loads.
"""

from __future__ import annotations

import argparse
import atexit
import importlib
import os
import pkgutil
import re
import signal
import sys
from types import ModuleType

from ikbench.cli import commands
from ikbench.cli.values import QUOTED_CHARS, PathValue, harden, quoted
from ikbench.core import chatter
from ikbench.core.errors import IkbenchError, OutputError
from ikbench.runtime import progress

#: A word argparse takes for an option although it is a value: ``-24.9,81.5`` (a negative
#: number followed by more values is not what argparse recognises as a negative number).
_NEGATIVE_VALUE = re.compile(r"-\.?\d")
#: A quoted value in a message, longer than an error should quote.
_LONG_QUOTE = re.compile(f"'([^'\\n]{{{QUOTED_CHARS + 1},}})'")
#: ``field: ...`` at the start of an error from the library (a settings field, a parameter).
_FIELD = re.compile(r"([a-z][a-z0-9_]*)(?=:)")
#: Unit suffixes a field has and its option does not (``duration_s`` is ``--duration``).
_UNIT_SUFFIXES = ("_s", "_mm", "_deg", "_hz", "_rad", "_ms")


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (the usage is in ``--help``), with the
    prefix every error of every command has, ``ikbench: error:`` (issue 64)."""

    _words: list[str] = []  # the words this parser was given (for the hint in ``error``)

    def parse_known_args(self, args=None, namespace=None):
        self._words = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def error(self, message: str):
        self.exit(2, f"ikbench: error: {shorten(message)}{self._hint(message)} "
                  f"(see {self._help_of()} --help)\n")

    def _help_of(self) -> str:
        """The command whose ``--help`` explains the words given: argparse reports an
        unknown option of a subcommand on the top parser, so follow the subcommands named."""
        parser: argparse.ArgumentParser = self
        for word in self._words:
            sub = _subparser(parser, word)
            if sub is not None:
                parser = sub
        return parser.prog

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


def shorten(message: str) -> str:
    """``message`` on one line, with every quoted value longer than an error should quote cut
    (a 10,000-character value is named by its start and length)."""
    message = _LONG_QUOTE.sub(lambda m: quoted(m[1]), message)
    return " ".join(message.split())


def with_flags(message: str, parser: argparse.ArgumentParser | None) -> str:
    """An error of the library names a field (``duration_s: inf must be ...``); on the
    command line it names the argument of ``parser`` that sets it (``--duration: ...``; the
    option of a list, ``--methods``, for a field of one item, ``method``)."""
    found = _FIELD.match(message)
    if not found or parser is None:
        return message
    field = found[1]
    names = [field] + [field.removesuffix(s) for s in _UNIT_SUFFIXES if field.endswith(s)]
    names.append(f"{field}s")
    for action in parser._actions:
        flags = [f for f in action.option_strings if f.startswith("--")]
        name = max(flags, key=len) if flags else None if action.option_strings else \
            str(action.metavar or action.dest)
        if name and action.dest.removeprefix("opt_") in names and action.nargs != 0:
            return name + message[len(field):]
    return message


def command_modules() -> dict[str, str]:
    """subcommand name -> module name, for every module in :mod:`ikbench.cli.commands`."""
    return {info.name: f"{commands.__name__}.{info.name}"
            for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name)}


def _invoked(argv: list[str], names) -> str | None:
    """The subcommand named in ``argv`` (the first word that is one), else None."""
    return next((word for word in argv if word in names), None)


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The ``ikbench`` parser: the subcommand in ``argv`` in full, the others as stubs
    (``argv=None`` registers every subcommand in full, e.g. for documentation). Every option
    that takes a value validates it (:func:`ikbench.cli.values.harden`)."""
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
            add_command(sub, name, module)
        else:
            sub.add_parser(name, help=module.HELP, add_help=False)
    harden(parser)
    return parser


def add_command(subparsers: argparse._SubParsersAction, name: str, module: ModuleType
                ) -> argparse.ArgumentParser:
    """The full parser of subcommand ``name``, built from what its module declares (``HELP``,
    ``DESCRIPTION``, ``arguments``, ``run``, ``DEFAULTS``: :mod:`ikbench.cli.commands`)."""
    description = module.DESCRIPTION
    parser = subparsers.add_parser(
        name, help=module.HELP,
        description=description() if callable(description) else description)
    module.arguments(parser)
    parser.set_defaults(func=module.run, **getattr(module, "DEFAULTS", {}))
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ikbench`` console script; returns the exit code.

    Bad input: one line on stderr, exit code 2 (3 for the hardware); Ctrl-C at any moment: one
    line, exit code 130.
    """
    console = argv is None
    argv = sys.argv[1:] if argv is None else list(argv)
    if console:
        sys.unraisablehook = _ctrl_c_not_swallowed(sys.unraisablehook,
                                                   progress.RERAISE_AFTER_S)
        _take_sigint()
    try:
        try:
            parser = build_parser(argv)
        except IkbenchError as exc:  # e.g. a broken robot or method while building options
            print(f"ikbench: error: {shorten(str(exc))}", file=sys.stderr)
            return exc.exit_code
        return run_parsed(parser, argv)
    except KeyboardInterrupt:
        code = interrupted(ignore_more=console)
        if console:
            _exit_now(code)
        return code


#: Functions that compiled code calls and whose exception it drops, so that a Ctrl-C raised
#: in one is lost and the command runs on to the end: numba's boxing unpickles the class of
#: what an ``@njit`` function returns (ours-lm's solve in ``ik`` lost about every second
#: Ctrl-C there). A Ctrl-C that lands in one is raised a moment later instead.
DROPS_EXCEPTIONS = frozenset({("numba.core.serialize", "_numba_unpickle")})


def _on_sigint(signum, frame):  # type: ignore[no-untyped-def]
    """The console command's SIGINT handler: Python's (KeyboardInterrupt), but where the
    signal lands in a function of :data:`DROPS_EXCEPTIONS`, which would lose it, it is
    raised again shortly in the main thread (or at the next progress event)."""
    if frame is not None and (frame.f_globals.get("__name__"),
                              frame.f_code.co_name) in DROPS_EXCEPTIONS:
        progress.ctrl_c_swallowed(progress.RERAISE_AFTER_S)
        return
    raise KeyboardInterrupt


def _take_sigint() -> None:
    """Install :func:`_on_sigint` in place of Python's handler, and also when the process
    started with SIGINT ignored, as a script's background job (``ikbench ik ... &``) inherits
    it and Python then installs none: a Ctrl-C or ``kill -INT`` sent to the command stops it,
    with exit 130 and its folders kept, whichever library is solving, rather than being lost
    (the command ran on to the end and replaced the complete run). Only in the main thread;
    a handler of the caller's own (or SIG_DFL) stays."""
    try:
        if signal.getsignal(signal.SIGINT) in (signal.SIG_IGN, signal.default_int_handler):
            signal.signal(signal.SIGINT, _on_sigint)
    except ValueError:  # not the main thread (an embedding caller's): leave it
        pass


def _ctrl_c_not_swallowed(previous, reraise_after_s=None):  # type: ignore[no-untyped-def]
    """A ``sys.unraisablehook`` that hands a swallowed Ctrl-C (a KeyboardInterrupt raised in a
    library's callback, which Python can only print and drop: llvmlite's, JAX's at each garbage
    collection) to the next progress event, which raises it again, or after
    ``reraise_after_s`` [s] to the main thread
    (:func:`~ikbench.runtime.progress.ctrl_c_swallowed`); anything else goes to ``previous``."""

    def hook(unraisable):  # type: ignore[no-untyped-def]
        if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
            progress.ctrl_c_swallowed(reraise_after_s)
            return
        previous(unraisable)

    return hook


def _exit_now(code: int) -> None:
    """End the process with ``code`` after Ctrl-C: the exit handlers run and the streams are
    flushed, then the process exits at once. Python would otherwise end it by SIGINT (exit
    status -2) when the KeyboardInterrupt passed through an ``exec`` of a string on its way
    (numba compiles that way), although it was handled here."""
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


def run_parsed(parser: argparse.ArgumentParser, argv: list[str]) -> int:
    """Parse ``argv`` with ``parser`` (from :func:`build_parser`) and run the command."""
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    chatter.forget()
    try:
        code = args.func(args)
        for line in chatter.summary():  # what the libraries printed, once, at the end
            print(line, file=sys.stderr)
    except IkbenchError as exc:
        command = _subparser(parser, args.command)
        if command is not None and getattr(args, "action", None):  # experiment design, ...
            command = _subparser(command, args.action) or command
        message = with_flags(str(exc), command)
        if isinstance(exc, OutputError):
            message = _name_output(message, command, args)
        print(f"ikbench: error: {shorten(message)}", file=sys.stderr)
        return exc.exit_code
    except BrokenPipeError:  # e.g. `ikbench plan X | head`: the reader went away
        sys.stderr.close()
        return 0
    except OSError as exc:  # a file or folder the user named that cannot be used
        where = f" {exc.filename}" if exc.filename else ""
        print(f"ikbench: error:{where}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    except MemoryError:  # the up-front budgets (ikbench.core.budget) missed a size
        print(f"ikbench: error: out of memory in ikbench {args.command}", file=sys.stderr)
        return 1
    finally:
        progress.reset()  # begin() set it for this command; a library call after it gets lines
    return int(code or 0)


def interrupted(ignore_more: bool = False) -> int:
    """Say that Ctrl-C stopped the command and return its exit code, 130; ``ignore_more``: a
    second Ctrl-C while the process ends is ignored (no traceback from clean-up code)."""
    if ignore_more:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    clear = "\r\033[K" if sys.stderr.isatty() else ""  # over a progress bar, if one is drawn
    print(f"{clear}ikbench: interrupted (Ctrl-C)", file=sys.stderr, flush=True)
    return 130


def _name_output(message: str, parser: argparse.ArgumentParser | None,
                 args: argparse.Namespace) -> str:
    """``--output: cannot write ...``: a path that cannot be written, named by the option
    that gave it (the longest value of an output option the message holds)."""
    given = []
    for action in parser._actions if parser is not None else []:
        value = getattr(args, action.dest, None)
        if isinstance(action.type, PathValue) and action.type.must_exist is None \
                and action.option_strings and isinstance(value, str) and value in message:
            given.append((len(value), max(action.option_strings, key=len)))
    return f"{max(given)[1]}: {message}" if given else message


def _subparser(parser: argparse.ArgumentParser, name: str | None
               ) -> argparse.ArgumentParser | None:
    """The parser of subcommand ``name``."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices.get(name or "")
    return None


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
