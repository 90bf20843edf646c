"""``ikbench reproduce``: regenerate everything the paper reports into one folder."""

from __future__ import annotations

import argparse
from pathlib import Path

from ikbench.cli.options import add_threads_and_quiet, begin, check_threads
from ikbench.cli.values import OUTPUT
from ikbench.core.errors import InputError

HELP = ("regenerate Tables 1 and 2, the comparison, the ablation, all figures and "
        "results/README.md")


DESCRIPTION = (
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
    "takes a few minutes on 2 cores.")


def arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--output", default=None, type=OUTPUT,
                        help="results directory (default: results; results-quick with "
                        "--quick)")
    parser.add_argument("--quick", action="store_true",
                        help="pipeline check on a reduced configuration: trajectory 1, n = 10, "
                        "at most 100 iterations (seconds, not the paper's numbers)")
    every = parser.add_argument_group(
        "every results folder (--all)",
        "Regenerate every committed results folder, one study per process, from a clean "
        "commit: the plan (each study, its command, its expected time) is printed first; a "
        "study already made at this commit is skipped (resumable); README.md's and docs/'s "
        "generated blocks are rendered again at the end. See docs/results-at-a-glance.md.")
    every.add_argument("--all", action="store_true",
                       help="run every study of the plan (the paper's reproduction is one)")
    every.add_argument("--only", default=None, metavar="STUDY[,STUDY...]",
                       help="with --all: only these studies (--plan lists them)")
    every.add_argument("--plan", action="store_true",
                       help="print the plan and what would be skipped; run nothing")
    every.add_argument("--force", action="store_true",
                       help="with --all: run studies already made at this commit again")
    every.add_argument("--allow-dirty", action="store_true",
                       help="with --all: run from a tree with modified code (recorded; the "
                       "committed results must come from a clean tree)")
    every.add_argument("--jobs", type=int, default=1, metavar="N",
                       help="with --all: run N studies at once (default 1: one at a time, "
                       "each timing alone on the machine; 2 on 2 cores roughly halves the "
                       "wall time, each study's timings then made beside another's, which "
                       "the record states with its load); never two that write into the "
                       "same folder, and the per-call timing tables (alone in --plan) with "
                       "nothing beside them")
    every.add_argument("--docs", action="store_true",
                       help="only render README.md's and docs/'s generated blocks again from "
                       "results/ (no solving)")
    add_threads_and_quiet(parser)


def run(args: argparse.Namespace) -> int:
    from ikbench.paper.reproduce import check_output, reproduce

    if args.docs:
        begin(args)
        return render_docs()
    if args.all or args.plan:
        return run_all(args)
    if args.only or args.force or args.allow_dirty or args.jobs != 1:
        raise InputError("--only, --force, --allow-dirty and --jobs go with --all (or --plan)")

    check_threads(args.threads)
    check_output(args.output, args.quick)
    begin(args, threads=args.threads)
    times = reproduce(args.output, quick=args.quick, progress=not args.quiet)
    width = max(map(len, times))
    for stage, seconds in times.items():
        print(f"{stage:<{width}} {seconds:8.1f} s")
    return 0


def run_all(args: argparse.Namespace) -> int:
    """``reproduce --all`` / ``--plan``: the regeneration plan
    (:mod:`ikbench.studies.regeneration`)."""
    from ikbench.studies.regeneration import RegenerationSpec, run

    only = tuple(s.strip() for s in args.only.split(",") if s.strip()) if args.only else ()
    spec = RegenerationSpec(Path(args.output or "results"), only, args.force, args.allow_dirty,
                            args.plan, args.jobs)
    spec.validate()  # an unknown study or a bad entry is refused before anything runs
    begin(args)
    times = run(spec).wall_s
    for study, seconds in times.items():
        print(f"{study:<16} {seconds / 60:6.1f} min")
    return 0


def render_docs() -> int:
    """``reproduce --docs``: render every generated block of README.md and docs/ again."""
    from ikbench.core.provenance import REPO
    from ikbench.render.blocks import documents, render_files

    changed = render_files(documents(REPO), REPO)
    print("rendered: " + (", ".join(str(p.relative_to(REPO)) for p in changed) or "nothing "
                          "changed"))
    return 0
