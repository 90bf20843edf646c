"""``ikbench compare``: many methods and libraries on the same tasks, one table."""

from __future__ import annotations

import argparse
import sys

from ikbench.cli.commands import cartesian
from ikbench.cli.options import (
    add_executor_arguments,
    add_line_task_arguments,
    add_threads_and_quiet,
    begin,
    check_executor_args,
    check_threads,
    executor_from_args,
    robot_from_args,
    targets_from_args,
)
from ikbench.cli.values import INPUT_FILE, OUTPUT, count, duration_s
from ikbench.core.defaults import COMPARE_METHODS, DEFAULT_DURATION_S
from ikbench.core.errors import InputError
from ikbench.studies.folders import WITHIN, default_output

HELP = "compare methods and libraries on the same robot and tasks: results.csv, leaderboard"
DEFAULT_METHODS = ",".join(COMPARE_METHODS)
DEFAULT_OUTPUT = default_output("compare")
#: At most this many solves per method and trajectory.
MAX_REPEAT = 1000


DESCRIPTION = (
    "Run every method on every task of the robot's targets under one task contract "
    "(start and touch poses fixed, the line, pointing over its judged part, the "
    "joints' speed limits at --duration, the tolerances), each task solved alone "
    "--repeat times, timed by the same harness, and write OUTPUT/compare/: "
    "results.csv (one row per method and trajectory: every criterion measured from "
    "the trajectory CSVs and judged, success on the paper's track and on the "
    "touch-pose-only track, single and batched solve times, the failure if any), "
    "leaderboard.md/.csv (one table per track, the contract above it, ratios against "
    "the reference method measured in the same run), pareto.png (with ours-lm's "
    "weight sweep), run.json (the contract, library versions, machine) and one run "
    "folder per method as `ikbench run` writes it. A method that is not installed, "
    "fails or does not honour the contract is a row saying so. Exit code 1 when a "
    "method is not installed, a solve failed or a method refused the tasks or does "
    "not honour the contract; "
    "130 on Ctrl-C (OUTPUT/compare/ left unchanged). docs/comparison.md explains "
    "the contract; ikbench methods lists the methods.")


def arguments(parser: argparse.ArgumentParser) -> None:
    # the registry scans the adapters: only when this command's parser is built (CLI start-up)
    from ikbench.methods.registry import method_status

    parser.add_argument("--methods", default=None,
                        help=f"comma-separated methods (default {DEFAULT_METHODS}; with "
                        "--problems every method that takes goal frames); 'all' for every "
                        f"registered method: {', '.join(method_status())}")
    parser.add_argument("--problems", action="append", default=None,
                        metavar="cppflow|NAME,...|FILE",
                        help="compare on Cartesian pose-path problems instead of touch poses: "
                        "the same as ikbench cartesian --problems (writes OUTPUT/cartesian/)")
    parser.add_argument("--seeds", default=None,
                        help="with --problems: seeds of the start search (default 1,2,3)")
    add_line_task_arguments(parser)
    parser.add_argument("--repeat", type=count("solves", 1, MAX_REPEAT), default=5,
                        help=f"solves per method and trajectory, 1 to {MAX_REPEAT}; times are "
                        "medians (default 5)")
    parser.add_argument("--tolerance", default=None, metavar="KEY=VALUE,...",
                        help="change the contract's tolerances: start_pose_deg, end_pose_deg "
                        "[pose units], line_distance_max_mm, pointing_judged_mean_deg, "
                        "speed_limit_use (1 = at the limit) (default start_pose_deg=0.5,"
                        "end_pose_deg=0.5,line_distance_max_mm=5,pointing_judged_mean_deg=15,"
                        "speed_limit_use=1)")
    parser.add_argument("--pointing", default="auto", choices=("auto", "on", "off"),
                        help="judge (and ask for) pointing along the line: auto = on for "
                        "robots whose config names a pointing axis, off for a bare URDF "
                        "(default auto)")
    parser.add_argument("--duration", type=duration_s(), default=DEFAULT_DURATION_S,
                        help="trajectory duration T [s] the speed limits are judged at "
                        f"(segments of T/n; default {DEFAULT_DURATION_S:g}, the paper's)")
    parser.add_argument("--obstacles", default=None, metavar="FILE|NAME|none",
                        help="obstacles on every task instead of the targets file's: an "
                        "obstacle file (*.json, *.yaml; mm, docs/collisions.md), a named set "
                        "of the robot (e.g. touchscreen for NICO) or none; the contract then "
                        "judges collisions (no self-collision, no obstacle collision; default: "
                        "the targets file's obstacles, none for the shipped targets)")
    parser.add_argument("--goals", default=None, metavar="FILE", type=INPUT_FILE,
                        help="goal set of the legibility columns: a targets file whose touch "
                        "poses' fingertip points are the goals (default: the targets' own, "
                        "every id; NICO's seven touch points; docs/legibility.md)")
    parser.add_argument("--reference", default=None,
                        help="method the ratios are against (default ours-lm if compared, "
                        "else the first)")
    add_executor_arguments(parser)
    parser.add_argument("--first-call", action="store_true",
                        help="after the timed solves, time each method's first call in a "
                        "fresh process (import, set-up on the robot, the first trajectory "
                        "solved once): the leaderboard's first_call_s column")
    parser.add_argument("--output", default=DEFAULT_OUTPUT, type=OUTPUT,
                        help=f"results directory; writes OUTPUT/compare/ (default "
                        f"{DEFAULT_OUTPUT}, which git ignores)")
    add_threads_and_quiet(parser)


