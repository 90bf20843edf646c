"""``ikbench run``: generate trajectories with a method and write tables, figures, report."""

from __future__ import annotations

LINE_COLUMNS = ["trajectory", "iterations", "duration_s", "loss", "line_distance_mean_mm",
                "pointing_deviation_mean_deg", "end_point_error_mm"]
SHAPE_COLUMNS = ["trajectory", "iterations", "duration_s", "loss", "curve_distance_mean_mm",
                 "curve_distance_max_mm", "point_error_mean_mm", "pointing_deviation_mean_deg"]


def register(subparsers) -> None:
    from ikbench.methods import available_methods

    methods = available_methods()
    parser = subparsers.add_parser(
        "run",
        help="generate trajectories with a method; write CSVs, table, figures and report",
        description=(
            "Generate one trajectory per touch pose (or per letter, or one along a polyline or "
            "spline) with a method and write, under "
            "OUTPUT/NAME/ (NAME: --name, default the method's name), trajectory_<id>.csv "
            "(motor degrees), table.csv (line distance "
            "[mm], pointing deviation [deg], start/end errors; for other shapes the distance "
            "from the target curve), details.csv, run.json "
            "(settings and versions), figures and report.md. Trajectory CSVs of an earlier "
            "run in that folder that this run does not write are removed. "
            "Methods: " + "; ".join(f"{name}: {cls.description}"
                                    for name, cls in methods.items())
        ),
    )
    add_task_arguments(parser, only_help="comma-separated trajectory ids, e.g. 1,3",
                       start_pose_default="the targets file's")
    add_run_arguments(parser, methods, "results")
    parser.add_argument("--name", default=None,
                        help="folder under OUTPUT for this run (default: the method's name), "
                        "e.g. sequential-ik-position; letters, digits, '_', '-', '.'")
    parser.set_defaults(func=run)


def add_task_arguments(parser, only_help: str, start_pose_default: str) -> None:
    """--targets, --only, --shape, --size, --direction, --start-pose, --steps (run, sweep)."""
    parser.add_argument("--targets", default=None,
                        help="targets JSON file (default: the paper's seven touch poses)")
    parser.add_argument("--only", default=None, help=only_help)
    parser.add_argument("--shape", default="line",
                        help="line (default: one per touch pose), polyline:FILE or spline:FILE "
                        "(CSV of x,y,z control points [mm], torso frame), or letter:X[,Y...] "
                        "(letters A-Z on the frontal plane through the fingertip at the start "
                        "pose, one trajectory each)")
    parser.add_argument("--size", type=float, default=None,
                        help="letter height [mm] (default 300)")
    parser.add_argument("--direction", default=None,
                        help="goal pointing directions: tangent (default for line, polyline, "
                        "spline), normal (of the drawing plane; default for letters) or a "
                        "vector x,y,z")
    add_start_pose_argument(parser, start_pose_default)
    parser.add_argument("--steps", type=int, default=None,
                        help="number of segments n (default: the targets file's, 50, for "
                        "lines; 100 for other shapes)")


def add_start_pose_argument(parser, default: str) -> None:
    parser.add_argument("--start-pose", default=None,
                        help=f"start pose, 7 comma-separated motor angles (default: {default}); "
                        "write --start-pose=-24,... for a leading minus")


def add_run_arguments(parser, methods: dict, default_output: str) -> None:
    """--method, output options and every method's own options (shared with ``letters``)."""
    parser.add_argument("--method", default="ours",
                        help=f"one of: {', '.join(methods)} (default: ours)")
    parser.add_argument("--output", default=default_output,
                        help=f"output directory (default: {default_output})")
    parser.add_argument("--duration", type=float, default=2.0,
                        help="movement duration T [s] for the time_s column (default 2)")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    parser.add_argument("--threads", type=int, default=1,
                        help="torch threads (default 1: the tensors are tiny, and on a busy "
                        "2-core machine 2 threads ran ours 15x slower than 1)")
    for name, cls in methods.items():
        cls.add_arguments(parser.add_argument_group(f"options of {name}"))


def reject_foreign_options(args, method) -> None:
    """InputError if an option of another method was given (it would be silently ignored)."""
    from ikbench.errors import InputError
    from ikbench.methods import available_methods

    for name, cls in available_methods().items():
        for dest in cls.options:
            if dest not in method.options and getattr(args, dest, None) is not None:
                raise InputError(f"--{dest.replace('_', '-')} is an option of --method {name}, "
                                 f"not of --method {method.name}")


def run(args, shape: str | None = None) -> int:
    from ikbench.errors import InputError
    from ikbench.methods import get_method
    from ikbench.run import check_name
    from ikbench.run import run as run_method
    from ikbench.targets import TargetsError, parse_pose

    if args.steps is not None and args.steps < 2:
        raise TargetsError(f"--steps: {args.steps} must be an integer >= 2")
    if args.threads < 1:
        raise InputError(f"--threads: {args.threads} must be an integer >= 1")
    import torch

    torch.set_num_threads(args.threads)
    start_pose = None if args.start_pose is None else parse_pose(args.start_pose,
                                                                 what="--start-pose")
    method = get_method(args.method)
    reject_foreign_options(args, method)
    name = getattr(args, "name", None)
    if name is not None:
        check_name(name)
    solver = method.from_args(args)
    table = run_method(solver, targets=getattr(args, "targets", None),
                       only=getattr(args, "only", None), steps=args.steps, output=args.output,
                       duration_s=args.duration, progress=not args.quiet,
                       shape=shape or args.shape, size_mm=args.size, start_pose=start_pose,
                       direction=args.direction, name=name)
    columns = LINE_COLUMNS if "line_distance_mean_mm" in table else SHAPE_COLUMNS
    print(table[columns].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"written to {args.output}/{name or solver.name}/")
    return 0
