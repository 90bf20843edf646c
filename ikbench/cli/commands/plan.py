"""``ikbench plan``: per-segment speeds of a trajectory, checked against the motors' limits."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from ikbench.cli.options import add_robot_arguments, begin, robot_from_args
from ikbench.cli.values import INPUT_FILE, OUTPUT, PathValue, duration_s
from ikbench.core.defaults import DEFAULT_DURATION_S

if TYPE_CHECKING:
    from collections.abc import Sequence

    from ikbench.core.robot import Robot
    from ikbench.core.timing import Limits, TimedPath
    from ikbench.hw.motors import MotorConfig
    from ikbench.hw.plan import MotionPlan

HELP = "segment table of a trajectory: joint speeds [motor deg/s] and limit flags"

#: A trajectory CSV to read.
TRAJECTORY_CSV = PathValue("a trajectory CSV", must_exist="file")


DESCRIPTION = (
    "Split a trajectory CSV into segments (segment k runs from pose k to pose k+1 in "
    "T/n seconds, or when --timing reaches them), compute each joint's speed "
    "|delta|/duration in motor deg/s and the "
    "Dynamixel register values the executor would send (goal position, moving speed), "
    "and flag segments that exceed a motor's speed limit or leave its angle limits. "
    "Prints the table and writes it as CSV. See docs/timing.md.")


def arguments(parser: argparse.ArgumentParser) -> None:
    add_plan_arguments(parser)
    parser.add_argument("--out", metavar="CSV", type=OUTPUT,
                        help="segment table CSV to write (default: TRAJ with suffix .plan.csv)")
    parser.add_argument("--figure", nargs="?", const="", default=None, metavar="PNG",
                        type=OUTPUT,
                        help="also draw joint speeds and fingertip speed against time for the "
                        "three timings (default file: TRAJ with suffix .timing.png)")


def add_plan_arguments(parser: argparse.ArgumentParser) -> None:
    """The trajectory, --duration and --motors options shared with ``ikbench execute``."""
    parser.add_argument("trajectory", metavar="TRAJ.csv", type=TRAJECTORY_CSV,
                        help="trajectory CSV (columns step, time_s, joint angles in motor deg, "
                        "...), as written by ikbench")
    parser.add_argument("--duration", type=duration_s(), default=DEFAULT_DURATION_S,
                        metavar="T",
                        help=f"duration of the whole movement in seconds (default: "
                        f"{DEFAULT_DURATION_S:g}, the paper's)")
    parser.add_argument("--motors", metavar="FILE", type=INPUT_FILE,
                        help="motor config JSON: Dynamixel id, model, offset, orientation and "
                        "angle limits per joint (default: the robot's, NICO's right arm; see "
                        "docs/hardware.md)")
    add_timing_arguments(parser)
    add_robot_arguments(parser)


def add_timing_arguments(parser: argparse.ArgumentParser) -> None:
    """--timing, --max-velocity and --max-acceleration (plan, execute, export, view)."""
    from ikbench.core.timing import DEFAULT_TIMING, TIMINGS

    parser.add_argument("--timing", default=DEFAULT_TIMING, metavar="NAME",
                        help="when each pose is reached: " + "; ".join(
                            f"{k}: {v}" for k, v in TIMINGS.items()) + " (see docs/timing.md)")
    parser.add_argument("--max-velocity", default=None, metavar="V[,V...]",
                        help="topp: joint speed limit in pose units/s (motor deg/s for NICO, "
                        "deg/s for Panda), one value or one per joint (default: the robot's: "
                        "NICO's motor table, else the URDF's velocity limits)")
    parser.add_argument("--max-acceleration", default=None, metavar="A[,A...]",
                        help="topp: joint acceleration limit in pose units/s^2, one value or "
                        "one per joint (default: the robot's; see docs/timing.md)")


def timing_from_args(args: argparse.Namespace, robot: Robot, config: MotorConfig | None = None
                     ) -> tuple[str, Limits | None]:
    """``(timing, limits)`` of the timing options; limits None unless ``topp``."""
    from ikbench.core.timing import check_timing

    timing = check_timing(args.timing)
    if timing != "topp":
        return timing, None
    from ikbench.hw.limits import timing_limits

    return timing, timing_limits(robot, config, args.max_velocity, args.max_acceleration)


def check_timing_args(args: argparse.Namespace) -> None:
    """Refuse a bad --timing or limit option before anything heavy loads."""
    from ikbench.core.timing import check_timing
    from ikbench.core.timing_limits import parse_limit_option

    check_timing(args.timing)
    for field, text in (("max_velocity", args.max_velocity),
                        ("max_acceleration", args.max_acceleration)):
        if text is not None:
            count = len(str(text).split(","))
            parse_limit_option(text, count, field)


def run(args: argparse.Namespace) -> int:
    from ikbench.core.io import atomic_write_csv, check_writable
    from ikbench.hw.motors import load_motor_config
    from ikbench.hw.plan import plan_trajectory_file

    check_timing_args(args)
    robot = robot_from_args(args)
    config = load_motor_config(args.motors, robot)
    timing, limits = timing_from_args(args, robot, config)
    plan, note = plan_trajectory_file(args.trajectory, config, args.duration, strict=False,
                                      robot=robot, timing=timing, limits=limits)
    out = args.out or _default_out(args.trajectory)
    check_writable(out)  # after reading the inputs (no folder made for a missing trajectory)
    figure = None
    if args.figure is not None:
        figure = args.figure or _default_out(args.trajectory, ".timing.png")
        check_writable(figure)
    begin(args)
    atomic_write_csv(out, plan.table(), float_format="%.10g")
    print(format_plan(plan))
    if note:
        print(note)
    print(f"segment table written to {out}")
    if figure is not None:
        _write_figure(figure, robot, plan, args, config)
    return 0


def _write_figure(path, robot, plan, args, config) -> None:
    from ikbench.core.io import atomic_savefig
    from ikbench.core.timing_topp import toppra_available
    from ikbench.hw.limits import timing_limits
    from ikbench.render.timing_plot import plot_timings, timings_of

    limits = (plan.timed.limits if plan.timed is not None and plan.timed.limits is not None
              else timing_limits(robot, config, args.max_velocity, args.max_acceleration))
    timings = timings_of(robot, plan.poses_motor_deg, args.duration, limits,
                         topp=toppra_available())
    from pathlib import Path

    fig = plot_timings(robot, timings, limits, title=Path(args.trajectory).name)
    atomic_savefig(path, fig)
    import matplotlib.pyplot as plt

    plt.close(fig)
    missing = "" if "topp" in timings else " (topp left out: toppra is not installed)"
    print(f"timing figure written to {path}{missing}")


def format_plan(plan: MotionPlan) -> str:
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
    if plan.timed is not None:
        segment_ms = np.diff(plan.times_s) * 1000
        header = (f"{plan.n_segments} segments of {segment_ms.min():.3g} to "
                  f"{segment_ms.max():.3g} ms (--timing {plan.timing}, T = "
                  f"{plan.duration_s:.4g} s); joint speeds in motor deg/s")
    lines = [header, view.to_string(index=False)]
    peak = plan.speed_deg_s.max(axis=0)
    lines.append("peak speed: " + ", ".join(
        f"{label} {p:.1f}/{m.max_speed_deg_s:g}" for label, p, m in
        zip(short, peak, plan.config.motors)) + " deg/s (peak/limit)")
    if plan.timed is not None:
        lines += timing_lines(plan.timed, short, plan.config.source)
    flagged = int(np.count_nonzero(plan.flagged))
    if flagged:
        lines.append(f"FLAGGED: {flagged} of {plan.n_segments} segments; "
                     + "; ".join(plan.problems()))
    else:
        lines.append("no segment flagged: within the speed and angle limits")
    return "\n".join(lines)


def timing_lines(timed: TimedPath, labels: Sequence[str], config_source: str = "") -> list[str]:
    """Lines on a retimed plan: limits, their peak use, the constant timing within them, and
    what the bus plays between poses."""
    from ikbench.core.timing import constant_duration_within, limit_use

    lines = ["between poses: the bus gets the solved poses as goals at their retimed times "
             "and each servo moves at constant speed to the next (no resampling; the path "
             "the servos follow is the paper timing's)"]
    if timed.limits is not None:
        limits = timed.limits
        v_use, a_use = limit_use(timed.times_s, timed.poses, limits)
        lines.append(f"limits: {limits.source}")
        lines.append("peak use of the limits (finite differences of the table's poses and "
                     "times): " + ", ".join(f"{label} v {v:.3f} a {a:.3f}" for label, v, a in
                                            zip(labels, v_use, a_use)))
        lines.append(f"duration {timed.duration_s:.4g} s; the constant timing within the same "
                     f"limits needs {constant_duration_within(timed.poses, limits):.4g} s")
    return lines


def _flags(over_speed: str, out_of_limits: str) -> str:
    parts = [f"speed:{over_speed}"] if over_speed else []
    parts += [f"limits:{out_of_limits}"] if out_of_limits else []
    return " ".join(parts)


def _default_out(trajectory: str, suffix: str = ".plan.csv") -> str:
    from pathlib import Path

    path = Path(trajectory)
    return str(path.with_name(path.name.removesuffix(".csv") + suffix))
