"""``ikbench report DIR``: compare the methods run into DIR and check the paper's claims."""

from __future__ import annotations


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "report",
        help="compare the methods run into DIR (ours vs sequential-ik); write DIR/report.md",
        description=(
            "Read every method folder that `ikbench run --output DIR` wrote (at least ours and "
            "sequential-ik, same targets and n), recompute all figures from the trajectory CSVs, "
            "and write DIR/report.md (methods side by side per trajectory, the paper's claims "
            "about its baseline checked with numbers, Table 2 beside the paper's) and "
            "DIR/pointing_deviation_per_step.png."
        ),
    )
    parser.add_argument("dir", metavar="DIR",
                        help="the --output directory of the runs (e.g. results)")
    parser.set_defaults(func=run)


def run(args) -> int:
    from ikbench.compare import write_comparison_report

    path = write_comparison_report(args.dir)
    print(f"written {path}")
    return 0
