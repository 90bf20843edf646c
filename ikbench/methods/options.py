"""A method's options: the settings fields that are also CLI options, and their checks.

A method's options live in one place, its settings dataclass: each field declared with
:func:`option` carries its default, type, help and unit, and the CLI options are generated
from these fields (:func:`method_options`). Two methods may share an option name (``--weights``
for ``ours`` and ``ours-lm``); the CLI then shows one option whose help names both. The checks
(:func:`check_choice`, :func:`check_positive`, :func:`check_seed`) name the option's flag in
their one-line error (:func:`flag_of`).
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field
from typing import Any

from ikbench.core.errors import InputError

#: Metadata key of the option description in a settings field.
OPTION = "ikbench_option"


@dataclass(frozen=True)
class OptionSpec:
    """How a settings field appears on the command line.

    Attributes:
        help: one line (without the default; it is appended).
        unit: the value's unit (shown in the help), e.g. ``"m, rad"``.
        flag: the option name without dashes (default: the field name with ``-`` for ``_``).
        choices: allowed values (shown in the help and checked by :func:`check_choice`).
        type: the CLI value's type (default: the type of the field's default).
        show_default: how the default is shown in the help (default: the value).
    """

    help: str
    unit: str | None = None
    flag: str | None = None
    choices: tuple[Any, ...] | None = None
    type: Callable[[str], Any] | None = None
    show_default: str | None = None


def option(default: Any, *, help: str, unit: str | None = None, flag: str | None = None,
           choices: Sequence[Any] | None = None, type: Callable[[str], Any] | None = None,
           show_default: str | None = None) -> Any:
    """A settings field that is also a CLI option (see :class:`OptionSpec`).

    Mutable defaults (dicts, lists) are copied for every instance.
    """
    spec = OptionSpec(help, unit, flag, tuple(choices) if choices else None, type, show_default)
    metadata = {OPTION: spec}
    if isinstance(default, (dict, list, set)):
        return field(default_factory=lambda: copy.copy(default), metadata=metadata)
    return field(default=default, metadata=metadata)


@dataclass(frozen=True)
class MethodOption:
    """One CLI option of one method: the flag, the settings field it sets, how."""

    flag: str
    field: str
    spec: OptionSpec
    default: Any

    @property
    def dest(self) -> str:
        """The argparse ``dest`` of the flag."""
        return self.flag.replace("-", "_")

    def help_text(self) -> str:
        """The option's ``--help`` line: help, unit and default."""
        unit = f" [{self.spec.unit}]" if self.spec.unit else ""
        shown = self.spec.show_default if self.spec.show_default is not None else self.default
        return f"{self.spec.help}{unit} (default {shown})"

    def value_type(self) -> Callable[[str], Any]:
        """What turns the command-line text into the value (argparse ``type``)."""
        if self.spec.type is not None:
            return self.spec.type
        if isinstance(self.default, bool) or self.default is None:
            return str
        if isinstance(self.default, (int, float)):
            return type(self.default)
        return str


def method_options(settings_class: type) -> list[MethodOption]:
    """The CLI options declared by a settings dataclass, in field order."""
    out: list[MethodOption] = []
    for f in dataclasses.fields(settings_class):
        spec = f.metadata.get(OPTION)
        if spec is None:
            continue
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = None
        out.append(MethodOption(spec.flag or f.name.replace("_", "-"), f.name, spec, default))
    return out


def flag_of(settings: Any, field_name: str) -> str:
    """``--lm-max-iterations`` for the field ``max_iterations`` of ``settings``."""
    for opt in method_options(type(settings)):
        if opt.field == field_name:
            return f"--{opt.flag}"
    return field_name


def check_choice(settings: Any, field_name: str, allowed: Collection[Any]) -> None:
    """InputError naming the flag when ``settings.<field_name>`` is not in ``allowed``."""
    value = getattr(settings, field_name)
    if value not in allowed:
        raise InputError(f"{flag_of(settings, field_name)}: {value!r} is not one of "
                         f"{', '.join(map(str, allowed))}")


def check_fraction(settings: Any, field_name: str) -> None:
    """InputError naming the flag when the settings field ``field_name`` is not in [0, 1]."""
    value = getattr(settings, field_name)
    if not (math.isfinite(value) and 0 <= value <= 1):
        raise InputError(f"{flag_of(settings, field_name)}: {value!r} must be in [0, 1]")


def check_positive(settings: Any, *field_names: str, integer: bool = False) -> None:
    """InputError naming the flag when a field is not a positive (integer) number."""
    for name in field_names:
        value = getattr(settings, name)
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        ok = number and math.isfinite(value) and value > 0
        if integer:
            ok = ok and float(value).is_integer()
        if not ok:
            kind = "an integer >= 1" if integer else "a positive number"
            raise InputError(f"{flag_of(settings, name)}: {value!r} must be {kind}")


def check_seed(settings: Any, field_name: str = "seed") -> None:
    """InputError naming the flag when ``settings.<field_name>`` is not an integer in
    [0, 2^63) (what numpy's and torch's generators take)."""
    value = getattr(settings, field_name)
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 2**63:
        raise InputError(f"{flag_of(settings, field_name)}: {value!r} must be an integer in "
                         "[0, 2^63)")
