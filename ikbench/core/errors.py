"""Exception hierarchy. Every message names the bad value and what is allowed.

The CLI turns any :class:`IkbenchError` into one line on stderr and its ``exit_code``: 2 for
bad input and failed solves, 3 for hardware (bus) failures; Ctrl-C exits with 130.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence


class IkbenchError(Exception):
    """Base class of every error ikbench raises on bad input or a failed operation."""

    exit_code = 2


class InputError(IkbenchError):
    """Bad user input: a pose, a targets file, an option value."""


class OutputError(InputError):
    """A result file or folder that cannot be written (checked before long work starts)."""


class TargetsError(InputError):
    """A targets file that cannot be used."""


class SolverError(IkbenchError):
    """A method could not produce a trajectory."""


class HardwareError(IkbenchError):
    """A problem on the servo bus (missing motor, communication failure, ...)."""

    exit_code = 3


def refuse_unknown_keys(document: Iterable[str], allowed: Sequence[str], where: str,
                        error: type[IkbenchError] = InputError) -> None:
    """``error`` ``"<where>: unknown key(s) 'a', 'b'; allowed: ..."`` when the keys of a
    parsed file (or one of its tables) are not all ``allowed``."""
    unknown = [k for k in document if k not in allowed]
    if unknown:
        raise error(f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; allowed: "
                    f"{', '.join(allowed)}")
