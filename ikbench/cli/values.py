"""Option values that validate themselves: one definition per kind of value, for every command.

Each kind is an argparse ``type``: it turns the command-line text into the value or refuses it
with one line naming what is allowed (argparse prefixes the option: ``argument --duration: inf
is not a finite number; give a duration [s] from 0.001 to 3600``). A value is refused while the
command line is parsed, before anything heavy is imported, so ``--duration`` means the same on
every command that has it.

:func:`harden` gives every option a command registers without one of these kinds a default
one (text of bounded length, a finite number, an integer within 64 bits), so a new option is
never a door for ``nan``, ``inf``, an empty string or a 10,000-character one. Sizes that
allocate (points of an export, solves of a comparison) are checked against the memory and time
they need by :mod:`ikbench.core.budget`, up front, with the estimate and the maximum in the
message.
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: Longest text an option takes (a list of ids, weights, a path), in characters.
MAX_TEXT_CHARS = 1000
#: Longest list an option takes (a sweep's 10,000 weights), in characters.
MAX_LIST_CHARS = 200_000
#: Longest path (Linux PATH_MAX) and path component (NAME_MAX), in bytes.
MAX_PATH_BYTES, MAX_NAME_BYTES = 4096, 255
#: How much of a refused value an error message quotes, in characters.
QUOTED_CHARS = 200
#: The largest magnitude a plain number option takes (a weight, a gain, a cost).
MAX_MAGNITUDE = 1e9


def quoted(text: str) -> str:
    """``repr(text)``, cut to :data:`QUOTED_CHARS` characters with its length when longer."""
    if len(text) <= QUOTED_CHARS:
        return repr(text)
    return f"{text[:QUOTED_CHARS]!r}... ({len(text):,} characters)"


def _shown(word: str) -> str:
    """A number as given (``inf``), or quoted when it is not a plain word."""
    return word if len(word) <= QUOTED_CHARS and word.isprintable() and " " not in word \
        else quoted(word)


def _refuse(message: str) -> argparse.ArgumentTypeError:
    return argparse.ArgumentTypeError(message)


@dataclass(frozen=True)
class Number:
    """A finite number in ``[low, high]`` (``low`` excluded when ``low_open``), or an integer.

    Attributes:
        what: what the number is, with its unit, for messages (``"a duration [s]"``).
        low, high: the range.
        low_open: ``low`` itself is not allowed (a duration > 0).
        integer: the value is an integer (``1e3`` is read as 1000).
        zero: when 0 is allowed outside the range, what it means (``"one point per pose"``).
        hint: why the range is what it is, or what to do instead (added to messages).
        shown: the range in words, where the numbers would not read well (``[0, 2^63)``).
        infinite: when ``inf`` is allowed, what it means (``"no budget"``).
    """

    what: str
    low: float
    high: float
    low_open: bool = False
    integer: bool = False
    zero: str | None = None
    hint: str | None = None
    shown: str | None = None
    infinite: str | None = None

    @property
    def __name__(self) -> str:  # argparse names a type by it in some messages
        return "integer" if self.integer else "number"

    def allowed(self) -> str:
        """The allowed values in words."""
        low = "more than " if self.low_open else "from "
        text = f"{self.what} {self.shown or low + _g(self.low) + ' to ' + _g(self.high)}"
        text = f"{text} (or 0: {self.zero})" if self.zero else text
        text = f"{text} (or inf: {self.infinite})" if self.infinite else text
        return f"{text} ({self.hint})" if self.hint else text

    def __call__(self, text: str) -> int | float:
        word = str(text).strip()
        if not word:
            raise _refuse(f"{quoted(str(text))} is empty; give {self.allowed()}")
        try:
            value = float(word) if len(word) <= 64 else math.nan
        except ValueError:
            raise _refuse(f"{_shown(word)} is not a number; give {self.allowed()}") from None
        if self.infinite and value == math.inf:
            return value
        if not math.isfinite(value):
            raise _refuse(f"{_shown(word)} is not a finite number; give {self.allowed()}")
        if self.integer:
            try:
                number: int | float = int(word)
            except ValueError:
                if not value.is_integer():
                    raise _refuse(f"{word} is not an integer; give {self.allowed()}") from None
                number = int(value)
        else:
            number = value
        if self.zero and number == 0:
            return number
        if number < self.low or (self.low_open and number == self.low) or number > self.high:
            raise _refuse(f"{word} is out of range; give {self.allowed()}")
        return number


def _g(value: float) -> str:
    if float(value).is_integer() and abs(value) < 1e16:
        return f"{int(value):,}" if abs(value) >= 10_000 else str(int(value))
    return f"{value:g}"


def duration_s(high: float = 3600.0, low: float = 1e-3) -> Number:
    """A movement's duration [s] (default 1 ms to an hour)."""
    return Number("a duration [s]", low, high)


