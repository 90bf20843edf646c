"""Old names of the documented API kept for one release, each with a DeprecationWarning.

:func:`renamed_fields` keeps a dataclass's renamed fields readable (and settable through its
constructor and ``dataclasses.replace``) under their old names; :func:`renamed_keywords` keeps a
function's renamed keyword arguments. Both name the old and new names as strings, so a
renaming script that reads code leaves them alone.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Mapping
from typing import Any, ParamSpec, TypeVar

P = ParamSpec("P")
R = TypeVar("R")
C = TypeVar("C", bound=type)

#: The release that drops the old names.
REMOVED_IN = "0.4.0"


def _warn(owner: str, old: str, new: str, stacklevel: int) -> None:
    warnings.warn(f"{owner}: {old} is deprecated (removed in {REMOVED_IN}); use {new}",
                  DeprecationWarning, stacklevel=stacklevel + 1)


def _translate(owner: str, renames: Mapping[str, str], kwargs: dict[str, Any],
               stacklevel: int) -> dict[str, Any]:
    """``kwargs`` with each old keyword given under its new name (the old one wins: it is
    what the caller wrote, ``dataclasses.replace`` adds the new one from the object)."""
    for old, new in renames.items():
        if old in kwargs:
            _warn(owner, old, new, stacklevel + 1)
            kwargs[new] = kwargs.pop(old)
    return kwargs


def renamed_keywords(renames: Mapping[str, str], owner: str = ""
                     ) -> Callable[[Callable[P, R]], Callable[P, R]]:
    """Decorator: the function also takes each old keyword of ``renames`` (old -> new), with a
    DeprecationWarning."""

    def wrap(function: Callable[P, R]) -> Callable[P, R]:
        name = owner or function.__qualname__

        @functools.wraps(function)
        def call(*args: P.args, **kwargs: P.kwargs) -> R:
            return function(*args, **_translate(name, renames, kwargs, 2))

        return call

    return wrap


def _alias(owner: str, old: str, new: str) -> property:
    def read(self: object) -> Any:
        _warn(owner, old, new, 2)
        return getattr(self, new)

    read.__doc__ = f"Deprecated (removed in {REMOVED_IN}): ``{new}``."
    return property(read)


def renamed_fields(renames: Mapping[str, str]) -> Callable[[C], C]:
    """Class decorator for a dataclass whose fields were renamed (old -> new): each old name
    reads the new field, and the constructor (so ``dataclasses.replace`` too) takes it as a
    keyword; both with a DeprecationWarning."""

    def wrap(cls: C) -> C:
        for old, new in renames.items():
            setattr(cls, old, _alias(cls.__name__, old, new))
        cls.__init__ = renamed_keywords(renames, cls.__name__)(cls.__init__)  # type: ignore
        return cls

    return wrap
