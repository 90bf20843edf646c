"""``ikbench run``: generate trajectories with a method and write tables, figures, report."""

from __future__ import annotations


def register(subparsers) -> None:
    from ikbench.methods import available_methods

    methods = available_methods()
    parser = subparsers.add_parser(
        "run",
        help="generate trajectories with a method; write CSVs, table, figures and report",
        description=(
            "Generate one trajectory per touch pose with a method and write, under "
            "OUTPUT/<method>/, trajectory_<id>.csv (motor degrees), table.csv (line distance "
            "[mm], pointing deviation [deg], start/end errors), details.csv, run.json "
            "(settings and versions), trajectories_3d.png, pointing_error.png and report.md. "
            "Methods: " + "; ".join(f"{name}: {cls.description}"
                                    for name, cls in methods.items())
        ),
    )
    parser.add_argument("--method", default="ours",
                        help=f"one of: {', '.join(methods)} (default: ours)")
    parser.add_argument("--targets", default=None,
                        help="targets JSON file (default: the paper's seven touch poses)")
    parser.add_argument("--only", default=None, help="comma-separated trajectory ids, e.g. 1,3")
    parser.add_argument("--steps", type=int, default=None,
                        help="number of segments n (default: the targets file's, 50)")
    parser.add_argument("--output", default="results",
                        help="output directory (default: results)")
    parser.add_argument("--duration", type=float, default=2.0,
                        help="movement duration T [s] for the time_s column (default 2)")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    for name, cls in methods.items():
        cls.add_arguments(parser.add_argument_group(f"options of {name}"))
    parser.set_defaults(func=run)


def run(args) -> int:
    from ikbench.methods import get_method
    from ikbench.run import run as run_method
    from ikbench.targets import TargetsError

    if args.steps is not None and args.steps < 2:
        raise TargetsError(f"--steps: {args.steps} must be an integer >= 2")
    solver = get_method(args.method).from_args(args)
    table = run_method(solver, targets=args.targets, only=args.only, steps=args.steps,
                       output=args.output, duration_s=args.duration, progress=not args.quiet)
    columns = ["trajectory", "iterations", "duration_s", "loss", "line_distance_mean_mm",
               "pointing_deviation_mean_deg", "end_point_error_mm"]
    print(table[columns].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"written to {args.output}/{solver.name}/")
    return 0
