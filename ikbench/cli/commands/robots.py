"""``ikbench robots``: the shipped robots (dof, end frame, source)."""

from __future__ import annotations

import argparse

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
                        "--robot takes (PACKAGE:NAME)")


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
        chain = (f"{r['base_link']} -> {r['end_frame']}" if r["end_frame"]
                 else "needs --end-frame LINK")
        print(f"{r['name']}: {chain}; {r['description'] if r['end_frame'] else r['urdf']}")
    return 0
