"""``ikbench ik``: the single-pose IK benchmark (success and solve time per library)."""

from __future__ import annotations

import argparse

from ikbench.cli.commands import Subparsers
from ikbench.cli.values import OUTPUT

HELP = "single-pose IK benchmark: success rate and solve time of every library on a robot"
DEFAULT_OUTPUT = "runs"


def register(subparsers: Subparsers) -> None:
    from ikbench.cli.options import add_progress_arguments, add_robot_arguments

    parser = subparsers.add_parser(
        "ik", help=HELP,
        description=(
            "Solve COUNT single-pose IK targets (FK of configurations drawn uniformly within "
            "the limits, seeded) with every installed library, each from the same initial "
            "poses, timing each call, and judge every answer by FK through Pinocchio. Writes "
            "OUTPUT/ik/<robot>/: results.csv (one row per method x target; Parquet above 50,000 "
            "rows), targets.csv, leaderboard.md, times.png, success_vs_tolerance.png, "
            "run.json. Robots by package name: --robot example-robot-data:panda (ikbench "
            "robots --all lists them)."),
    )
    add_robot_arguments(parser)
    parser.add_argument("--count", type=int, default=1000, help="targets (default 1000)")
    parser.add_argument("--seed", type=int, default=1, help="seed of targets, initial poses "
                        "and restarts (default 1)")
    parser.add_argument("--methods", default=None,
                        help="comma-separated methods (default: every installed one: ours-lm, "
                        "trac-ik, sequential-ik, pink, mink, drake-ik, pyroki, ikpy)")
    parser.add_argument("--kind", choices=("pose", "position"), default="pose",
                        help="pose (6-D, default) or position (rotation free)")
    parser.add_argument("--tolerance-mm", type=float, default=1.0,
                        help="position tolerance of a success [mm] (default 1)")
    parser.add_argument("--tolerance-deg", type=float, default=0.5,
                        help="rotation tolerance of a success [deg] (default 0.5)")
    parser.add_argument("--init", choices=("random", "nearby"), default="random",
                        help="initial pose: random (uniform within the limits, default) or "
                        "nearby (the target's configuration perturbed by --perturb-deg)")
    parser.add_argument("--perturb-deg", type=float, default=10.0,
                        help="--init nearby: largest change per joint [deg] (default 10)")
    parser.add_argument("--max-count-per-method", default=None, metavar="METHOD=N,...",
                        help="solve only the first N targets with METHOD (slow libraries, "
                        "e.g. ikpy=500); the leaderboard says so")
    parser.add_argument("--output", default=DEFAULT_OUTPUT, type=OUTPUT,
                        help=f"output directory; writes OUTPUT/ik/<robot>/ (default "
                        f"{DEFAULT_OUTPUT})")
    add_progress_arguments(parser)
    parser.set_defaults(func=run)


def parse_caps(text: str | None) -> dict[str, int]:
    """``"ikpy=500,drake-ik=2000"`` -> {"ikpy": 500, "drake-ik": 2000}; InputError else."""
    from ikbench.core.errors import InputError

    caps: dict[str, int] = {}
    for item in (text or "").split(","):
        if not item.strip():
            continue
        name, sep, value = item.partition("=")
        try:
            caps[name.strip()] = int(value)
        except ValueError:
            sep = ""
        if not sep or not name.strip():
            raise InputError(f"--max-count-per-method: {item!r} is not METHOD=N")
    return caps


def command_line(args: argparse.Namespace) -> str:
    """The command as given (for the leaderboard)."""
    import shlex

    words = ["ikbench", "ik", "--robot", args.robot]
    if args.end_frame:
        words += ["--end-frame", args.end_frame]
    words += ["--count", str(args.count), "--seed", str(args.seed)]
    if args.methods:
        words += ["--methods", args.methods]
    words += ["--kind", args.kind, "--tolerance-mm", f"{args.tolerance_mm:g}",
              "--tolerance-deg", f"{args.tolerance_deg:g}", "--init", args.init]
    if args.init == "nearby":
        words += ["--perturb-deg", f"{args.perturb_deg:g}"]
    if args.max_count_per_method:
        words += ["--max-count-per-method", args.max_count_per_method]
    words += ["--output", args.output]
    return " ".join(shlex.quote(w) for w in words)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ikbench.cli.options import begin, robot_from_args
    from ikbench.core.io import check_folder_writable
    from ikbench.render.ik_report import summarise
    from ikbench.studies.ik import (
        FOLDER,
        IKSettings,
        check_memory,
        parse_methods,
        robot_slug,
        run_ik,
        write,
    )

    settings = IKSettings(args.count, args.seed, args.kind, args.tolerance_mm,
                          args.tolerance_deg, args.init, args.perturb_deg,
                          parse_caps(args.max_count_per_method))
    robot = robot_from_args(args)
    names = parse_methods(args.methods, args.kind)
    folder = Path(args.output) / FOLDER / robot_slug(robot)
    check_folder_writable(folder)
    check_memory(settings.count, len(names))
    begin(args)
    result = run_ik(robot, settings, names, progress=not args.quiet)
    write(result, args.output, command_line(args))
    summary = summarise(result.table)
    print(summary[["method", "targets", "success_pct", "time_median_ms", "time_p95_ms",
                   "batched_time_per_ik_ms"]].to_string(
                       index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"written to {folder}/")
    return 0
