"""Report sections that higher layers add (the paper's tables beside a run's measured ones).

The studies write generic reports; a higher layer provides what it adds for its own targets
and methods, so no study, and nothing here, names a method or the paper. Providers are named
as ``"module:function"`` by whoever puts the package together (:func:`name_report_section`;
the paper's in ``ikbench/__init__.py``, the top of the house, so render never imports upward)
and imported the first time a report of their kind is written, so importing ikbench costs
nothing for them; :func:`add_report_section` adds one at run time (a notebook, a plugin).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

#: A provider takes the report's context as keywords and returns Markdown lines (or None).
Provider = Callable[..., list[str] | None]
#: kind -> the built-in providers, ``"module:function"`` (:func:`name_report_section`).
PROVIDERS: dict[str, tuple[str, ...]] = {"run": (), "ablation": ()}
#: kind -> providers added at run time.
_ADDED: dict[str, list[Provider]] = {"run": [], "ablation": []}


def name_report_section(kind: str, target: str) -> None:
    """Name a built-in provider of the reports of ``kind`` as ``"module:function"``; it is
    imported the first time such a report is written (:func:`providers`)."""
    if target not in PROVIDERS[kind]:
        PROVIDERS[kind] = (*PROVIDERS[kind], target)


def add_report_section(kind: str, provider: Provider) -> None:
    """Register ``provider(**context) -> list[str]`` (Markdown lines, possibly empty) for the
    reports of ``kind``: ``"run"`` (context: method, table, record, targets) or ``"ablation"``
    (context: table)."""
    if provider not in _ADDED[kind]:
        _ADDED[kind].append(provider)


def providers(kind: str) -> list[Provider]:
    """The providers of ``kind``: the built-in ones (imported now), then those added."""
    built_in = []
    for target in PROVIDERS[kind]:
        module, _, name = target.partition(":")
        built_in.append(getattr(importlib.import_module(module), name))
    return [*built_in, *(p for p in _ADDED[kind] if p not in built_in)]


def report_sections(kind: str, **context: Any) -> list[str]:
    """The lines every provider of ``kind`` adds for ``context``."""
    lines: list[str] = []
    for provider in providers(kind):
        lines += provider(**context) or []
    return lines
