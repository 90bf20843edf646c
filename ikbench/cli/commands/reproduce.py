"""``ikbench reproduce``: regenerate everything the paper reports into one folder."""

from __future__ import annotations

import argparse

from ikbench.cli.commands import Subparsers
from ikbench.cli.values import OUTPUT

HELP = ("regenerate Tables 1 and 2, the comparison, the ablation, all figures and "
        "results/README.md")


def register(subparsers: Subparsers) -> None:
    from ikbench.cli.options import add_threads_and_quiet

    parser = subparsers.add_parser(
        "reproduce", help=HELP,
        description=(
            "Run the paper's method (Table 1: OUTPUT/ours/) and the authors' baseline, the "
            "walk from the touch pose (sequential-ik-walk; Table 2, --orientation frame: "
            "OUTPUT/sequential-ik/; also --orientation pointing "
            "and position: OUTPUT/sequential-ik-pointing/, OUTPUT/sequential-ik-position/) on "
            "the paper's targets, ours with --init interpolation (OUTPUT/"
            "ours-init-interpolation/), write the comparison report (OUTPUT/report.md) and the "
            "loss-term ablation (OUTPUT/ablation/: every single term, and L2..L5 together), "
            "and write OUTPUT/README.md: each paper table beside the measured one, the "
            "baseline's three modes, the figures, the deviations from the paper, and the "
            "versions and machine used. The output folder is checked before any solving. "
            "Progress goes to stderr; the total time is printed at the end. The full run "
            "takes a few minutes on 2 cores."
        ),
    )
    parser.add_argument("--output", default=None, type=OUTPUT,
                        help="results directory (default: results; results-quick with "
                        "--quick)")
    parser.add_argument("--quick", action="store_true",
                        help="pipeline check on a reduced configuration: trajectory 1, n = 10, "
                        "at most 100 iterations (seconds, not the paper's numbers)")
    add_threads_and_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ikbench.cli.options import begin, check_threads, set_threads
    from ikbench.paper.reproduce import check_output, reproduce

    check_threads(args.threads)
    check_output(args.output, args.quick)
    set_threads(args.threads)
    begin(args)
    times = reproduce(args.output, quick=args.quick, progress=not args.quiet)
    width = max(map(len, times))
    for stage, seconds in times.items():
        print(f"{stage:<{width}} {seconds:8.1f} s")
    return 0
