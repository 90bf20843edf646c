"""``ikbench view``: the arm playing run folders' trajectories, in the browser."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from ikbench.cli.commands import Subparsers

if TYPE_CHECKING:
    from collections.abc import Sequence

    from ikbench.core.robot import Robot
    from ikbench.viewer.folders import ViewRun

HELP = "show run folders in a 3-D browser viewer: the arm, goal and fingertip paths, playback"
INSTALL = "pip install 'ikbench[viewer]'"


def register(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "view", help=HELP,
        description=(
            "Serve an interactive 3-D view of run folders (written by ikbench run, letters or "
            "compare) and print its URL: the robot drawn from its URDF's visual shapes, the "
            "goal path (rebuilt from run.json; the panel says how), the fingertip path, a "
            "timeline slider and Play at the trajectory's real speed. Several folders (runs "
            "of the same robot, e.g. results/ours results/sequential-ik) are shown side by "
            "side: the first run's arm in the URDF's colours, the others as ghosts in their "
            f"colour; a dropdown picks the trajectory. Ctrl-C stops it. Needs viser: {INSTALL}."
            " See docs/viewer.md."),
    )
    parser.add_argument("folders", nargs="+", metavar="RUN_DIR",
                        help="run folders (OUTPUT/NAME/ with run.json), e.g. results/ours")
    parser.add_argument("--port", type=int, default=8080,
                        help="TCP port (default 8080; the next free one if it is taken; 0: any)")
    parser.add_argument("--host", default="127.0.0.1",
                        help="interface to listen on (default 127.0.0.1, this machine only; "
                        "0.0.0.0: every interface)")
    parser.add_argument("--no-browser", action="store_true",
                        help="do not open a browser (e.g. on a server; open the URL printed)")
    parser.add_argument("--trajectory", default=None, metavar="ID",
                        help="trajectory shown first (default: the first)")
    parser.add_argument("--duration", type=float, default=None, metavar="T",
                        help="duration of each movement in seconds for --timing constant and "
                        "min-jerk (default: each trajectory's own, its time_s column)")
    from ikbench.cli.commands.plan import add_timing_arguments

    add_timing_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ikbench.cli.commands.plan import check_timing_args
    from ikbench.core.errors import InputError
    from ikbench.viewer.folders import check_folders, load_runs

    if not 0 <= args.port <= 65535:
        raise InputError(f"--port: {args.port} is not a port number (0-65535)")
    check_timing_args(args)
    if args.duration is not None and not (args.duration > 0 and args.duration < float("inf")):
        raise InputError(f"--duration {args.duration:g}; give a positive number of seconds")
    check_folders(args.folders)
    try:
        import viser  # noqa: F401
    except ImportError:
        raise InputError(f"ikbench view needs viser, which is not installed: {INSTALL}") from None
    from ikbench.viewer.server import run_forever

    robot, runs = load_runs(args.folders)
    retime_runs(robot, runs, args)
    run_forever(robot, runs, port=args.port, host=args.host, open_browser=not args.no_browser,
                trajectory=args.trajectory)
    return 0


def retime_runs(robot: Robot, runs: Sequence[ViewRun], args: argparse.Namespace) -> None:
    """Apply --timing (and --duration) to every trajectory of ``runs``."""
    from ikbench.cli.commands.plan import timing_from_args

    timing, limits = timing_from_args(args, robot)
    for run in runs:
        for trajectory in run.trajectories.values():
            trajectory.retime(robot, timing, limits, args.duration)
