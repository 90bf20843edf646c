"""``ikbench robot init URDF``: a robot config and targets file from a URDF, no hand-written
file."""

from __future__ import annotations

import argparse

from ikbench.cli.values import OUTPUT, Text

HELP = "robot init URDF|PACKAGE:NAME: write a robot config and a targets file for a new robot"
DESCRIPTION = (
    "robot init: from a URDF (or a robot of an installed description package, "
    "example-robot-data:NAME) write OUTPUT/NAME.toml (the chain, the pointing axis, the letter "
    "plane) and OUTPUT/NAME.targets.json (a start pose, the middle of the limits unless "
    "--start-pose, and seven touch poses drawn near it whose lines are 80-400 mm long), so "
    "that letters, run --shape, run, compare and view take --robot OUTPUT/NAME.toml with no "
    "other file. Without --end-frame it chooses among the URDF's candidates (leaf links, "
    "then tool-like names) the one with the fewest moving joints, at least 3, and says which; "
    "docs/robots.md.")
DEFAULT_OUTPUT = "."
#: Other end frame candidates named at most.
SHOWN = 8


def arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=("init",), help="init: write the config and targets")
    parser.add_argument("urdf", metavar="URDF|PACKAGE:NAME",
                        type=Text("a URDF path or a package robot"),
                        help="the robot's URDF, or PACKAGE:NAME (ikbench robots --all)")
    parser.add_argument("--end-frame", default=None, metavar="LINK",
                        help="the end link (default: chosen among the candidates)")
    parser.add_argument("--base-link", default=None, metavar="LINK",
                        help="the chain's first link (default: the URDF's root, or the common "
                        "arm's base): a humanoid's chest or shoulder keeps the trunk's joints "
                        "out of the chain; it must be an ancestor of the end frame")
    parser.add_argument("--pointing-axis", default="auto",
                        choices=("auto", "x", "y", "z", "-x", "-y", "-z"),
                        help="the end frame's axis that points; auto (default): the axis the "
                        "last link's offset to the end frame runs along, else z")
    parser.add_argument("--name", default=None, type=Text("a robot name"),
                        help="the robot's name and file stem (default: the URDF's stem)")
    parser.add_argument("--start-pose", default=None, metavar="P1,...,Pn",
                        help="the start pose [joint deg, mm for prismatic joints] (default: "
                        "the middle of the limits)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the touch poses")
    parser.add_argument("--check-targets", action="store_true",
                        help="solve each touch pose's line with ours-exact under the task "
                        "contract and replace the ones it does not solve by further draws "
                        "(14 solves at most; 1-15 s where every target is solved, up to "
                        "about 90 s where none is; the targets file's description says "
                        "what it found)")
    parser.add_argument("--output", default=DEFAULT_OUTPUT, type=OUTPUT,
                        help="folder the two files go to (default: this one)")


def run(args: argparse.Namespace) -> int:
    import json
    import sys
    from pathlib import Path

    import numpy as np

    from ikbench.core.errors import InputError
    from ikbench.core.io import atomic_write_text, check_folder_writable
    from ikbench.core.robot_init import init_robot, reach_of, targets_description, toml_text
    from ikbench.core.targets import ID_PATTERN

    if args.name is not None and not (ID_PATTERN.fullmatch(args.name)
                                      and len(args.name) <= 64):
        raise InputError(f"--name: {args.name!r} must be a file stem: letters (any script's), "
                         "digits, _ . - (not . or - first; 64 at most)")
    check_folder_writable(args.output)  # a file there: refused now, naming --output
    if not 0 <= args.seed < 2**63:
        raise InputError(f"--seed: {args.seed!r} must be an integer in [0, 2^63)")
    start = None
    if args.start_pose is not None:
        try:
            start = np.array([float(x) for x in args.start_pose.split(",")])
        except ValueError:
            raise InputError(f"--start-pose: {args.start_pose!r} is not comma-separated "
                             "numbers") from None
    made = init_robot(args.urdf, args.end_frame, args.base_link, args.pointing_axis, args.name,
                      start, args.seed)
    check = None
    if args.check_targets:
        from ikbench.studies.target_check import check_targets

        print(f"checking {len(made['targets']['targets'])} touch poses under the task "
              "contract", file=sys.stderr)
        check = check_targets(made)
        # the check rewrites the description; say again how the start pose was chosen
        made["targets"]["description"] = targets_description(
            made["name"], len(check.touches), made["seed"], reach_of(made["start"],
                                                                     check.touches),
            check.sentence(), start=made["start_from"])
    folder = Path(args.output)
    folder.mkdir(parents=True, exist_ok=True)
    config = folder / f"{made['name']}.toml"
    targets = folder / made["config"]["targets"]["file"]
    atomic_write_text(targets, json.dumps(made["targets"], indent=2) + "\n")
    atomic_write_text(config, toml_text(made["config"]))
    if made["candidates"]:
        others = [c for c in made["candidates"] if c != made["end_frame"]]
        shown = ", ".join(others[:SHOWN]) + (f", ... ({len(others) - SHOWN} more)"
                                              if len(others) > SHOWN else "")
        print(f"end frame {made['end_frame']} (chosen; other candidates: "
              f"{shown or 'none'}; --end-frame to change it)", file=sys.stderr)
    print(f"pointing axis {made['axis']} of {made['end_frame']} (--pointing-axis to change it)",
          file=sys.stderr)
    print(f"start pose {made['start_from']} (--start-pose to change it)", file=sys.stderr)
    if check is not None:
        print(f"targets: {check.sentence()} in {check.seconds:.1f} s", file=sys.stderr)
    print(f"wrote {config} and {targets}; next: ikbench letters P --robot {config}, "
          f"ikbench compare --robot {config}")
    return 0
