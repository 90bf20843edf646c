"""``ikbench export``: a trajectory for ROS controllers and MoveIt, in URDF units."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from ikbench.cli.commands.plan import add_timing_arguments, check_timing_args, timing_from_args
from ikbench.cli.options import add_robot_arguments, begin, robot_from_args
from ikbench.cli.values import OUTPUT, PathValue, duration_s, rate_hz
from ikbench.core.defaults import DEFAULT_DURATION_S, DEFAULT_ROBOT
from ikbench.core.errors import InputError

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.runtime.record import RunFolder

HELP = ("write a trajectory (or every trajectory of a run folder) as a ROS JointTrajectory "
        "(JSON/YAML) or a CSV in URDF radians")
#: The default --format.
DEFAULT_FORMAT = "ros-json"
#: A run folder's export goes to RUN_DIR/<this>/ by default.
FOLDER_OUTPUT = "export"
#: File extension of each format, for a run folder's files (trajectory_<id><extension>).
EXTENSIONS = {"ros-json": ".json", "ros-yaml": ".yaml", "csv-rad": ".csv"}


DESCRIPTION = (
    "Convert a trajectory CSV (poses in the robot's units: motor degrees for NICO) to "
    "URDF joint values through the robot's motor map (radians; metres for prismatic "
    "joints) and write it as a trajectory_msgs/JointTrajectory (positions, velocities "
    "by central differences with zero at both ends, time_from_start as sec/nanosec, "
    "T/n apart) in JSON or YAML, or as a CSV step,time_s,<joints>. --timing min-jerk "
    "or topp samples the retimed motion at --rate with its velocities and "
    "accelerations. A run folder (ikbench run, letters, one method's folder of compare: "
    "RUN_DIR with run.json) exports every trajectory it holds, with the robot and the "
    f"duration its run.json names, to RUN_DIR/{FOLDER_OUTPUT}/trajectory_<id>.json|.yaml|.csv "
    "unless --robot, --duration or --output say otherwise. See docs/viewer.md and "
    "docs/timing.md.")


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.viewer.export import FORMATS

    parser.add_argument("trajectory", metavar="TRAJ.csv|RUN_DIR",
                        type=PathValue("a trajectory CSV or a run folder", must_exist="any"),
                        help="trajectory CSV as ikbench writes it (trajectory_<id>.csv), or a "
                        "run folder (with run.json): every trajectory of it")
    parser.add_argument("--format", default=DEFAULT_FORMAT, choices=list(FORMATS),
                        help="; ".join(f"{k}: {v}" for k, v in FORMATS.items())
                        + f" (default {DEFAULT_FORMAT})")
    parser.add_argument("--duration", type=duration_s(), default=None, metavar="T",
                        help=f"duration of the whole movement in seconds (default: a run "
                        f"folder's duration_s, else {DEFAULT_DURATION_S:g}, as ikbench plan "
                        "and execute); a note says when the CSV's time_s column ends "
                        "elsewhere")
    parser.add_argument("--output", default=None, metavar="FILE|DIR", type=OUTPUT,
                        help="file to write (replaced atomically; required for a CSV), or for "
                        f"a run folder the folder to write (default RUN_DIR/{FOLDER_OUTPUT}/, "
                        "replaced whole)")
    from ikbench.viewer.export import DEFAULT_RATE_HZ, MAX_RATE_HZ

    add_timing_arguments(parser)
    parser.add_argument("--rate", default=DEFAULT_RATE_HZ, metavar="HZ",
                        type=rate_hz(MAX_RATE_HZ, zero="one point per solved pose"),
                        help=f"min-jerk, topp: points per second along the retimed motion, up "
                        f"to {MAX_RATE_HZ:g} (default {DEFAULT_RATE_HZ:g}; 0: one point per "
                        "solved pose)")
    add_robot_arguments(parser)
    parser.set_defaults(robot=None)  # a run folder's own robot unless --robot names one


def run(args: argparse.Namespace) -> int:
    import sys

    from ikbench.core.io import check_writable

    check_timing_args(args)
    from ikbench.viewer.export import export_trajectory

    if Path(args.trajectory).is_dir():
        return run_folder(args)
    if args.output is None:
        raise InputError("--output: give the file to write (required for a trajectory CSV; "
                         f"a run folder writes RUN_DIR/{FOLDER_OUTPUT}/ by default)")
    if args.robot is None:
        args.robot = DEFAULT_ROBOT
    robot = robot_from_args(args)
    timing, limits = timing_from_args(args, robot)
    check_writable(args.output)
    begin(args)
    duration = DEFAULT_DURATION_S if args.duration is None else args.duration
    path, note = export_trajectory(args.trajectory, args.format, args.output, robot,
                                   duration, timing, limits, args.rate)
    if note:
        print(note, file=sys.stderr)
    print(f"{args.format} written to {path} ({robot.dof} joints: "
          f"{', '.join(robot.joint_names)}; URDF units)")
    return 0


def folder_trajectories(folder: RunFolder, trajectories: list[str] | None) -> list[str]:
    """The trajectory ids of ``folder`` whose CSV it holds, in its run.json's order;
    InputError naming the folders to give instead (a compare's methods) when none."""
    ids = [t for t in trajectories or [] if folder.trajectory_path(t).is_file()]
    if ids:
        return ids
    raise InputError(f"TRAJ.csv|RUN_DIR: {folder.path} holds no trajectory CSV that its "
                     f"run.json names{_inner_hint(folder.path)}")


def _inner_hint(path: Path) -> str:
    """``"; give one of its run folders: ..."`` for a folder of run folders, else ``""``."""
    inner = sorted(str(p) for p in path.iterdir() if p.is_dir() and (p / "run.json").is_file())
    return f"; give one of its run folders: {', '.join(inner)}" if inner else ""


def run_folder(args: argparse.Namespace) -> int:
    """``ikbench export RUN_DIR``: every trajectory of a run folder, its run.json's robot."""
    import sys

    from ikbench.core.io import check_folder_writable, staged_folder
    from ikbench.runtime.record import RunFolder
    from ikbench.viewer.export import export_trajectory

    folder = RunFolder(args.trajectory)
    if not folder.has_record:
        raise InputError(f"TRAJ.csv|RUN_DIR: {folder.path} holds no run.json; give a "
                         f"trajectory CSV or a run folder ikbench wrote{_inner_hint(folder.path)}")
    record = folder.read_record("TRAJ.csv|RUN_DIR")
    ids = folder_trajectories(folder, record.trajectories)
    robot: Robot = robot_from_args(args) if args.robot is not None else record.load_robot()
    timing, limits = timing_from_args(args, robot)
    output = Path(args.output) if args.output is not None else folder.path / FOLDER_OUTPUT
    check_folder_writable(output)
    duration = args.duration if args.duration is not None else (
        record.duration_s or DEFAULT_DURATION_S)
    begin(args)
    with staged_folder(output) as staged:
        for trajectory in ids:
            name = f"trajectory_{trajectory}{EXTENSIONS[args.format]}"
            _, note = export_trajectory(folder.trajectory_path(trajectory), args.format,
                                        staged / name, robot, duration, timing, limits,
                                        args.rate)
            if note:
                print(f"{trajectory}: {note}", file=sys.stderr)
    failed = [t for t in record.failed if t in ids]
    print(f"{args.format}: {len(ids)} trajectories of {folder.path} ({robot.name}, "
          f"{robot.dof} joints; URDF units) written to {output}/"
          + (f"; judged failed in the run: {', '.join(failed)}" if failed else ""))
    return 0
