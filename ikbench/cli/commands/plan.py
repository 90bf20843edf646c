"""``ikbench plan``: per-segment speeds of a trajectory, checked against the motors' limits."""

from __future__ import annotations

HELP = "segment table of a trajectory: joint speeds [motor deg/s] and limit flags"

DEFAULT_DURATION_S = 2.0


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "plan", help=HELP,
        description=(
            "Split a trajectory CSV into segments (segment k runs from pose k to pose k+1 in "
            "T/n seconds), compute each joint's speed |delta|/(T/n) in motor deg/s and the "
            "Dynamixel register values the executor would send (goal position, moving speed), "
            "and flag segments that exceed a motor's speed limit or leave its angle limits. "
            "Prints the table and writes it as CSV."
        ),
    )
    add_plan_arguments(parser)
    parser.add_argument("--out", metavar="CSV",
                        help="segment table CSV to write (default: TRAJ with suffix .plan.csv)")
    parser.set_defaults(func=run)


def add_plan_arguments(parser) -> None:
    """The trajectory, --duration and --motors options shared with ``ikbench execute``."""
    parser.add_argument("trajectory", metavar="TRAJ.csv",
                        help="trajectory CSV (columns step, time_s, joint angles in motor deg, "
                        "...), as written by ikbench")
    parser.add_argument("--duration", type=float, default=DEFAULT_DURATION_S, metavar="T",
                        help=f"duration of the whole movement in seconds (default: "
                        f"{DEFAULT_DURATION_S:g}, the paper's)")
    parser.add_argument("--motors", metavar="FILE",
                        help="motor config JSON: Dynamixel id, model, offset, orientation and "
                        "angle limits per joint (default: the robot's, NICO's right arm; see "
                        "docs/hardware.md)")
    from ikbench.cli.options import add_robot_arguments

    add_robot_arguments(parser)


def run(args) -> int:
    from ikbench.cli.options import robot_from_args
    from ikbench.core.io import atomic_write_csv, check_writable
    from ikbench.hw.motors import load_motor_config
    from ikbench.hw.plan import plan_trajectory_file

    robot = robot_from_args(args)
    config = load_motor_config(args.motors, robot)
    plan, note = plan_trajectory_file(args.trajectory, config, args.duration, strict=False,
                                      robot=robot)
    out = args.out or _default_out(args.trajectory)
    check_writable(out)  # after reading the inputs (no folder made for a missing trajectory)
    atomic_write_csv(out, plan.table(), float_format="%.10g")
    print(format_plan(plan))
    if note:
        print(note)
    print(f"segment table written to {out}")
    return 0


def format_plan(plan) -> str:
    """The segment table as text: speeds [deg/s] per joint and flags, then a summary."""
    import numpy as np
    import pandas as pd

    names = plan.config.joint_names
    short = [name.removeprefix("r_").removeprefix("l_") for name in names]
    table = plan.table()
    view = pd.DataFrame({"seg": table["segment"], "t_end_s": table["t_end_s"].round(3)})
    for name, label in zip(names, short):
        view[label] = table[f"{name}_speed_deg_s"].round(1)
    view["flags"] = [_flags(a, b) for a, b in zip(table["over_speed"], table["out_of_limits"])]
    header = (f"{plan.n_segments} segments of {plan.segment_s * 1000:g} ms (T = "
              f"{plan.duration_s:g} s); joint speeds in motor deg/s")
    lines = [header, view.to_string(index=False)]
    peak = plan.speed_deg_s.max(axis=0)
    lines.append("peak speed: " + ", ".join(
        f"{label} {p:.1f}/{m.max_speed_deg_s:g}" for label, p, m in
        zip(short, peak, plan.config.motors)) + " deg/s (peak/limit)")
    flagged = int(np.count_nonzero(plan.flagged))
    if flagged:
        lines.append(f"FLAGGED: {flagged} of {plan.n_segments} segments; "
                     + "; ".join(plan.problems()))
    else:
        lines.append("no segment flagged: within the speed and angle limits")
    return "\n".join(lines)


def _flags(over_speed: str, out_of_limits: str) -> str:
    parts = [f"speed:{over_speed}"] if over_speed else []
    parts += [f"limits:{out_of_limits}"] if out_of_limits else []
    return " ".join(parts)


def _default_out(trajectory: str) -> str:
    from pathlib import Path

    path = Path(trajectory)
    return str(path.with_name(path.name.removesuffix(".csv") + ".plan.csv"))
