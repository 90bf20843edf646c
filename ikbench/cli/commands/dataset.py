"""``ikbench dataset``: N random reachable line trajectories solved by ours-lm, as Parquet."""

from __future__ import annotations

import argparse

from ikbench.cli.options import (
    add_executor_arguments,
    add_method_options,
    add_progress_arguments,
    add_robot_arguments,
    begin,
    check_executor_args,
    check_threads,
    executor_from_args,
    method_from_args,
    robot_from_args,
)
from ikbench.cli.values import OUTPUT, SEED, STEPS, THREADS, count
from ikbench.studies.folders import default_output

HELP = "a training set: N random reachable trajectories (ours-lm) as Parquet shards"


DESCRIPTION = (
    "Draw N touch poses with the batch sampler (the robot config's workspace filter; "
    "shard k seeded by (--seed, k)), solve one line task per pose from the start pose "
    "with ours-lm in one batch per shard, and write OUTPUT/steps/part-*.parquet (one "
    "row per trajectory and step: joints, fingertip x_mm, y_mm, z_mm, pointing "
    "direction), OUTPUT/trajectories/part-*.parquet (one row per trajectory: start "
    "and touch poses and points, loss and terms, iterations, convergence, line "
    "distance, pointing deviation, errors, smoothness) and OUTPUT/dataset.json (the "
    "options, the schema with units, totals). Run it again with the same options to "
    "resume: complete shards are kept. The same seed gives the same files with any "
    "executor and shard order.")


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.methods.ours_lm import OursLM
    from ikbench.studies.batch import MAX_COUNT as MAX_SHARD_SIZE
    from ikbench.studies.dataset import DEFAULT_SHARD_SIZE, MAX_COUNT, MAX_SHARDS

    parser.add_argument("--count", type=count("trajectories", 1, MAX_COUNT), default=1000,
                        help=f"number of trajectories N, at most {MAX_COUNT:,} and "
                        f"{MAX_SHARDS:,} shards (default 1000)")
    parser.add_argument("--seed", type=SEED, default=0,
                        help="seed, an integer in [0, 2^63) (default 0)")
    parser.add_argument("--steps", type=STEPS, default=50,
                        help="number of segments n per trajectory (default 50)")
    parser.add_argument("--shard-size", type=count("trajectories", 1, MAX_SHARD_SIZE,
                                                   "one shard is one batch in memory"),
                        default=DEFAULT_SHARD_SIZE,
                        help="trajectories per shard and per batched solve, at most "
                        f"{MAX_SHARD_SIZE:,} (default {DEFAULT_SHARD_SIZE}; on a GPU larger "
                        "shards, e.g. 100000, run faster)")
    add_robot_arguments(parser)
    parser.add_argument("--targets", default=None,
                        help="targets JSON file whose start pose is used (default: the "
                        "robot's, NICO: the paper's)")
    parser.add_argument("--output", default=default_output("dataset"), type=OUTPUT,
                        help="dataset folder (default: runs/dataset, which git ignores)")
    parser.add_argument("--threads", type=THREADS, default=1,
                        help="torch threads for --device cpu (default 1)")
    add_progress_arguments(parser)
    add_executor_arguments(parser)
    add_method_options(parser, {OursLM.name: OursLM})  # the dataset's solver


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace
    from pathlib import Path

    from ikbench.core.io import check_writable
    from ikbench.core.targets import load_targets
    from ikbench.methods.ours_lm import OursLM
    from ikbench.studies import dataset as study

    check_threads(args.threads)
    check_executor_args(args)
    solver = method_from_args(args, OursLM, {OursLM.name: OursLM})
    robot = robot_from_args(args)
    targets = load_targets(args.targets, robot)  # its start pose is used: checked up front
    spec = study.DatasetSpec(args.count, robot, targets, seed=args.seed, steps=args.steps,
                             shard_size=args.shard_size, lm_settings=solver.settings,
                             output=Path(args.output), progress=not args.quiet)
    spec.validate()
    check_writable(spec.output / study.MANIFEST)  # before sampling and solving
    begin(args, threads=args.threads)
    # the executor after begin: --executor ray starts or joins Ray
    spec = replace(spec, executor=executor_from_args(args))
    report = study.run(spec)
    report.write(spec.output)
    summary, run_figures = report.manifest["summary"], report.manifest["this_run"]
    rate = run_figures["trajectories_per_s"]
    print(f"{summary['trajectories']} trajectories in {args.output}/ "
          f"({len(report.kept)} shard(s) kept, {len(report.written)} built"
          + (f", {rate:.0f} trajectories/s" if rate else "") + "); converged "
          f"{summary['converged_share']:.1%}, median line distance "
          f"{summary['line_distance_mean_mm_median']:.3f} mm, median pointing deviation "
          f"{summary['pointing_deviation_mean_deg_median']:.2f} deg")
    return 0
