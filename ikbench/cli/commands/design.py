"""``ikbench design``: design a trajectory by hand in the browser, re-solved as you drag."""

from __future__ import annotations

import argparse

from ikbench.cli.options import add_robot_arguments, begin, robot_from_args
from ikbench.core.defaults import DEFAULT_DURATION_S, DEFAULT_ROBOT, DESIGN_METHOD, REFERENCE_METHOD
from ikbench.core.errors import InputError
from ikbench.studies.folders import default_output

HELP = "design a trajectory by hand in the browser: drag a point, see it re-solved and judged"
INSTALL = "pip install 'ikbench[viewer]'"


DESCRIPTION = (
    "Serve a 3-D designer and print its URL. Drag the touch point (or the start "
    "point) of a line, the centre of a letter (--shape letter:X; its size in the "
    "panel) or a waypoint of a 6-D pose path (--problem): every move re-solves the "
    "trajectory with --method, warm-started from the previous solution, plays it, and "
    "judges it live against the task contract (line distance, pointing, the largest "
    "step against the speed limit, joint limits, collisions where the robot has a "
    "collision model). Save writes OUTPUT/NAME.targets.json (or NAME.yaml and "
    "NAME.csv) and the run folder OUTPUT/NAME/ exactly as ikbench run writes it. "
    f"Ctrl-C stops it. Needs viser: {INSTALL}. See docs/viewer.md.")


def arguments(parser: argparse.ArgumentParser) -> None:
    add_robot_arguments(parser)
    parser.add_argument("--targets", default=None,
                        help="targets JSON file whose poses the design starts from (default: "
                        "the robot's own; a robot without any starts mid-range)")
    parser.add_argument("--trajectory", default=None, metavar="ID",
                        help="the touch pose a line starts from (default: the first)")
    parser.add_argument("--shape", default="line",
                        help="line (default) or letter:X (one letter)")
    parser.add_argument("--size", type=float, default=None, help="letter height [mm] "
                        "(default 300)")
    parser.add_argument("--start-pose", default=None,
                        help="start pose (a letter: the pose it is placed from), "
                        "comma-separated values in the robot's units; write --start-pose=-24,.. "
                        "for a leading minus")
    parser.add_argument("--steps", type=int, default=None,
                        help="number of segments n (default: the targets file's; 100 for a "
                        "letter)")
    parser.add_argument("--problem", default=None, metavar="FILE.yaml|NAME",
                        help="a 6-D pose path problem (CppFlow's format) whose waypoints are "
                        "dragged, instead of a line or letter")
    parser.add_argument("--method", default=DESIGN_METHOD,
                        help=f"the method that re-solves (default {DESIGN_METHOD}; ours-lm and "
                        "ours-exact start from the previous solution, others from scratch)")
    parser.add_argument("--fallback", default=REFERENCE_METHOD,
                        help="the method shown where --method's solution is infeasible "
                        f"(default {REFERENCE_METHOD}; none: no fallback)")
    parser.add_argument("--timing", default="constant", metavar="NAME",
                        help="constant (default), min-jerk or topp (changeable in the panel)")
    parser.add_argument("--duration", type=float, default=DEFAULT_DURATION_S,
                        help=f"movement duration T [s] (default {DEFAULT_DURATION_S:g})")
    parser.add_argument("--output", default=default_output("design"),
                        help="where Save writes (default runs)")
    parser.add_argument("--name", default="design",
                        help="the saved run's name (default design)")
    parser.add_argument("--port", type=int, default=8080,
                        help="TCP port (default 8080; the next free one if it is taken; 0: any)")
    parser.add_argument("--host", default="127.0.0.1",
                        help="interface to listen on (default 127.0.0.1, this machine only)")
    parser.add_argument("--no-browser", action="store_true",
                        help="do not open a browser (e.g. on a server; open the URL printed)")


def run(args: argparse.Namespace) -> int:
    from ikbench.core.targets import parse_pose
    from ikbench.core.timing import check_timing
    from ikbench.methods.registry import get_method
    from ikbench.studies.run import check_name, check_problem_options

    if not 0 <= args.port <= 65535:
        raise InputError(f"--port: {args.port} is not a port number (0-65535)")
    check_timing(args.timing)
    if not (args.duration > 0 and args.duration < float("inf")):
        raise InputError(f"--duration {args.duration:g}; give a positive number of seconds")
    check_name(args.name)
    fallback = None if args.fallback.lower() == "none" else args.fallback
    for name in (args.method, fallback):
        if name is not None:
            get_method(name)
    try:
        import viser  # noqa: F401
    except ImportError:
        raise InputError(f"ikbench design needs viser, which is not installed: {INSTALL}"
                         ) from None
    from ikbench.viewer.design.designer import Designer, DesignSpec
    from ikbench.viewer.design.view import run_design_forever

    if args.problem is not None:
        check_problem_options(targets=args.targets, trajectory=args.trajectory,
                              shape=args.shape, size=args.size, start_pose=args.start_pose,
                              steps=args.steps)
    robot = (None if args.problem is not None and args.robot == DEFAULT_ROBOT
             else robot_from_args(args))
    start = None if args.start_pose is None or robot is None else parse_pose(
        args.start_pose, robot, "--start-pose")
    spec = DesignSpec(shape=args.shape, targets=args.targets, trajectory=args.trajectory,
                      start_pose=start, steps=args.steps, size_mm=args.size,
                      problem=args.problem, duration_s=args.duration, timing=args.timing,
                      fallback=fallback)
    begin(args)
    designer = Designer(robot, args.method, spec)
    run_design_forever(designer, port=args.port, host=args.host,
                       open_browser=not args.no_browser, output=args.output, name=args.name)
    return 0
