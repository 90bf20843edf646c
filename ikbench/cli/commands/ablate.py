"""``ikbench ablate``: what each loss term contributes (the paper's ablation study)."""

from __future__ import annotations

import argparse

from ikbench.cli.options import (
    add_line_task_arguments,
    add_method_options,
    add_threads_and_quiet,
    begin,
    check_threads,
    method_from_args,
    robot_from_args,
    targets_from_args,
)
from ikbench.cli.values import OUTPUT
from ikbench.core.defaults import DEFAULT_METHOD
from ikbench.studies.folders import default_output

HELP = ("loss-term ablation: run a method with terms of L0..L6 dropped, compare with "
        "the full loss")


DESCRIPTION = (
    "Run a method with the full loss and with the weights of some loss terms set to "
    "zero (everything else as in the paper, stopping rule included) on the same "
    "targets. Writes OUTPUT/ablation/: <variant>/trajectory_<id>.csv, table.csv (one "
    "row per variant and trajectory: the Table 1 metrics, smoothness, distance from "
    "the joint-space interpolation, whether the iteration cap was hit), summary.csv, "
    "run.json, metrics.png, trajectories_3d.png, joints.png and report.md, which "
    "checks the paper's claims about the terms. Terms: L0 line points, L1 pointing, "
    "L2 start pose, L3 end pose, L4 start point, L5 end point, L6 smoothness. The "
    "output folder is checked before any solve; trajectory CSVs and variant folders "
    "of an earlier ablation there that this run does not write are removed.")


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.studies.ablation import weighted_methods

    methods = weighted_methods()
    parser.add_argument(
        "--drop", action="append", default=None, metavar="TERMS",
        help="terms to drop together, e.g. L1 or L2,L3,L4,L5; 'each' (its own --drop value, "
        "not in a list) runs every single-term ablation; repeat for more variants (--drop "
        "each --drop L2,L3,L4,L5). The full loss always runs too (default: each)")
    parser.add_argument("--method", default=DEFAULT_METHOD,
                        help=f"a method with loss weights: {', '.join(methods)} (default: "
                        f"{DEFAULT_METHOD})")
    add_line_task_arguments(parser)
    parser.add_argument("--output", default=default_output("ablation"), type=OUTPUT,
                        help="results directory; writes OUTPUT/ablation/ (default: runs, which "
                        "git ignores; ikbench reproduce writes results/ablation/)")
    parser.add_argument("--figure-trajectory", default=None, metavar="ID",
                        help="trajectory drawn per variant in the figures (default: the first)")
    add_threads_and_quiet(parser)
    add_method_options(parser, methods)


def run(args: argparse.Namespace) -> int:
    from dataclasses import asdict
    from pathlib import Path

    from ikbench.core.io import check_folder_writable
    from ikbench.core.losses import parse_weights
    from ikbench.studies import ablation as study

    check_threads(args.threads)
    variants = study.parse_drops(args.drop or ["each"])  # bad term names fail before set-up
    cls = study.check_method(args.method)
    solver = method_from_args(args, cls, study.weighted_methods())  # validates every option
    options = {k: v for k, v in asdict(solver.settings).items() if k != "weights"}
    robot = robot_from_args(args)
    weights = solver.settings.weights
    spec = study.AblationSpec(
        tuple(variants), args.method, robot, targets_from_args(args, robot), options,
        dict(weights) if isinstance(weights, dict) else parse_weights(weights),
        args.figure_trajectory, progress=not args.quiet)
    spec.validate()
    folder = Path(args.output) / study.FOLDER
    check_folder_writable(folder)
    begin(args, threads=args.threads)
    result = study.run(spec)
    result.write(args.output)
    columns = ["variant", "trajectory", "iterations", "hit_cap", "line_distance_mean_mm",
               "pointing_deviation_mean_deg", "velocity_sign_changes",
               "joint_interpolation_distance_deg"]
    print(result.table[columns].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"written to {args.output}/ablation/ (report.md checks the paper's claims)")
    return 0
