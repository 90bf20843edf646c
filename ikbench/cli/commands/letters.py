"""``ikbench letters``: draw letters in the air (the paper's second experiment)."""

from __future__ import annotations

import argparse

from ikbench.cli.commands.run import (
    add_method_and_output,
    add_size_and_direction,
    add_solve_arguments,
    add_start_pose_argument,
)
from ikbench.cli.commands.run import run as run_command
from ikbench.cli.options import add_robot_arguments, robot_from_args
from ikbench.cli.values import STEPS, Text
from ikbench.core.defaults import DEFAULT_METHOD
from ikbench.core.errors import InputError
from ikbench.studies.folders import default_output

HELP = "draw letters A-Z in the air with the end point (the paper's letter experiment)"
DEFAULT_OUTPUT = default_output("letters")


#: Values the command's run() reads that no option of its own sets.
DEFAULTS = dict(only=None)


def description() -> str:
    """The paragraph of ``ikbench letters --help`` (it quotes the paper's letter setting)."""
    from ikbench.core.letters import DEFAULT_STEPS, PAPER_ITERATIONS

    return (
        "Draw each letter on the robot's letter plane through the end point at the start "
        "pose (NICO: the frontal plane, read by a viewer facing the robot, the finger "
        "pointing along its normal (-1, 0, 0)); no start/end pose or point terms. "
        "Same as `ikbench run --shape letter:LETTERS` with the paper's letter setting as "
        f"defaults: start pose from the robot config (NICO: {paper_start_pose()}), else "
        "from the targets (--targets FILE for a robot that ships none), "
        "letters 300 mm high, "
        f"n = {DEFAULT_STEPS}, weights c0=1, c1=50, c6=1, others 0, to which --weights "
        f"changes apply, and for ours --stop none --max-iterations {PAPER_ITERATIONS} "
        "(best loss kept). --method ours-lm solves a letter in a fraction of a second, "
        "starting with every pose at the start pose. Writes the run folder "
        f"OUTPUT/<method>/ (by default {DEFAULT_OUTPUT}/<method>/, e.g. "
        f"{DEFAULT_OUTPUT}/ours/): trajectory_<letter>.csv, table.csv, details.csv, "
        "run.json, shapes.png, animation.gif (unless --no-animation) and report.md.")


#: The paragraph of --help.
DESCRIPTION = description


def paper_start_pose() -> str:
    """NICO's letter start pose as the paper gives it, comma-separated [motor deg]."""
    from ikbench.core.letters import PAPER_START_POSE_DEG

    return ",".join(f"{v:g}" for v in PAPER_START_POSE_DEG)


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.core.letters import DEFAULT_STEPS
    from ikbench.methods.registry import available_methods

    # sequential methods start at a touch pose, which a letter does not have
    methods = {n: c for n, c in available_methods().items() if not c.capabilities.needs_touch_pose}
    parser.add_argument("letters", type=letters_value,
                        help="letters A-Z, comma-separated, e.g. P or P,A,S "
                        "(lower case is drawn upper case)")
    add_method_and_output(parser, methods, DEFAULT_OUTPUT, folder="<method>")
    add_robot_arguments(parser)
    parser.add_argument("--targets", default=None, metavar="FILE",
                        help="targets JSON file (start and touch poses in the robot's units) "
                        "whose start pose the letters start from when the robot config gives "
                        "no letter pose and --start-pose is not given (default: the robot's "
                        "own targets; a bare URDF or a description package's robot ships "
                        "none)")
    add_size_and_direction(parser, "normal (default), tangent or x,y,z")
    add_start_pose_argument(parser, f"the robot's letter pose; NICO: the paper's "
                            f"{paper_start_pose()}")
    parser.add_argument("--steps", type=STEPS, default=None,
                        help=f"number of segments n per letter (default {DEFAULT_STEPS})")
    add_solve_arguments(parser, methods)


def letters_value(text: str) -> str:
    """The LETTERS argument checked (argparse ``type``): comma-separated letters A-Z."""
    from ikbench.core.letters import parse_letters

    text = Text("letters A-Z, comma-separated")(text)
    try:
        parse_letters(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def run(args: argparse.Namespace) -> int:
    from ikbench.core.letters import PAPER_ITERATIONS
    from ikbench.core.targets import load_targets
    from ikbench.core.task import letter_start_pose

    if args.start_pose is None:
        robot = robot_from_args(args)
        targets = None if args.targets is None else load_targets(args.targets, robot)
        args.start_pose = ",".join(f"{v:.17g}" for v in letter_start_pose(robot, targets))
    fixed: dict[str, object] = {}
    if args.method == DEFAULT_METHOD:  # the paper's letter script: a fixed number of iterations
        if getattr(args, "opt_stop", None) is None:
            fixed["stop"] = "none"
        if getattr(args, "opt_max_iterations", None) is None:
            fixed["max_iterations"] = PAPER_ITERATIONS
    return run_command(args, shape=f"letter:{args.letters}", fixed=fixed)
