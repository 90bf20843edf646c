"""``ikbench methods``: every registered method, available or not (and why)."""

from __future__ import annotations

import argparse
from typing import Any

HELP = "list the methods: available ones with their library, missing ones with the reason"


DESCRIPTION = (
    "List every registered method: built-in ones, those of baselines/ (one per "
    "kinematics library, installed with pip install 'ikbench[libs]') and those other "
    "packages add through the entry-point group ikbench.methods. A method whose "
    "library is missing is listed as unavailable with the reason; every other "
    "command still works. [goal frames]: the method follows 6-D pose paths "
    "(run --problem, ikbench cartesian).")


def arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("method", nargs="?", default=None, metavar="NAME",
                        help="one method: its description, library and every option with its "
                        "help and default (the options `ikbench run --help` leaves out)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def describe(row: dict[str, Any], cls: Any) -> int:
    """``ikbench methods NAME``: one method in full, each option on its own lines."""
    import textwrap

    state = "available" if row["available"] else f"UNAVAILABLE: {row['reason']}"
    lib = f"{row['library']} {row['version'] or ''}".strip()
    print(f"{row['method']} ({state}{'; ' + lib if lib and row['available'] else ''})")
    print(textwrap.fill(row["description"], 92, initial_indent="  ", subsequent_indent="  "))
    for opt in cls.options() if cls else []:
        choices = f" {{{','.join(map(str, opt.spec.choices))}}}" if opt.spec.choices else ""
        print(f"  --{opt.flag}{choices}")
        print(textwrap.fill(opt.help_text(), 88, initial_indent="      ",
                            subsequent_indent="      "))
    return 0


def run(args: argparse.Namespace) -> int:
    import json

    from ikbench.core.provenance import library_versions
    from ikbench.methods.registry import method_status

    statuses = method_status()
    if args.method is not None:
        if args.method not in statuses:
            from ikbench.methods.registry import get_method

            get_method(args.method)  # the one-line error naming the methods there are
        statuses = {args.method: statuses[args.method]}
    rows: list[dict[str, Any]] = []
    for name, status in statuses.items():
        cls = status.cls
        library = cls.library if cls else ""
        version = library_versions([library]).get(library) if library else None
        rows.append({"method": name, "available": status.available,
                     "library": library, "version": version, "source": status.source,
                     "description": cls.description if cls else "",
                     "reason": status.reason,
                     "goal_frames": bool(cls and cls.capabilities.frames),
                     "options": [f"--{o.flag}" for o in cls.options()] if cls else []})
    if args.json:
        print(json.dumps({"methods": rows}))
        return 0
    if args.method is not None:
        return describe(rows[0], statuses[args.method].cls)
    width = max(len(r["method"]) for r in rows)
    for r in rows:
        if r["available"]:
            lib = f"{r['library']} {r['version'] or ''}".strip()
            frames = " [goal frames]" if r["goal_frames"] else ""
            print(f"{r['method']:<{width}}  available    [{lib}]{frames} {r['description']}")
        else:
            print(f"{r['method']:<{width}}  UNAVAILABLE  {r['reason']}")
    return 0
