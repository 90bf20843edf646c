"""``ikbench fk``: where is the fingertip for a pose?"""

from __future__ import annotations

import json

PAPER_START_POSE = "-24.92,81.45,46.55,94.37,-59.03,28.0,45.67"


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "fk",
        help="forward kinematics: fingertip point [mm] and pointing direction of a pose",
        description=(
            "Print the fingertip point [mm] (torso frame: x behind the robot, y to its right, "
            "z up) and the unit pointing direction for a pose given in motor degrees."
        ),
    )
    parser.add_argument(
        "--pose",
        default=PAPER_START_POSE,
        help="7 comma-separated motor angles in degrees, order r_shoulder_z, r_shoulder_y, "
        "r_arm_x, r_elbow_y, r_wrist_z, r_wrist_x, r_indexfinger_x (default: the paper's "
        f"start pose {PAPER_START_POSE}); write --pose=-24,... for a leading minus",
    )
    parser.add_argument("--backend", choices=["torch", "pinocchio"], default="torch",
                        help="kinematics library: torch (pytorch-kinematics) or pinocchio "
                        "(default: torch)")
    parser.add_argument("--json", action="store_true",
                        help="print exactly one JSON object instead of text")
    parser.set_defaults(func=run)


def run(args) -> int:
    from ikbench.robot import load_robot
    from ikbench.targets import parse_pose

    robot = load_robot()
    pose = parse_pose(args.pose, robot, "--pose")
    result = robot.fk(pose, backend=args.backend)
    point = [float(v) for v in result.point_mm[0]]
    direction = [float(v) for v in result.direction[0]]
    if args.json:
        print(json.dumps({"backend": args.backend, "pose_deg": [float(v) for v in pose],
                          "point_mm": point, "direction": direction}))
    else:
        print(f"backend:         {args.backend}")
        print("pose [motor deg]: " + ", ".join(f"{v:g}" for v in pose))
        print("point [mm]:       " + ", ".join(f"{v:.3f}" for v in point))
        print("direction:        " + ", ".join(f"{v:.4f}" for v in direction))
    return 0
