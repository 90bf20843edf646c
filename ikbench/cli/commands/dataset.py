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
from ikbench.core.errors import InputError
from ikbench.studies.folders import default_output

HELP = "a training set: N random reachable trajectories (ours-lm) as Parquet shards"
#: At most this many trajectories (a million took 76 min on one CPU core, docs/scale.md).
MAX_COUNT = 1_000_000_000
#: At most this many shards: the plan of the dataset holds one entry per shard.
MAX_SHARDS = 100_000


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
    from ikbench.studies.dataset import DEFAULT_SHARD_SIZE

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
    from pathlib import Path

    from ikbench.core.io import check_writable
    from ikbench.methods.ours_lm import OursLM
    from ikbench.studies.dataset import MANIFEST, build_dataset, check_options

    check_sizes(args.count, args.shard_size)
    check_options(args.count, args.seed, args.steps, args.shard_size)
    check_threads(args.threads)
    check_executor_args(args)
    solver = method_from_args(args, OursLM, {OursLM.name: OursLM})
    robot = robot_from_args(args)
    from ikbench.core.targets import load_targets

    load_targets(args.targets, robot)  # its start pose is used: checked up front
    check_writable(Path(args.output) / MANIFEST)  # before sampling and solving
    begin(args, threads=args.threads)
    report = build_dataset(args.count, seed=args.seed, steps=args.steps,
                           shard_size=args.shard_size, lm_settings=solver.settings,
                           targets=args.targets, robot=robot, output=args.output,
                           executor=executor_from_args(args), progress=not args.quiet)
    summary, run_figures = report.manifest["summary"], report.manifest["this_run"]
    rate = run_figures["trajectories_per_s"]
    print(f"{summary['trajectories']} trajectories in {args.output}/ "
          f"({len(report.kept)} shard(s) kept, {len(report.written)} built"
          + (f", {rate:.0f} trajectories/s" if rate else "") + "); converged "
          f"{summary['converged_share']:.1%}, median line distance "
          f"{summary['line_distance_mean_mm_median']:.3f} mm, median pointing deviation "
          f"{summary['pointing_deviation_mean_deg_median']:.2f} deg")
    return 0


def check_sizes(count: int, shard_size: int) -> None:
    """InputError, before anything is planned, for a --count or --shard-size beyond the
    stated maxima (a count of 10^12 used to fill the memory with the plan of its shards)."""
    from ikbench.studies.batch import MAX_COUNT as MAX_SHARD_SIZE

    if count > MAX_COUNT:
        raise InputError(f"--count: {count} is more than the maximum, {MAX_COUNT:,} "
                         "trajectories")
    if shard_size > MAX_SHARD_SIZE:
        raise InputError(f"--shard-size: {shard_size} is more than the maximum, "
                         f"{MAX_SHARD_SIZE:,} (one shard is one batch in memory)")
    if count >= 1 and shard_size >= 1 and -(-count // shard_size) > MAX_SHARDS:
        raise InputError(f"--count {count} in shards of {shard_size} makes "
                         f"{-(-count // shard_size):,} shards, more than the maximum, "
                         f"{MAX_SHARDS:,}; raise --shard-size to at least "
                         f"{-(-count // MAX_SHARDS)}")
