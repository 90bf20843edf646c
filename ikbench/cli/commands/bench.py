"""``ikbench bench``: wall-time benchmark of methods on the same targets."""

from __future__ import annotations

HELP = "time methods on the same targets (median/min/max, ratios, losses)"
DEFAULT_METHODS = "ours,ours-lm"


def register(subparsers) -> None:
    from ikbench.cli.options import add_line_task_arguments, add_threads_and_quiet

    parser = subparsers.add_parser(
        "bench", help=HELP,
        description=(
            "Solve the targets with each method in one process: warm-up rounds, then timed "
            "rounds; every trajectory is timed on its own, and batched methods also solve all "
            "targets in one call. Writes OUTPUT/benchmark.csv (median, min, max wall time per "
            "method and trajectory, totals, speed-ups against the first method, final losses "
            "and metrics), benchmark_runs.csv (every timed solve), benchmark.json (settings, "
            "CPU, versions, git revision) and benchmark.md (with the range of per-trajectory "
            "speed-ups). The output folder is checked before timing. The paper's method takes "
            "tens of seconds per round, so by default it runs 3 rounds and other methods 5."
        ),
    )
    parser.add_argument("--methods", default=DEFAULT_METHODS,
                        help=f"comma-separated methods; the first is the baseline of the ratios "
                        f"(default: {DEFAULT_METHODS})")
    add_line_task_arguments(parser)
    parser.add_argument("--repeat", default=None,
                        help="timed rounds: N for every method, or N,method=M to give a "
                        "method of --methods its own count (default: each method's own, 5; "
                        "ours 3)")
    parser.add_argument("--warmup", type=int, default=1,
                        help="untimed rounds before timing (default 1)")
    parser.add_argument("--output", default="runs",
                        help="output directory (default: runs, which git ignores)")
    add_threads_and_quiet(parser)
    parser.set_defaults(func=run)


def run(args) -> int:
    from pathlib import Path

    from ikbench.cli.options import check_threads, robot_from_args, set_threads, targets_from_args
    from ikbench.core.io import check_writable
    from ikbench.studies.bench import (
        benchmark,
        headline,
        parse_methods,
        parse_repeat,
        speedup_ranges,
        write,
    )

    check_threads(args.threads)
    names = parse_methods(args.methods)
    parse_repeat(args.repeat, names)
    robot = robot_from_args(args)
    targets = targets_from_args(args, robot)
    check_writable(Path(args.output) / "benchmark.csv")  # before the timed rounds
    set_threads(args.threads)
    result = benchmark(names, repeat=args.repeat, warmup=args.warmup, targets=targets,
                       progress=not args.quiet, robot=robot)
    path = write(result, args.output)
    table = headline(result).drop(columns=["iterations", "line_distance_mean_mm",
                                           "pointing_deviation_mean_deg", "end_point_error_mm",
                                           "within_limits"], errors="ignore")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    base = result.record["methods"][0]
    for method, (low, t_low, high, t_high) in speedup_ranges(result.summary, base).items():
        print(f"per trajectory, {method} vs {base}: {low:.1f}x (trajectory {t_low}) to "
              f"{high:.1f}x (trajectory {t_high})")
    print(f"written to {path} (and benchmark.md, benchmark_runs.csv, benchmark.json)")
    return 0
