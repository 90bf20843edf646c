"""Report sections that higher layers add (the paper's tables beside a run's measured ones).

The studies write generic reports; the paper layer (:mod:`ikbench.paper`) registers what it
adds for its own targets and methods, so no study names a method or the paper. This module
imports nothing heavy: registering costs nothing at start-up.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

#: kind -> providers; a provider takes the report's context as keywords and returns lines.
_SECTIONS: dict[str, list[Callable[..., list[str] | None]]] = {"run": [], "ablation": []}


def add_report_section(kind: str, provider: Callable[..., list[str] | None]) -> None:
    """Register ``provider(**context) -> list[str]`` (Markdown lines, possibly empty) for the
    reports of ``kind``: ``"run"`` (context: method, table, record, targets) or ``"ablation"``
    (context: table)."""
    if provider not in _SECTIONS[kind]:
        _SECTIONS[kind].append(provider)


def report_sections(kind: str, **context: Any) -> list[str]:
    """The lines every provider of ``kind`` adds for ``context``."""
    lines: list[str] = []
    for provider in _SECTIONS[kind]:
        lines += provider(**context) or []
    return lines
