"""``ikbench sweep``: the paper's objective with a grid of other loss weights."""

from __future__ import annotations


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "sweep",
        help="solve the targets for a grid of loss weights (ours-lm); CSV, Pareto figure",
        description=(
            "Minimise the paper's objective with ours-lm for every combination of the given "
            "weights (other terms keep the paper's weights; the paper's setting is always "
            "included) on the targets, in one batched solve. Writes OUTPUT/sweep.csv (one row "
            "per setting: mean line distance [mm], pointing deviation [deg], smoothness, "
            "worst end errors, Pareto flag), sweep_trajectories.csv, pareto.png (line "
            "distance vs pointing deviation, smoothness as colour), sweep.json and sweep.md."
        ),
    )
    parser.add_argument("--weight", action="append", metavar="TERM=V1,V2,...",
                        help="a term of the grid and its values, e.g. --weight c0=1,10,100,1000 "
                        "(repeat for a grid over several terms: --weight c1=5,50)")
    parser.add_argument("--targets", default=None,
                        help="targets JSON file (default: the paper's seven touch poses)")
    parser.add_argument("--only", default=None, help="comma-separated trajectory ids, e.g. 1,3")
    parser.add_argument("--steps", type=int, default=None,
                        help="number of segments n (default: the targets file's, 50)")
    parser.add_argument("--output", default="results/sweep",
                        help="output directory (default: results/sweep)")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    parser.set_defaults(func=run)


def run(args) -> int:
    from ikbench.errors import InputError
    from ikbench.sweep import parse_grid, sweep, write

    grid = parse_grid(args.weight)
    if args.steps is not None and args.steps < 2:
        raise InputError(f"--steps: {args.steps} must be an integer >= 2")
    result = sweep(grid, targets=args.targets, only=args.only, steps=args.steps,
                   progress=not args.quiet)
    path = write(result, args.output)
    cols = ["setting", "line_distance_mean_mm", "pointing_deviation_mean_deg",
            "mean_sq_joint_step_deg2", "end_point_error_mm", "pareto"]
    table = result.settings.sort_values("line_distance_mean_mm")[cols]
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"written to {path} (and sweep.md, pareto.png, sweep_trajectories.csv)")
    return 0
