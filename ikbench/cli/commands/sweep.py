"""``ikbench sweep``: the paper's objective with a grid of other loss weights."""

from __future__ import annotations

import argparse

from ikbench.cli.commands.letters import paper_start_pose
from ikbench.cli.commands.run import add_task_arguments
from ikbench.cli.options import (
    add_study_arguments,
    begin,
    check_executor_args,
    executor_from_args,
    robot_from_args,
)
from ikbench.cli.values import MAX_LIST_CHARS, Text
from ikbench.studies.folders import default_output

HELP = ("solve the targets or a shape for a grid of loss weights (ours-lm or ours-exact); "
        "CSV, Pareto figure")


DESCRIPTION = (
    "Minimise the paper's objective with ours-lm for every combination of the given "
    "weights (other terms keep the reference weights: the paper's for lines, "
    "polylines and splines, the paper's letter setting c0=1, c1=50, c6=1, others 0, "
    "for letters; the reference setting is always included) on the targets or a "
    "shape, in one batched solve. Writes OUTPUT/sweep.csv (one row per setting: mean "
    "line distance [mm] for lines, point error and distance from the curve [mm] for "
    "other shapes, pointing deviation [deg], smoothness, worst errors, Pareto flag), "
    "sweep_trajectories.csv, pareto.png (accuracy vs pointing deviation, smoothness "
    "as colour), sweep.json and sweep.md. With --method ours-exact the path and the "
    "fixed poses are constraints: the grid may hold c1 (pointing) and c6 "
    "(smoothness), around ours-exact's defaults.")


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.studies.sweep import SWEEP_METHODS

    methods = tuple(SWEEP_METHODS)
    parser.add_argument("--method", default=methods[0], choices=methods,
                        help=f"the method swept (default {methods[0]})")
    parser.add_argument("--weight", action="append", metavar="TERM=V1,V2,...",
                        type=Text("a term and its values", max_chars=MAX_LIST_CHARS),
                        help="a term of the grid and its values, e.g. --weight c0=1,10,100,1000 "
                        "(repeat for a grid over several terms: --weight c1=5,50)")
    add_task_arguments(parser, only_help="comma-separated trajectory ids, e.g. 1,3 (line only)",
                       start_pose_default=f"the targets file's; for letters the robot's "
                       f"letter pose, NICO: the paper's {paper_start_pose()}")
    add_study_arguments(parser, default_output("sweep"))


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace
    from pathlib import Path

    from ikbench.core.io import check_writable
    from ikbench.core.targets import parse_pose
    from ikbench.studies import sweep as study

    check_executor_args(args)
    grid = study.parse_grid(args.weight)
    robot = robot_from_args(args)
    start_pose = None if args.start_pose is None else parse_pose(args.start_pose, robot,
                                                                 "--start-pose")
    targets, tasks, kind = study.sweep_tasks(robot, args.targets, args.shape, args.only,
                                             args.steps, args.size, start_pose, args.direction)
    spec = study.SweepSpec(grid, robot, targets, tuple(tasks), kind, args.shape, args.size,
                           args.direction, method=args.method, progress=not args.quiet)
    spec.validate()  # the method, the tasks and the grid's size checked before anything runs
    check_writable(Path(args.output) / "sweep.csv")  # before the solve, not after it
    begin(args)
    spec = replace(spec, executor=executor_from_args(args))  # starts or joins Ray: only now
    spec.validate()  # the method on that executor
    result = study.run(spec)
    path = result.write(args.output)
    m = study.measures_of(result.settings, args.method)
    cols = [c for c in m.table_columns if c not in ("loss", "paper_loss", "converged")]
    table = result.settings.sort_values(m.accuracy)[cols]
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"written to {path} (and sweep.md, pareto.png, sweep_trajectories.csv)")
    return 0
