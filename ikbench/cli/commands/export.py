"""``ikbench export``: a trajectory for ROS controllers and MoveIt, in URDF units."""

from __future__ import annotations

import argparse

from ikbench.cli.commands.plan import (
    TRAJECTORY_CSV,
    add_timing_arguments,
    check_timing_args,
    timing_from_args,
)
from ikbench.cli.options import add_robot_arguments, begin, robot_from_args
from ikbench.cli.values import OUTPUT, duration_s, rate_hz
from ikbench.core.defaults import DEFAULT_DURATION_S

HELP = "write a trajectory as a ROS JointTrajectory (JSON/YAML) or a CSV in URDF radians"


DESCRIPTION = (
    "Convert a trajectory CSV (poses in the robot's units: motor degrees for NICO) to "
    "URDF joint values through the robot's motor map (radians; metres for prismatic "
    "joints) and write it as a trajectory_msgs/JointTrajectory (positions, velocities "
    "by central differences with zero at both ends, time_from_start as sec/nanosec, "
    "T/n apart) in JSON or YAML, or as a CSV step,time_s,<joints>. --timing min-jerk "
    "or topp samples the retimed motion at --rate with its velocities and "
    "accelerations. See docs/viewer.md and docs/timing.md.")


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.viewer.export import FORMATS

    parser.add_argument("trajectory", metavar="TRAJ.csv", type=TRAJECTORY_CSV,
                        help="trajectory CSV as ikbench writes it (trajectory_<id>.csv)")
    parser.add_argument("--format", required=True, choices=list(FORMATS),
                        help="; ".join(f"{k}: {v}" for k, v in FORMATS.items()))
    parser.add_argument("--duration", type=duration_s(), default=DEFAULT_DURATION_S,
                        metavar="T",
                        help=f"duration of the whole movement in seconds (default "
                        f"{DEFAULT_DURATION_S:g}, as ikbench plan and execute); a note says "
                        "when the CSV's time_s column ends elsewhere")
    parser.add_argument("--output", required=True, metavar="FILE", type=OUTPUT,
                        help="file to write (replaced atomically)")
    from ikbench.viewer.export import DEFAULT_RATE_HZ, MAX_RATE_HZ

    add_timing_arguments(parser)
    parser.add_argument("--rate", default=DEFAULT_RATE_HZ, metavar="HZ",
                        type=rate_hz(MAX_RATE_HZ, zero="one point per solved pose"),
                        help=f"min-jerk, topp: points per second along the retimed motion, up "
                        f"to {MAX_RATE_HZ:g} (default {DEFAULT_RATE_HZ:g}; 0: one point per "
                        "solved pose)")
    add_robot_arguments(parser)


def run(args: argparse.Namespace) -> int:
    import sys

    from ikbench.core.io import check_writable

    check_timing_args(args)
    from ikbench.viewer.export import export_trajectory

    robot = robot_from_args(args)
    timing, limits = timing_from_args(args, robot)
    check_writable(args.output)
    begin(args)
    path, note = export_trajectory(args.trajectory, args.format, args.output, robot,
                                   args.duration, timing, limits, args.rate)
    if note:
        print(note, file=sys.stderr)
    print(f"{args.format} written to {path} ({robot.dof} joints: "
          f"{', '.join(robot.joint_names)}; URDF units)")
    return 0