def count(what: str, low: int = 1, high: int = 1_000_000, hint: str | None = None) -> Number:
    """An integer count of ``what`` (``"segments"``) in ``[low, high]``; ``hint``: see
    :class:`Number`."""
    return Number(f"a number of {what}", low, high, integer=True, hint=hint)


def rate_hz(high: float, zero: str | None = None) -> Number:
    """A rate [Hz] above 0 up to ``high``; ``zero``: what 0 means when it is allowed."""
    return Number("a rate [Hz]", 0.0, high, low_open=True, zero=zero)


def tolerance(unit: str, high: float, low_open: bool = True) -> Number:
    """A tolerance in ``unit`` above 0 (or from 0 when not ``low_open``) up to ``high``."""
    return Number(f"a tolerance [{unit}]", 0.0, high, low_open=low_open)


#: A seed of numpy's and torch's generators.
SEED = Number("a seed", 0, 2**63 - 1, integer=True, shown="in [0, 2^63)")
#: Torch threads.
THREADS = count("threads", 1, 1024)
#: Segments n of a trajectory (what the targets and shapes allow).
STEPS = count("segments", 2, 5000)
#: Any finite number of sane magnitude (the default for number options without a kind).
FINITE = Number("a number", -MAX_MAGNITUDE, MAX_MAGNITUDE)
#: An integer option of a method (an iteration cap, a count of seeds): within a million.
METHOD_INTEGER = Number("an integer", 0, 1_000_000, integer=True)
#: Any integer of 64 bits (the default for integer options without a kind).
INTEGER = Number("an integer", -2**63, 2**63 - 1, integer=True)


@dataclass(frozen=True)
class Text:
    """Non-empty text of at most ``max_chars`` characters on one line."""

    what: str = "a value"
    max_chars: int = MAX_TEXT_CHARS

    @property
    def __name__(self) -> str:
        return "text"

    def __call__(self, text: str) -> str:
        text = str(text)
        if not text.strip():
            raise _refuse(f"{quoted(text)} is empty; give {self.what}")
        if len(text) > self.max_chars:
            raise _refuse(f"{quoted(text)} is longer than {self.max_chars:,} characters; give "
                          f"{self.what}")
        if any(c in text for c in "\0\n\r"):
            raise _refuse(f"{quoted(text)} holds a line break or NUL; give {self.what}")
        return text


@dataclass(frozen=True)
class PathValue(Text):
    """A path: not empty, within the system's limits on lengths.

    Attributes:
        must_exist: ``"file"`` (an existing regular file, e.g. an input CSV), ``"dir"`` (an
            existing folder), ``"any"`` (an existing file or folder) or None (a path to
            write, checked for writing by the command before its work starts).
    """

    what: str = "a path"
    max_chars: int = MAX_PATH_BYTES
    must_exist: str | None = None

    def __call__(self, text: str) -> str:
        text = super().__call__(text)
        data = os.fsencode(text)
        if len(data) > MAX_PATH_BYTES or any(len(p) > MAX_NAME_BYTES for p in data.split(b"/")):
            raise _refuse(f"{quoted(text)} is longer than a path may be ({MAX_NAME_BYTES} "
                          f"bytes a name, {MAX_PATH_BYTES} in all)")
        if self.must_exist == "file":
            if os.path.isdir(text):
                raise _refuse(f"{quoted(text)} is a directory; give {self.what}")
            if not os.path.isfile(text):
                raise _refuse(f"{quoted(text)} not found; give {self.what}")
        elif self.must_exist == "any" and not (os.path.isfile(text) or os.path.isdir(text)):
            raise _refuse(f"{quoted(text)} not found; give {self.what}")
        elif self.must_exist == "dir" and not os.path.isdir(text):
            state = "is not a directory" if os.path.exists(text) else "not found"
            raise _refuse(f"{quoted(text)} {state}; give {self.what}")
        return text


#: A file to write or a folder to write into (checked for writing before the work starts).
OUTPUT = PathValue("a file or folder to write")
#: An existing file to read.
INPUT_FILE = PathValue("an existing file", must_exist="file")


def harden(parser: argparse.ArgumentParser) -> None:
    """Give every option of ``parser`` (and its subcommands) that takes a value without a kind
    of this module a default one: :class:`Text` for text, :data:`FINITE` for ``float``,
    :data:`INTEGER` for ``int``. Kinds set by the commands are kept."""
    defaults: dict[Any, Callable[[str], Any]] = {None: Text(), str: Text(), float: FINITE,
                                                 int: INTEGER}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in {id(p): p for p in action.choices.values()}.values():
                harden(sub)
        elif action.nargs != 0 and not isinstance(action, argparse._VersionAction) \
                and action.type in defaults:
            action.type = defaults[action.type]
