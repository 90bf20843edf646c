"""``ikbench bench``: wall-time benchmark of methods on the same targets."""

from __future__ import annotations

import argparse

from ikbench.cli.options import (
    add_line_task_arguments,
    add_progress_arguments,
    begin,
    check_threads,
    robot_from_args,
    targets_from_args,
)
from ikbench.cli.values import OUTPUT, THREADS, count
from ikbench.core.defaults import BENCH_METHODS
from ikbench.core.errors import InputError
from ikbench.studies.folders import default_output

HELP = "time methods on the same targets (median/min/max, ratios, losses)"
DEFAULT_METHODS = ",".join(BENCH_METHODS)
#: At most this many untimed rounds.
MAX_WARMUP = 100


DESCRIPTION = (
    "Solve the targets with each method in one process: warm-up rounds, then timed "
    "rounds; every trajectory is timed on its own, and batched methods also solve all "
    "targets in one call. Writes OUTPUT/benchmark.csv (median, min, max wall time per "
    "method and trajectory, totals, speed-ups against the first method, final losses "
    "and metrics), benchmark_runs.csv (every timed solve), benchmark.json (settings, "
    "CPU, versions, git revision) and benchmark.md (with the range of per-trajectory "
    "speed-ups). The output folder is checked before timing. The paper's method takes "
    "tens of seconds per round, so by default it runs 3 rounds and other methods 5.")


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.studies.throughput import MAX_BATCH

    parser.add_argument("--methods", default=None,
                        help=f"comma-separated methods; the first is the baseline of the ratios "
                        f"(default: {DEFAULT_METHODS}; not with --device)")
    add_line_task_arguments(parser)
    parser.add_argument("--repeat", default=None,
                        help="timed rounds: N for every method, or N,method=M to give a "
                        "method of --methods its own count (default: each method's own, 5; "
                        "ours 3)")
    parser.add_argument("--warmup", type=count("warm-up rounds", 0, MAX_WARMUP), default=1,
                        help=f"untimed rounds before timing, 0 to {MAX_WARMUP} (default 1)")
    parser.add_argument("--output", default=default_output("bench"), type=OUTPUT,
                        help="output directory (default: runs, which git ignores)")
    parser.add_argument("--threads", type=THREADS, default=None,
                        help="torch threads (default 1: the tensors are tiny, and on a busy "
                        "2-core machine 2 threads ran ours 15x slower than 1); with --device "
                        "also the numba backend's (default: all cores)")
    add_progress_arguments(parser)
    scale = parser.add_argument_group(
        "throughput mode (--device)",
        "ours-lm's numpy solver against its numba backend (the same loop compiled, when "
        "numba is installed) and its torch backend on a device, per batch size: "
        "trajectories/s, latency of the paper's seven (batch 7), speed-ups, loss agreement; "
        "writes OUTPUT/throughput.csv, throughput_runs.csv, throughput.json (device name, "
        "versions), throughput.md")
    scale.add_argument("--device", default=None, metavar="cpu|cuda|cuda:N",
                       help="time the torch backend on this device (and the numpy and numba "
                       "solvers on the CPU)")
    scale.add_argument("--no-numba", action="store_true",
                       help="leave the numba backend out (default: timed when installed)")
    scale.add_argument("--batches", default=None,
                       help="batch sizes; 7 is the paper's seven targets (default "
                       "7,1000,10000,100000)")
    scale.add_argument("--dtypes", default=None,
                       help="torch precisions to time (default float64,float32)")
    scale.add_argument("--numpy-max-batch", type=count("trajectories", 1, MAX_BATCH),
                       default=None,
                       help="largest batch the numpy solver is timed on (default 10000)")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ikbench.core.io import check_writable
    from ikbench.studies import bench as study

    if args.threads is not None:
        check_threads(args.threads)
    if args.device is not None:
        return run_throughput(args)
    for flag, given in (("--batches", args.batches), ("--dtypes", args.dtypes),
                        ("--numpy-max-batch", args.numpy_max_batch),
                        ("--no-numba", args.no_numba or None)):
        if given is not None:
            raise InputError(f"{flag} applies to the throughput mode only (give --device)")
    names = study.parse_methods(args.methods or DEFAULT_METHODS)
    counts = study.parse_repeat(args.repeat, names)
    robot = robot_from_args(args)
    spec = study.BenchSpec(tuple(names), counts, robot, targets_from_args(args, robot),
                           args.warmup, progress=not args.quiet)
    spec.validate()
    check_writable(Path(args.output) / "benchmark.csv")  # before the timed rounds
    begin(args, threads=args.threads or 1)
    result = study.run(spec)
    path = result.write(args.output)
    table = study.headline(result).drop(columns=["iterations", "line_distance_mean_mm",
                                           "pointing_deviation_mean_deg", "end_point_error_mm",
                                           "within_limits"], errors="ignore")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    base = result.record["methods"][0]
    for method, (low, t_low, high, t_high) in study.speedup_ranges(result.summary, base).items():
        print(f"per trajectory, {method} vs {base}: {low:.1f}x (trajectory {t_low}) to "
              f"{high:.1f}x (trajectory {t_high})")
    print(f"written to {path} (and benchmark.md, benchmark_runs.csv, benchmark.json)")
    return 0


def run_throughput(args: argparse.Namespace) -> int:
    """``ikbench bench --device DEV``: numpy solver vs numba and torch backends per batch."""
    from pathlib import Path

    from ikbench.core.io import check_writable
    from ikbench.methods.ours_lm.devices import check_device
    from ikbench.studies import throughput as study
    from ikbench.studies.bench import MAX_ROUNDS

    if args.methods is not None or args.only is not None:
        flag = "--methods" if args.methods is not None else "--only"
        raise InputError(f"{flag}: not with --device (the throughput mode times ours-lm on "
                         "batches; batch 7 is the paper's seven)")
    batches = study.parse_batches(args.batches or ",".join(map(str, study.DEFAULT_BATCHES)))
    dtypes = study.parse_dtypes(args.dtypes or ",".join(study.DEFAULT_DTYPES))
    try:
        repeat = 3 if args.repeat is None else int(args.repeat)
    except ValueError:
        repeat = 0
    if not 1 <= repeat <= MAX_ROUNDS:
        raise InputError(f"--repeat: {args.repeat!r} must be an integer from 1 to "
                         f"{MAX_ROUNDS} with --device")
    device = check_device(args.device)
    assert device is not None, "the throughput mode runs with --device"
    robot = robot_from_args(args)
    spec = study.ThroughputSpec(device, tuple(batches), tuple(dtypes), repeat, args.warmup,
                                args.numpy_max_batch or 10_000, args.steps, args.targets,
                                robot, not args.quiet, args.threads,
                                False if args.no_numba else None)
    spec.validate()
    check_writable(Path(args.output) / "throughput.csv")  # before the timed rounds
    begin(args, threads=args.threads or 1)
    result = study.run(spec)
    path = result.write(args.output)
    cols = ["backend", "dtype", "batch", "wall_median_s", "trajectories_per_s",
            "speedup_vs_numpy", "loss_max_rel_diff"]
    print(result.summary[cols].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"device: {result.record['device']} ({result.record['device_name']})")
    numba = result.summary[result.summary["backend"] == "numba"]
    if len(numba):
        print(f"numba {result.record['numba']} on up to {result.record['numba_threads']} "
              f"thread(s) ({result.record['numba_threads_rule']}); "
              f"largest relative loss difference from numpy: "
              f"{numba['loss_max_rel_diff'].max():.1e}")
    print(f"written to {path} (and throughput.md, throughput_runs.csv, throughput.json)")
    return 0