def run(args: argparse.Namespace) -> int:
    if args.problems:
        return run_problems(args)
    if args.seeds is not None:
        raise InputError("--seeds applies to --problems only")
    from pathlib import Path

    from ikbench.core.io import check_folder_writable
    from ikbench.methods.registry import method_status
    from ikbench.studies import compare as study

    check_threads(args.threads)
    check_executor_args(args)
    methods = args.methods or DEFAULT_METHODS
    names = list(method_status()) if methods.strip() == "all" else study.parse_methods(methods)
    from ikbench.core.contract import contract_for, parse_tolerances

    parse_tolerances(args.tolerance)
    robot = robot_from_args(args)
    contract = contract_for(robot, tolerances=args.tolerance, pointing=args.pointing,
                            duration_s=args.duration)
    targets = study.with_obstacles(targets_from_args(args, robot), args.obstacles, robot)
    from ikbench.core.targets import load_targets

    # the goal set: --goals, else every id of the targets file (--only keeps fewer tasks)
    goals = load_targets(args.goals or args.targets, robot)
    spec = study.line_spec(names, robot, targets, contract, args.reference, args.repeat,
                           executor=executor_from_args(args), output=Path(args.output),
                           progress=not args.quiet, goals=goals, first_call=args.first_call)
    spec.validate()
    folder = Path(args.output) / WITHIN["compare"]
    check_folder_writable(folder)
    begin(args, threads=args.threads)
    from ikbench.runtime.harness import Interrupted

    try:
        result = study.run(spec)
        result.write(Path(args.output))
    except (Interrupted, KeyboardInterrupt):
        print(f"ikbench: interrupted; {folder}/ left unchanged",
              file=sys.stderr)
        return 130
    shown = ["track", "method", "status", "success_count", "trajectories", "time_median_s",
             "time_vs_reference", "line_distance_max_mm", "pointing_deviation_judged_mean_deg",
             "max_joint_step_deg"]
    if "collisions_count" in result.leaderboard:
        shown.insert(4, "collisions_count")
    if "first_call_s" in result.leaderboard:
        shown.insert(shown.index("time_vs_reference") + 1, "first_call_s")
    board = result.leaderboard[shown]
    print(board.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"written to {folder}/ (leaderboard.md, results.csv, "
          "pareto.png)")
    if result.failed:
        status = result.results["status"].astype(str)
        bad = result.results[status.str.startswith(study.FAILING)]
        missing = sorted(set(bad.loc[status == "not installed", "method"]))
        other = sorted(set(bad["method"]) - set(missing))
        print("ikbench: " + "; ".join(
            ([f"{', '.join(missing)}: not installed (ikbench methods says what to install)"]
             if missing else [])
            + ([f"{', '.join(other)}: a solve failed, the tasks were refused or the contract "
                "is not honoured (see the status column)"] if other else []))
            + "; exit code 1", file=sys.stderr)
        return 1
    return 0


def run_problems(args: argparse.Namespace) -> int:
    """``compare --problems``: the Cartesian benchmark (ikbench cartesian), its spec built and
    run as that command's (:func:`ikbench.cli.commands.cartesian.spec_of`, ``run_spec``), with
    every method's defaults."""
    from ikbench.studies.cartesian import DEFAULT_SEEDS

    if args.targets or args.only or args.steps is not None or args.reference \
            or args.obstacles is not None or args.goals is not None:
        raise InputError("--targets, --only, --steps, --obstacles, --goals and --reference do not "
                         "apply to --problems (the problem files define the paths and their "
                         "obstacles)")
    spec = cartesian.spec_of(args, ",".join(args.problems),
                             None if args.methods == "all" else args.methods,
                             args.seeds or ",".join(map(str, DEFAULT_SEEDS)))
    return cartesian.run_spec(spec, args)
