"""``ikbench legibility``: ours-exact's legibility term swept over its weight."""

from __future__ import annotations

import argparse

from ikbench.cli.options import add_robot_arguments, begin, robot_from_args
from ikbench.cli.values import INPUT_FILE, OUTPUT
from ikbench.studies.folders import default_output

HELP = ("ours-exact with ikbench's legibility term (not the paper's method) for a sweep of "
        "weights on one target: CSV, trade-off figure")

DESCRIPTION = (
    "ikbench's extension, not the paper's method: solve one line target with ours-exact "
    "for each --exact-legibility-weight W of --weights (0 = the paper's objective), the term "
    "W * weighted mean over the poses of (1 - P(true goal))^2, P the pointing observer's "
    "probability of the target's touch point against the goal set (default every touch "
    "point of --targets), early poses weighted most (f = 1 - t/T). The fingertip stays on "
    "the line (ours-exact's constraints: line distance within 1e-6 mm); the term trades "
    "pointing. Writes OUTPUT/legibility_tradeoff.csv (weight, pointing and position "
    "legibility, predictability, line_distance_max_mm, pointing deviation [deg], time_s) "
    "and OUTPUT/legibility_tradeoff.png (legibility against pointing deviation and line "
    "distance, points labelled by W). See docs/legibility.md.")


def arguments(parser: argparse.ArgumentParser) -> None:
    add_robot_arguments(parser)
    parser.add_argument("--targets", default=None, metavar="FILE", type=INPUT_FILE,
                        help="targets file (default: the robot's; NICO: the paper's seven)")
    parser.add_argument("--target", default=None, metavar="ID",
                        help="the target's id (default: the first of the targets file)")
    parser.add_argument("--goals", default=None, metavar="FILE", type=INPUT_FILE,
                        help="a targets file of the same robot whose touch points are the "
                        "goal set (default: every touch point of --targets)")
    parser.add_argument("--weights", default=None, metavar="W1,W2,...",
                        help="the weights W, each >= 0 (default 0,10,30,100,300,1000,3000; "
                        "ours-exact's pointing weight c1 is 2000)")
    parser.add_argument("--output", default=default_output("legibility"), metavar="DIR",
                        type=OUTPUT,
                        help="output folder (default runs/legibility, which git ignores)")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ikbench.core.io import check_writable
    from ikbench.core.targets import load_targets
    from ikbench.studies import legibility_tradeoff as study

    weights = study.check_weights(study.WEIGHTS if args.weights is None
                                  else [w.strip() for w in str(args.weights).split(",")])
    robot = robot_from_args(args)
    targets = load_targets(args.targets, robot)
    goals = None if args.goals is None else load_targets(args.goals, robot)
    spec = study.LegibilitySpec(robot, targets, args.target, tuple(weights), goals)
    spec.validate()
    out = Path(args.output)
    check_writable(out / study.CSV)
    begin(args)
    result = study.run(spec)
    result.write(out)
    print(result.curve.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"written to {out / study.CSV} (and {study.PNG})")
    return 0
