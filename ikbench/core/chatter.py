"""What kinematics libraries print on their own, kept off the console.

Some libraries talk while they load a robot: TRAC-IK's KDL parser prints "The root link %s has
an inertia ..." (its ``%s`` unfilled) on the C-level stdout, above ikbench's table; Drake logs
a warning per joint for URDF tags it ignores. :func:`quiet` captures both (file descriptors 1
and 2, and the named Python loggers) around such a call and keeps the text per library;
:func:`summary` gives one line per library for the end of a command, and with
:func:`set_verbose` (the CLI's ``--verbose``) the text goes on to stderr as it comes.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import sys
import tempfile
from collections.abc import Iterator, Sequence

_state = {"verbose": False}
_heard: dict[str, list[str]] = {}


def set_verbose(verbose: bool) -> None:
    """Pass captured text on to stderr as well (True), or only keep it (False, the default)."""
    _state["verbose"] = bool(verbose)


def heard() -> dict[str, list[str]]:
    """library -> the lines it printed inside :func:`quiet` since :func:`forget`."""
    return {k: list(v) for k, v in _heard.items()}


def forget() -> None:
    """Drop what was heard (a command starts)."""
    _heard.clear()


def summary() -> list[str]:
    """One line per library that printed something: how much, and its first line."""
    lines = []
    for library, said in _heard.items():
        first = said[0] if len(said[0]) <= 240 else said[0][:240] + "..."
        more = f" (and {len(said) - 1} more)" if len(said) > 1 else ""
        shown = "shown above" if _state["verbose"] else "--verbose shows it"
        lines.append(f"note: {library} printed {len(said)} line(s) of its own ({shown}): "
                     f"{first}{more}")
    return lines


@contextlib.contextmanager
def quiet(library: str, loggers: Sequence[str] = ()) -> Iterator[None]:
    """Capture what the block prints on file descriptors 1 and 2 (C libraries included) and
    what ``loggers`` emit, and keep it under ``library`` (see the module docstring)."""
    records: list[str] = []
    handler = _ListHandler(records)
    saved = []
    for name in loggers:
        logger = logging.getLogger(name)
        saved.append((logger, logger.propagate))
        logger.addHandler(handler)
        logger.propagate = False
    with tempfile.TemporaryFile(mode="w+b") as sink:
        _flush()
        originals = [os.dup(1), os.dup(2)]
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            yield
        finally:
            _flush()
            os.dup2(originals[0], 1)
            os.dup2(originals[1], 2)
            for fd in originals:
                os.close(fd)
            for logger, propagate in saved:
                logger.removeHandler(handler)
                logger.propagate = propagate
            sink.seek(0)
            text = sink.read().decode("utf-8", "replace")
            _keep(library, [line for line in text.splitlines() if line.strip()] + records)


def _keep(library: str, lines: list[str]) -> None:
    if not lines:
        return
    _heard.setdefault(library, []).extend(lines)
    if _state["verbose"]:
        for line in lines:
            print(f"[{library}] {line}", file=sys.stderr)


def _flush() -> None:
    """Flush Python's and C's buffered output (C's stdout is block-buffered in a pipe)."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    with contextlib.suppress(Exception):
        ctypes.CDLL(None).fflush(None)


class _ListHandler(logging.Handler):
    def __init__(self, records: list[str]) -> None:
        super().__init__()
        self.records = records

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(f"{record.levelname.lower()}: {record.getMessage()}")
