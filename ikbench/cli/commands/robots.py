"""``ikbench robots``: the shipped robots (dof, end frame, source)."""

from __future__ import annotations

import argparse

#: End frame candidates shown per robot (``--json`` gives them all).
SHOWN_CANDIDATES = 8
HELP = "list the shipped robots with their joints, end frame, units and source"


DESCRIPTION = (
    "List the robots that ship with ikbench (a URDF plus a small config each, in "
    "urdf/). Any other robot is --robot CONFIG.toml or --robot FILE.urdf --end-frame "
    "LINK on every command that uses a robot.")


def arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--all", action="store_true",
                        help="also the robots of installed description packages "
                        "(example-robot-data: pip install 'ikbench[robots]'), by the name "
                        "--robot takes (PACKAGE:NAME); for those that need --end-frame, the "
                        "candidates: leaf links first, then links with a tool-like name")


def run(args: argparse.Namespace) -> int:
    import json

    from ikbench.core.robot import load_robot, shipped_robots

    robots = [load_robot(name).describe() for name in shipped_robots()]
    packaged = []
    if args.all:
        from ikbench.core.robot_packages import PACKAGES, listing

        packaged = listing()
    if args.json:
        print(json.dumps({"robots": robots, **({"packages": packaged} if args.all else {})}))
        return 0
    for r in robots:
        print(f"{r['name']}: {r['dof']} joints ({', '.join(r['joints'])}), {r['base_link']} "
              f"-> {r['end_frame']}, poses in {r['pose_unit']}")
        print(f"    {r['description']}; source: {r['source']}")
    if args.all and not packaged:
        print(f"no description package installed ({', '.join(PACKAGES)}: "
              "pip install 'ikbench[robots]')")
    for r in packaged:
        if r["end_frame"]:
            print(f"{r['name']}: {r['base_link']} -> {r['end_frame']}; {r['description']}")
        elif "refused" in r:
            print(f"{r['name']}: cannot be used: {r['refused']}")
        else:
            print(f"{r['name']}: needs --end-frame LINK, candidates: "
                  f"{_first(r['end_frame_candidates'])}; {r['urdf']}")
    return 0


def _first(names: list[str], count: int = SHOWN_CANDIDATES) -> str:
    """The first ``count`` of ``names``, and how many more there are."""
    more = f" (+{len(names) - count} more: --json lists them)" if len(names) > count else ""
    return (", ".join(names[:count]) or "none") + more
