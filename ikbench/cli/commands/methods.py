"""``ikbench methods``: every registered method, available or not (and why)."""

from __future__ import annotations

import argparse
from typing import Any

from ikbench.cli.commands import Subparsers

HELP = "list the methods: available ones with their library, missing ones with the reason"


def register(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "methods", help=HELP,
        description=(
            "List every registered method: built-in ones, those of baselines/ (one per "
            "kinematics library, installed with pip install 'ikbench[libs]') and those other "
            "packages add through the entry-point group ikbench.methods. A method whose "
            "library is missing is listed as unavailable with the reason; every other "
            "command still works. [goal frames]: the method follows 6-D pose paths "
            "(run --problem, ikbench cartesian)."),
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import json

    from ikbench.core.provenance import library_versions
    from ikbench.methods.registry import method_status

    rows: list[dict[str, Any]] = []
    for name, status in method_status().items():
        cls = status.cls
        library = cls.library if cls else ""
        version = library_versions([library]).get(library) if library else None
        rows.append({"method": name, "available": status.available,
                     "library": library, "version": version, "source": status.source,
                     "description": cls.description if cls else "",
                     "reason": status.reason,
                     "goal_frames": bool(cls and cls.supports_frames),
                     "options": [f"--{o.flag}" for o in cls.options()] if cls else []})
    if args.json:
        print(json.dumps({"methods": rows}))
        return 0
    width = max(len(r["method"]) for r in rows)
    for r in rows:
        if r["available"]:
            lib = f"{r['library']} {r['version'] or ''}".strip()
            frames = " [goal frames]" if r["goal_frames"] else ""
            print(f"{r['method']:<{width}}  available    [{lib}]{frames} {r['description']}")
        else:
            print(f"{r['method']:<{width}}  UNAVAILABLE  {r['reason']}")
    return 0
