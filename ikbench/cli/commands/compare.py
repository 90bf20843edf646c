"""``ikbench compare``: many methods and libraries on the same tasks, one table."""

from __future__ import annotations

HELP = "compare methods and libraries on the same robot and tasks: results.csv, leaderboard"
DEFAULT_METHODS = "ours-lm,sequential-ik"
DEFAULT_OUTPUT = "runs"


def register(subparsers) -> None:
    from ikbench.cli.options import add_line_task_arguments, add_threads_and_quiet

    parser = subparsers.add_parser(
        "compare", help=HELP,
        description=(
            "Run every method on every task of the robot's targets, --repeat times each, "
            "timed by the same harness, and write OUTPUT/compare/: results.csv (one row per "
            "method and trajectory: success against stated tolerances, line distance, "
            "pointing deviation, start/end errors, smoothness, median/min/max solve time, "
            "iterations, the failure if any), leaderboard.md (fastest, most accurate, "
            "smoothest; ratios against the reference method measured in the same run), "
            "pareto.png, run.json (library versions, machine) and one run folder per method "
            "as `ikbench run` writes it. A method that is not installed or fails is a row "
            "saying so. ikbench methods lists the methods."),
    )
    parser.add_argument("--methods", default=None,
                        help=f"comma-separated methods (default {DEFAULT_METHODS}; with "
                        "--problems every method that takes goal frames); 'all' for every "
                        "registered method")
    parser.add_argument("--problems", action="append", default=None,
                        metavar="cppflow|NAME,...|FILE",
                        help="compare on Cartesian pose-path problems instead of touch poses: "
                        "the same as ikbench cartesian --problems (writes OUTPUT/cartesian/)")
    parser.add_argument("--seeds", default=None,
                        help="with --problems: seeds of the start search (default 1,2,3)")
    add_line_task_arguments(parser)
    parser.add_argument("--repeat", type=int, default=5,
                        help="solves per method and trajectory; times are medians (default 5)")
    parser.add_argument("--reference", default=None,
                        help="method the ratios are against (default ours-lm if compared, "
                        "else the first)")
    from ikbench.cli.options import add_executor_arguments

    add_executor_arguments(parser)
    parser.add_argument("--output", default=DEFAULT_OUTPUT,
                        help=f"results directory; writes OUTPUT/compare/ (default "
                        f"{DEFAULT_OUTPUT}, which git ignores)")
    add_threads_and_quiet(parser)
    parser.set_defaults(func=run)


def run(args) -> int:
    if args.problems:
        return run_problems(args)
    if args.seeds is not None:
        from ikbench.core.errors import InputError

        raise InputError("--seeds applies to --problems only")
    from pathlib import Path

    from ikbench.cli.options import (
        check_executor_args,
        check_threads,
        executor_from_args,
        robot_from_args,
        set_threads,
        targets_from_args,
    )
    from ikbench.core.io import check_folder_writable
    from ikbench.methods.registry import method_status
    from ikbench.studies.compare import check_repeat, compare, parse_methods

    check_threads(args.threads)
    check_executor_args(args)
    methods = args.methods or DEFAULT_METHODS
    names = list(method_status()) if methods.strip() == "all" else parse_methods(methods)
    check_repeat(args.repeat)
    robot = robot_from_args(args)
    targets = targets_from_args(args, robot)
    check_folder_writable(Path(args.output) / "compare")
    set_threads(args.threads)
    result = compare(names, robot=robot, targets=targets, repeat=args.repeat,
                     output=args.output, reference=args.reference, progress=not args.quiet,
                     executor=executor_from_args(args))
    board = result.leaderboard.drop(columns=["note"])
    print(board.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"written to {Path(args.output) / 'compare'}/ (leaderboard.md, results.csv, "
          "pareto.png)")
    return 0


def run_problems(args) -> int:
    """``compare --problems``: the Cartesian benchmark (ikbench cartesian)."""
    import argparse

    from ikbench.cli.commands import cartesian
    from ikbench.studies.cartesian import DEFAULT_SEEDS

    if args.targets or args.only or args.steps is not None or args.reference:
        from ikbench.core.errors import InputError

        raise InputError("--targets, --only, --steps and --reference do not apply to "
                         "--problems (the problem files define the paths)")
    given = argparse.Namespace(
        problems=args.problems, methods=None if args.methods == "all" else args.methods,
        seeds=args.seeds or ",".join(map(str, DEFAULT_SEEDS)), output=args.output,
        trajectories="first", threads=args.threads, quiet=args.quiet)
    return cartesian.run(given)
