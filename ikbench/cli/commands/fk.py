"""``ikbench fk``: where is the end point for a pose?"""

from __future__ import annotations

import argparse
import json

from ikbench.cli.options import add_robot_arguments, begin, robot_from_args

HELP = "forward kinematics: end point [mm] and pointing direction of a pose"


DESCRIPTION = (
    "Print the end point [mm] in the robot's base frame (NICO: the torso frame, x "
    "behind the robot, y to its right, z up) and the unit pointing direction for a "
    "pose in the robot's units (NICO: motor degrees; robots without a motor map: "
    "joint degrees, mm for prismatic joints).")


def arguments(parser: argparse.ArgumentParser) -> None:
    add_robot_arguments(parser)
    parser.add_argument(
        "--pose", default=None,
        help="comma-separated joint values in the robot's order and units (default: the start "
        "pose of the robot's targets; NICO: the paper's -24.92,81.45,46.55,94.37,-59.03,28.0,"
        "45.67); write --pose=-24,... for a leading minus")
    parser.add_argument("--backend", choices=["torch", "pinocchio"], default="pinocchio",
                        help="kinematics library: pinocchio (default; loads in 1 s) or torch "
                        "(pytorch-kinematics, float64; 4 s)")
    parser.add_argument("--json", action="store_true",
                        help="print exactly one JSON object instead of text")


def run(args: argparse.Namespace) -> int:
    from ikbench.core.targets import load_targets, parse_pose

    robot = robot_from_args(args)
    if args.pose is None:
        pose = load_targets(None, robot).start_pose
    else:
        pose = parse_pose(args.pose, robot, "--pose")
    begin(args)
    result = robot.fk(pose, backend=args.backend)
    point = [float(v) for v in result.point_mm[0]]
    direction = [float(v) for v in result.direction[0]]
    if args.json:
        print(json.dumps({"robot": robot.name, "backend": args.backend,
                          "pose_deg": [float(v) for v in pose], "pose_unit": robot.pose_unit,
                          "point_mm": point, "direction": direction}))
    else:
        print(f"robot:           {robot.name} ({robot.dof} joints, end frame "
              f"{robot.end_frame})")
        print(f"backend:         {args.backend}")
        print(f"pose [{robot.pose_unit}]: " + ", ".join(f"{v:g}" for v in pose))
        print("point [mm]:       " + ", ".join(f"{v:.3f}" for v in point))
        print("direction:        " + ", ".join(f"{v:.4f}" for v in direction))
    return 0
