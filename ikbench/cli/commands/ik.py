"""``ikbench ik``: the single-pose IK benchmark (success and solve time per library)."""

from __future__ import annotations

import argparse

from ikbench.cli.options import add_progress_arguments, add_robot_arguments, begin, robot_from_args
from ikbench.cli.values import OUTPUT, Number
from ikbench.core.errors import InputError
from ikbench.studies.folders import default_output

HELP = ("single-pose IK benchmark: success rate and time per call of every library on a robot, "
        "under one protocol (budget, initial configurations, attempts)")
DEFAULT_OUTPUT = default_output("ik")


#: The default budget [ms] (ikbench.studies.ik.BUDGET_MS; not imported: the CLI starts light).
BUDGET_MS = 5.0
#: --budget-ms: more than 0 ms, at most an hour, or inf (no budget).
BUDGET = Number("a budget [ms]", 0.0, 3_600_000.0, low_open=True, infinite="no budget")
#: The default attempts rule: the deterministic protocol of the committed studies
#: (ikbench.studies.ik.DEFAULT_ATTEMPTS; not imported: the CLI starts light).
ATTEMPTS = "8"


DESCRIPTION = (
    "Solve COUNT single-pose IK targets (FK of configurations drawn uniformly within "
    "the limits, seeded) with every installed library under one protocol: each target "
    "has a seeded sequence of initial configurations, the same for every method. By "
    f"default (--attempts {ATTEMPTS}) a method makes at most {ATTEMPTS} attempts with no "
    "wall-clock cut: deterministic, the same success columns run to run (TRAC-IK excepted: "
    "it restarts from its own random draws within its timeout); 1: one descent each. "
    "--attempts auto restarts it from the next configuration until its answer holds or "
    "the wall-clock budget (--budget-ms) is spent: load-dependent, its successes change "
    "with the machine's load (--repeat R runs it R times and gives the spread). "
    "One target per call, each call timed; every answer judged by FK through Pinocchio. "
    "Writes OUTPUT/ik/<robot>/: "
    "results.csv (one row per rule x method x target with the answer's joint values; "
    "Parquet above 50,000 rows), targets.csv, leaderboard.md, times.png, "
    "success_vs_tolerance.png, run.json. Robots by package name: --robot "
    "example-robot-data:panda (ikbench robots --all lists them).")


def arguments(parser: argparse.ArgumentParser) -> None:
    # the registry scans the adapters: only when this command's parser is built (CLI start-up)
    from ikbench.methods.registry import solver_status

    add_robot_arguments(parser)
    parser.add_argument("--count", type=int, default=1000, help="targets (default 1000)")
    parser.add_argument("--seed", type=int, default=1, help="seed of targets and initial "
                        "configurations (default 1)")
    parser.add_argument("--methods", default=None,
                        help="comma-separated methods (default: every installed one: "
                        f"{', '.join(solver_status())})")
    parser.add_argument("--budget-ms", type=BUDGET, default=BUDGET_MS,
                        help="wall-clock budget per target [ms] of --attempts auto (and "
                        "TRAC-IK's timeout under every rule), the same for every method; "
                        f"inf: none (default {BUDGET_MS:g}: TRAC-IK's default timeout)")
    parser.add_argument("--attempts", default=ATTEMPTS, metavar="N|auto[,...]",
                        help="N: at most N attempts from the target's seeded initial "
                        "configurations, no wall-clock cut, so success depends on the seed "
                        "alone: the same table run to run (TRAC-IK excepted: its own random "
                        "restarts within its timeout); 1: one descent from the first, for "
                        "every method; auto: restart from the next configuration until the "
                        "answer holds or --budget-ms is spent, load-dependent (its successes "
                        "change with the machine's load: give --repeat); several rules, "
                        f"e.g. {ATTEMPTS},auto,1, give one table each (default {ATTEMPTS})")
    parser.add_argument("--repeat", type=int, default=1,
                        help="runs of the load-dependent auto table on the same targets and "
                        "rows: the summary and leaderboard give the median and the spread "
                        "(min-max) of its successes over them; fixed-count rules run once, "
                        "their success is the same every run (default 1)")
    parser.add_argument("--threads", type=int, default=None,
                        help="threads of the batched throughput run of the methods that batch "
                        "(default: every core)")
    parser.add_argument("--kind", choices=("pose", "position"), default="pose",
                        help="pose (6-D, default) or position (rotation free)")
    parser.add_argument("--tolerance-mm", type=float, default=1.0,
                        help="position tolerance of a success [mm] (default 1)")
    parser.add_argument("--tolerance-deg", type=float, default=0.5,
                        help="rotation tolerance of a success [deg] (default 0.5)")
    parser.add_argument("--init", choices=("random", "nominal", "nearby", "learned"),
                        default="random",
                        help="the first initial configuration: random (uniform within the "
                        "limits, default), nominal (the middle of the limits, as TRAC-IK's "
                        "benchmark seeds), nearby (the target's configuration perturbed by "
                        "--perturb-deg, the tracking case) or learned (the best proposal of "
                        "the pose model --model, and its next K - 1 proposals as the next "
                        "rows); the further ones are uniform draws")
    parser.add_argument("--model", default=None, metavar="MODEL",
                        help="--init learned: a pose model file of ikbench learn, trained for "
                        "this robot; its file, training samples and CPU-minutes, query time "
                        "per target (model_query_ms) and raw error go into run.json and "
                        "summary.csv")
    parser.add_argument("--first-call", action="store_true",
                        help="also time each method's first call in a fresh process (import, "
                        "set-up, first solve), after the timed runs: its own table and the "
                        "first_call_ms column")
    parser.add_argument("--unreachable", type=float, default=0.0, metavar="FRACTION",
                        help="replace this fraction of the targets (0 to 0.9) by frames beyond "
                        "the robot's reach (half of them, where an analytic solver applies: an "
                        "orientation it proves impossible at a reachable position): no method "
                        "may succeed on them; the report gives "
                        "each library's claims on them and its time to give up (default 0)")
    parser.add_argument("--perturb-deg", type=float, default=10.0,
                        help="--init nearby: largest change per joint [deg] (default 10)")
    parser.add_argument("--max-count-per-method", default=None, metavar="METHOD=N,...",
                        help="solve only the first N targets with METHOD (slow libraries, "
                        "e.g. ikpy=500); the leaderboard says so")
    parser.add_argument("--output", default=DEFAULT_OUTPUT, type=OUTPUT,
                        help=f"output directory; writes OUTPUT/ik/<robot>/ (default "
                        f"{DEFAULT_OUTPUT})")
    add_progress_arguments(parser)


