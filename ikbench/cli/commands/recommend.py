"""``ikbench recommend``: which IK solver for this robot, within this budget, with intervals."""

from __future__ import annotations

import argparse
import shlex

from ikbench.cli.options import add_progress_arguments, add_robot_arguments, begin, robot_from_args
from ikbench.cli.values import OUTPUT, SEED, Number, count
from ikbench.studies.folders import default_output

HELP = ("which single-pose IK solver for my robot: every installed method on a sample sized "
        "to --minutes, success and per-call times with 95 %% intervals, and a verdict")
DEFAULT_OUTPUT = default_output("recommend")
#: The default budgets [ms] per call and per path (ikbench.studies.recommend.BUDGET_MS,
#: PATH_BUDGET_MS; not imported: the CLI starts light).
BUDGET_MS, PATH_BUDGET_MS = 5.0, 1000.0
#: --budget-ms: a finite time per call [ms] (the p99 is held against it).
BUDGET = Number("a budget per call [ms]", 0.0, 3_600_000.0, low_open=True,
                hint="the p99 per call is held against it; inf has no meaning here")
MINUTES = Number("minutes", 0.0, 1440.0, low_open=True)

DESCRIPTION = (
    "Answers \"which IK solver should I use for my robot?\": runs every installed single-pose "
    "method on the deterministic protocol of `ikbench ik` (at most --attempts initial "
    "configurations per target, no wall-clock cut) on 3 seeds, each with a target sample "
    "sized so the whole run fits --minutes (a 20-target pilot per method measures the cost; "
    "the size is stated). Reports success with its Wilson 95 % interval, per-call p50 and "
    "p99 with bootstrap intervals, each method's first call in a fresh process, the joint "
    "distance and, where an analytic solver applies, the nearest-branch share; ranks the "
    "methods on each seed (Kendall tau between them) and writes a verdict: the recommended "
    "method for the budget (its p99 within --budget-ms), the methods tied with it, the "
    "trade-off. Writes OUTPUT/recommend/<robot>/: recommend.md, recommend.csv, results.csv, "
    "pareto.png, CITATIONS.bib, run.json. --task path: circles and lines of poses placed "
    "in the robot's reachable workspace (orientation held), every installed method that "
    "follows goal frames, success by CppFlow's validity.")


def arguments(parser: argparse.ArgumentParser) -> None:
    add_robot_arguments(parser)
    parser.add_argument("--budget-ms", type=BUDGET, default=None,
                        help="time per call [ms] the p99 must be within (finite, > 0; "
                        f"default {BUDGET_MS:g}: TRAC-IK's default timeout; --task path: per "
                        f"path, default {PATH_BUDGET_MS:g})")
    parser.add_argument("--task", choices=("pose", "position", "path"), default="pose",
                        help="pose (6-D, default), position (rotation free), or path: circles "
                        "and lines of poses placed in the reachable workspace, solved by the "
                        "methods that follow goal frames, judged by CppFlow's validity")
    parser.add_argument("--minutes", type=MINUTES, default=5.0,
                        help="time the whole run may take [min]; the sample is sized to fit "
                        "(default 5)")
    parser.add_argument("--methods", default=None,
                        help="comma-separated methods (default: every installed one that "
                        "takes the task; ikbench methods lists them)")
    parser.add_argument("--seed", type=SEED, default=1,
                        help="the first of the 3 seeds (default 1)")
    parser.add_argument("--attempts", type=count("attempts", 1, 1000), default=10,
                        help="initial configurations per target at most (default 10)")
    parser.add_argument("--output", default=DEFAULT_OUTPUT, type=OUTPUT,
                        help=f"writes OUTPUT/recommend/<robot>/ (default {DEFAULT_OUTPUT})")
    add_progress_arguments(parser)


def command_line(args: argparse.Namespace) -> str:
    """The command as given, every default spelled out (for recommend.md)."""
    words = ["ikbench", "recommend", "--robot", args.robot]
    if args.end_frame:
        words += ["--end-frame", args.end_frame]
    words += ["--task", args.task, "--budget-ms", f"{args.budget_ms:g}", "--minutes",
              f"{args.minutes:g}", "--seed", str(args.seed), "--attempts", str(args.attempts)]
    if args.methods:
        words += ["--methods", args.methods]
    words += ["--output", args.output]
    return " ".join(shlex.quote(w) for w in words)


def run(args: argparse.Namespace) -> int:
    # imported here, not at the top: the CLI starts light (the study pulls in every
    # installed solver library), and `ikbench --help` must not pay for it
    from ikbench.core.io import check_folder_writable
    from ikbench.render.recommend_report import folder_of
    from ikbench.studies import recommend as study
    from ikbench.studies.recommend import RecommendSettings, RecommendSpec, method_names

    if args.budget_ms is None:
        args.budget_ms = PATH_BUDGET_MS if args.task == "path" else BUDGET_MS
    names_given = None if args.methods is None else tuple(args.methods.split(","))
    settings = RecommendSettings(args.budget_ms, args.task, args.minutes, args.seed,
                                 args.attempts, methods=names_given)
    robot = robot_from_args(args)
    spec = RecommendSpec(robot, settings, tuple(method_names(settings)),
                         progress=not args.quiet, command=command_line(args))
    spec.validate()
    folder = folder_of(args.output, robot)
    check_folder_writable(folder)
    begin(args)
    result = study.run(spec)
    result.write(args.output)
    print(result.verdict)
    unit = "paths" if args.task == "path" else "targets"
    print(f"written to {folder}/ in {result.wall_s:.0f} s ({result.plan.targets_per_seed} "
          f"{unit} per seed x 3 seeds)")
    return 0
