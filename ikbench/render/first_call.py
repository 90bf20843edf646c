"""How a report shows the first-call times of :mod:`ikbench.studies.first_call` (a fresh
process: import, set-up, first solve)."""

from __future__ import annotations

from collections.abc import Callable

#: What the first-call column measures, for a report's header.
FIRST_CALL_MEANING = (
    "first call [s] (`first_call_s`): what a user waits for before the first answer, in a "
    "fresh Python process started after the timed runs (numba's cache as they left it): the "
    "import of ikbench and the method's library, the set-up (the robot, the method, its "
    "model, compiling or loading compiled code) and the first solve; one measurement in "
    "seconds, so it carries the machine's load at that moment")


def first_call_section(first_calls: dict[str, dict], what: str) -> list[str]:
    """Markdown: a "First call" section, one row per method (first call, import, set-up,
    first solve [s], or why it failed) for ``what`` (the task solved); none when not timed."""
    if not first_calls:
        return []
    lines = ["## First call", "", f"{FIRST_CALL_MEANING[0].upper()}{FIRST_CALL_MEANING[1:]}; "
             f"each method solved {what}.", "",
             *first_call_table(first_calls, lambda v: f"{v:.3g}")]
    return [*lines, ""]


def first_call_table(first_calls: dict[str, dict], fmt: Callable[[float], str]) -> list[str]:
    """The table's lines: one row per method (first call, import, set-up, first solve [s],
    each by ``fmt``), or why its first call failed."""
    lines = ["| method | first call [s] | import [s] | set-up [s] | first solve [s] |",
             "|---|---|---|---|---|"]
    for method, t in first_calls.items():
        if "error" in t:
            lines.append(f"| {method} | failed: {t['error']} | | | |")
        else:
            lines.append(" | ".join([f"| {method}", *(fmt(t[k]) for k in (
                "first_call_s", "import_s", "setup_s", "solve_s"))]) + " |")
    return lines