def parse_caps(text: str | None) -> dict[str, int]:
    """``"ikpy=500,drake-ik=2000"`` -> {"ikpy": 500, "drake-ik": 2000}; InputError else."""
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
    words += ["--budget-ms", f"{args.budget_ms:g}", "--attempts", args.attempts]
    if args.repeat != 1:
        words += ["--repeat", str(args.repeat)]
    if args.threads:
        words += ["--threads", str(args.threads)]
    words += ["--kind", args.kind, "--tolerance-mm", f"{args.tolerance_mm:g}",
              "--tolerance-deg", f"{args.tolerance_deg:g}", "--init", args.init]
    if args.init == "nearby":
        words += ["--perturb-deg", f"{args.perturb_deg:g}"]
    if args.model is not None:
        words += ["--model", args.model]
    if args.max_count_per_method:
        words += ["--max-count-per-method", args.max_count_per_method]
    if args.unreachable:
        words += ["--unreachable", f"{args.unreachable:g}"]
    if args.first_call:
        words += ["--first-call"]
    words += ["--output", args.output]
    return " ".join(shlex.quote(w) for w in words)


def auto_note(repeat: int) -> str:
    """The printed summary's line under a table with the ``auto`` rule."""
    spread = (f"its success_pct is the median of {repeat} runs, success_pct_min-max their "
              "spread" if repeat > 1 else "one run: give --repeat R for its spread")
    return ("attempts auto is load-dependent: its successes depend on the machine's load and "
            f"speed, not on the seed alone; {spread}")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ikbench.core.io import check_folder_writable
    from ikbench.render.ik_report import robot_slug, summarise
    from ikbench.studies import ik as study

    settings = study.IKSettings(args.count, args.seed, args.kind, args.tolerance_mm,
                                args.tolerance_deg, args.init, args.perturb_deg,
                                parse_caps(args.max_count_per_method), args.budget_ms,
                                study.parse_attempts(args.attempts), args.threads,
                                unreachable=args.unreachable, repeat=args.repeat,
                                first_call=args.first_call, model=args.model)
    robot = robot_from_args(args)
    spec = study.IKSpec(robot, settings, tuple(study.parse_methods(args.methods, args.kind)),
                        progress=not args.quiet, command=command_line(args))
    spec.validate()
    folder = Path(args.output) / study.FOLDER / robot_slug(robot)
    check_folder_writable(folder)
    begin(args)
    result = study.run(spec)
    result.write(args.output)
    summary = summarise(result.table, result.batches)
    columns = ["attempts_rule", "method", "targets", "success_pct", "attempts_median",
               "time_median_ms", "time_mean_ms", "time_p95_ms", "batched_per_s", "runs"]
    if "success_pct_min" in summary and (summary["runs"] > 1).any():  # the auto table's spread
        columns += ["success_pct_min", "success_pct_max"]
    shown = summary[columns].astype({"success_pct": object})
    unable = summary["cannot_run"].astype(bool) if "cannot_run" in summary else False
    shown.loc[unable, "success_pct"] = "cannot run"  # no call ran: no rate
    print(shown.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    for method, why in summary.loc[unable, ["method", "cannot_run"]].drop_duplicates().values:
        print(f"{method}: cannot run: {why}")
    if study.AUTO in settings.attempts:
        print(auto_note(settings.repeat))
    print(f"written to {folder}/")
    return 0
