"""``ikbench view``: the arm playing run folders' trajectories, in the browser."""

from __future__ import annotations

import argparse
import re
from typing import TYPE_CHECKING

from ikbench.cli.commands.plan import add_timing_arguments, check_timing_args, timing_from_args
from ikbench.cli.options import begin
from ikbench.cli.values import Number, PathValue, Text, duration_s
from ikbench.core.errors import InputError

if TYPE_CHECKING:
    from collections.abc import Sequence

    from ikbench.core.robot import Robot
    from ikbench.viewer.folders import ViewRun

HELP = "show run folders in a 3-D browser viewer: the arm, goal and fingertip paths, playback"
INSTALL = "pip install 'ikbench[viewer]'"


DESCRIPTION = (
    "Serve an interactive 3-D view of run folders (written by ikbench run, letters or "
    "compare) and print its URL: the robot drawn from its URDF's visual shapes, the "
    "goal path (rebuilt from run.json; the panel says how), the fingertip path, a "
    "timeline slider and Play at the trajectory's real speed. Several folders (runs "
    "of the same robot, e.g. results/ours results/sequential-ik) are shown side by "
    "side: the first run's arm in the URDF's colours, the others as their fingertip paths "
    "in their colour (--ghosts, or the panel's box: their whole arms too, as ghosts); a "
    f"dropdown picks the trajectory. Ctrl-C stops it. Needs viser: {INSTALL}."
    " See docs/viewer.md.")


def arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folders", nargs="+", metavar="RUN_DIR",
                        type=PathValue("a run folder", must_exist="dir"),
                        help="run folders (OUTPUT/NAME/ with run.json), e.g. results/ours, "
                        "or a folder of them (compare's OUTPUT/compare/: every method)")
    parser.add_argument("--port", type=Number("a TCP port", 0, 65535, integer=True,
                                              shown="from 0 to 65535"),
                        default=8080,
                        help="TCP port (default 8080; the next free one if it is taken; 0: any)")
    parser.add_argument("--host", default="127.0.0.1", type=host_value,
                        help="interface to listen on (default 127.0.0.1, this machine only; "
                        "0.0.0.0: every interface)")
    parser.add_argument("--no-browser", action="store_true",
                        help="do not open a browser (e.g. on a server; open the URL printed)")
    parser.add_argument("--ghosts", action="store_true",
                        help="draw the other runs' whole arms as translucent ghosts from the "
                        "start (default: their fingertip paths only, which keeps a humanoid "
                        "readable; the panel's 'whole ghosts' box switches)")
    parser.add_argument("--trajectory", default=None, metavar="ID",
                        help="trajectory shown first (default: the first)")
    parser.add_argument("--duration", type=duration_s(), default=None, metavar="T",
                        help="duration of each movement in seconds for --timing constant and "
                        "min-jerk (default: each trajectory's own, its time_s column)")
    add_timing_arguments(parser)


def host_value(text: str) -> str:
    """The --host argument checked (argparse ``type``): a host name or an IP address."""
    text = Text("a host name or IP address", max_chars=253)(text)
    if not re.fullmatch(r"[A-Za-z0-9.:_\-\[\]%]+", text):
        raise argparse.ArgumentTypeError(f"{text!r} is not a host name or IP address (e.g. "
                                         "127.0.0.1, 0.0.0.0, localhost)")
    return text


def run(args: argparse.Namespace) -> int:
    from ikbench.viewer.folders import check_folders, load_runs

    check_timing_args(args)
    folders = check_folders(args.folders)
    try:
        import viser  # noqa: F401
    except ImportError:
        raise InputError(f"ikbench view needs viser, which is not installed: {INSTALL}") from None
    from ikbench.viewer.server import check_trajectory, run_forever

    robot, runs = load_runs(folders)
    retime_runs(robot, runs, args)
    check_trajectory(runs, args.trajectory)
    begin(args)
    run_forever(robot, runs, port=args.port, host=args.host, open_browser=not args.no_browser,
                trajectory=args.trajectory, ghosts=args.ghosts)
    return 0


def retime_runs(robot: Robot, runs: Sequence[ViewRun], args: argparse.Namespace) -> None:
    """Apply --timing (and --duration) to every trajectory of ``runs``."""
    timing, limits = timing_from_args(args, robot)
    for run in runs:
        for trajectory in run.trajectories.values():
            trajectory.retime(robot, timing, limits, args.duration)
