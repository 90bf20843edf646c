"""``ikbench report DIR``: compare the methods run into DIR and check the paper's claims."""

from __future__ import annotations

import argparse

from ikbench.cli.options import begin
from ikbench.cli.values import PathValue
from ikbench.core.errors import OutputError

HELP = "compare the runs in DIR (ours vs each sequential-ik run); write DIR/report.md"


DESCRIPTION = (
    "Read every run folder that `ikbench run --output DIR [--name NAME]` wrote (the "
    "folder ours and at least one sequential-ik run, e.g. sequential-ik/, "
    "sequential-ik-pointing/, sequential-ik-position/; same targets and n; the folders "
    "ablation/, sweep/, batch/ and letters/ of other commands are skipped), recompute "
    "all figures from the trajectory CSVs, and write DIR/report.md (all runs side by "
    "side per trajectory; the paper's claims about its baseline checked with numbers "
    "once per sequential-ik / ikpy run, labelled with its --orientation mode and the task "
    "it solved (walk: touch pose only; track: the paper's task); the modes in one "
    "table; Table 2 beside the paper's, from the frame-mode run) and "
    "DIR/pointing_deviation_per_step.png.")


def arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dir", metavar="DIR", type=PathValue("a folder of runs",
                                                             must_exist="dir"),
                        help="the --output directory of the runs (e.g. results)")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ikbench.core.io import check_writable
    from ikbench.paper.comparison import write_comparison_report

    try:
        check_writable(Path(args.dir) / "report.md")  # before reading every run
    except OutputError as exc:
        raise OutputError(f"dir: {exc}") from None
    begin(args)
    path = write_comparison_report(args.dir)
    print(f"written {path}")
    return 0
