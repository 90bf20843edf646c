"""``ikbench batch``: many random reachable touch poses solved at once by ours-lm."""

from __future__ import annotations

import argparse

from ikbench.cli.options import (
    add_robot_arguments,
    add_study_arguments,
    begin,
    check_executor_args,
    executor_from_args,
    robot_from_args,
)
from ikbench.cli.values import SEED, STEPS, count, tolerance
from ikbench.studies.folders import default_output

HELP = "sample random reachable touch poses, solve them in one batch (ours-lm)"
#: A tolerance on a distance (up to 10 m).
TOLERANCE_MM = tolerance("mm", 10_000.0)


DESCRIPTION = (
    "Draw N touch poses uniformly within the motor ranges (seeded), keep those in the "
    "front workspace (fingertip x <= -250 mm, z >= 0 mm, at least 100 mm below the "
    "start point, finger within 20 deg of the line direction), solve one line task per "
    "pose from the start pose with ours-lm in one batched call per weight setting, and "
    "report trajectories per second and the share within tolerance (mean line "
    "distance and end point error). Writes OUTPUT/batch.csv, batch_trajectories.csv, "
    "touch_poses.csv, batch.json and batch.md.")


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.studies.batch import (
        DEFAULT_WEIGHTS,
        END_TOLERANCE_MM,
        LINE_TOLERANCE_MM,
        MAX_COUNT,
    )

    parser.add_argument("--count", default=1000,
                        type=count("touch poses", 1, MAX_COUNT,
                                   "in one batch; ikbench dataset builds larger sets"),
                        help=f"number of touch poses N, at most {MAX_COUNT:,} (default 1000; "
                        "ikbench dataset builds larger sets)")
    parser.add_argument("--seed", type=SEED, default=0,
                        help="sampling seed, an integer in [0, 2^63) (default 0)")
    parser.add_argument("--steps", type=STEPS, default=50,
                        help="number of segments n per trajectory (default 50)")
    parser.add_argument("--weights", action="append", metavar="SETTING",
                        help="a weight setting: 'paper' or changes such as c0=100,c1=500; "
                        f"repeat for several (default: {' and '.join(DEFAULT_WEIGHTS)})")
    add_robot_arguments(parser)
    parser.add_argument("--targets", default=None,
                        help="targets JSON file whose start pose is used (default: the "
                        "paper's)")
    parser.add_argument("--line-tolerance-mm", type=TOLERANCE_MM, default=LINE_TOLERANCE_MM,
                        help=f"tolerance on the mean line distance (default {LINE_TOLERANCE_MM})")
    parser.add_argument("--end-tolerance-mm", type=TOLERANCE_MM, default=END_TOLERANCE_MM,
                        help=f"tolerance on the end point error (default {END_TOLERANCE_MM})")
    add_study_arguments(parser, default_output("batch"))


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace
    from pathlib import Path

    from ikbench.core.io import check_writable
    from ikbench.core.targets import load_targets
    from ikbench.studies import batch as study

    check_executor_args(args)
    robot = robot_from_args(args)
    spec = study.BatchSpec(args.count, args.seed, args.steps,
                           tuple(args.weights or study.DEFAULT_WEIGHTS), args.targets,
                           args.line_tolerance_mm, args.end_tolerance_mm,
                           progress=not args.quiet, robot=robot)
    spec.validate()
    load_targets(args.targets, robot)  # its start pose is used: checked up front
    check_writable(Path(args.output) / "batch.csv")  # before sampling and solving
    begin(args)
    spec = replace(spec, executor=executor_from_args(args))  # starts or joins Ray: only now
    report = study.run(spec)
    path = report.write(args.output)
    cols = ["setting", "trajectories", "solve_wall_s", "trajectories_per_s",
            "share_line_within_tol", "share_end_within_tol", "share_within_tol",
            "line_distance_mean_mm_median", "pointing_deviation_mean_deg_median"]
    print(report.summary[cols].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"written to {path} (and batch.md, batch_trajectories.csv, touch_poses.csv)")
    return 0
