"""``ikbench cartesian``: the CppFlow/TORM Cartesian path benchmark."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import TYPE_CHECKING

from ikbench.cli.options import (
    _convert,
    _given,
    add_method_options,
    add_progress_arguments,
    begin,
    check_threads,
)
from ikbench.cli.values import OUTPUT, THREADS
from ikbench.core.errors import InputError
from ikbench.studies.folders import default_output

if TYPE_CHECKING:
    from ikbench.studies.cartesian import CartesianSpec

HELP = "Cartesian path benchmark: methods on the CppFlow/TORM 6-D pose paths, several seeds"
DEFAULT_OUTPUT = default_output("cartesian")


def description() -> str:
    """The paragraph of ``ikbench cartesian --help`` (it names the problems and methods)."""
    from ikbench.core.problems import BENCHMARK, SHIPPED, shipped_problems
    from ikbench.studies.cartesian import frame_methods

    methods = frame_methods()
    return (
        "Solve Cartesian path problems (6-D pose paths in CppFlow's format: CppFlow's 13 "
        f"benchmark problems ({BENCHMARK}), every shipped one ({SHIPPED}: "
        f"{', '.join(shipped_problems())}), or your own YAML files, obstacles included) "
        "with every method that follows goal frames "
        f"({', '.join(methods)}), once per seed, and write OUTPUT/cartesian/: table.csv "
        "(one row per problem x method x seed: pose errors, joint changes, path lengths, "
        "CppFlow's validity, time to a valid solution), summary.csv, published.csv "
        "(CppFlow's and TORM's published figures with their sources, 'not found' where "
        "none was found), the trajectories, a figure per problem, report.md and run.json. "
        "Method options below apply to the methods that have them.")


#: The paragraph of --help.
DESCRIPTION = description


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.core.problems import BENCHMARK, SHIPPED
    from ikbench.studies.cartesian import DEFAULT_SEEDS, frame_methods

    methods = frame_methods()
    parser.add_argument("--problems", action="append", default=None,
                        metavar=f"{BENCHMARK}|{SHIPPED}|NAME,...|FILE.yaml",
                        help=f"{BENCHMARK} (default: CppFlow's 13 benchmark problems), "
                        f"{SHIPPED} (every shipped problem), problem names or YAML files, "
                        "comma-separated; may be repeated")
    parser.add_argument("--methods", default=None,
                        help=f"comma-separated methods (default: {', '.join(methods)})")
    parser.add_argument("--seeds", default=",".join(map(str, DEFAULT_SEEDS)),
                        help="seeds, comma-separated or as ranges (1-5), one solve per "
                        f"method and seed (default {','.join(map(str, DEFAULT_SEEDS))})")
    parser.add_argument("--output", default=DEFAULT_OUTPUT, type=OUTPUT,
                        help=f"output directory; the study writes OUTPUT/cartesian/ (default "
                        f"{DEFAULT_OUTPUT})")
    parser.add_argument("--trajectories", choices=["first", "all"], default="first",
                        help="trajectory CSVs to write: the first seed's (default) or every "
                        "seed's (a 553-waypoint path is about 100 kB)")
    parser.add_argument("--first-call", action="store_true",
                        help="after the solves, time each method's first call in a fresh "
                        "process (import, set-up, the first problem solved once with the "
                        "first seed): summary.csv's first_call_s column")
    parser.add_argument("--threads", type=THREADS, default=1, help="torch threads (default 1)")
    add_progress_arguments(parser)
    add_method_options(parser, methods)


def method_settings(args: argparse.Namespace, names: list[str]) -> dict[str, dict]:
    """method -> settings from the method options given (each applies to the methods that
    have it); InputError for an option none of them has, and for --seed, --lm-seed (use --seeds)."""
    from ikbench.methods.registry import get_method

    given = _given(args)
    for flag in ("seed", "lm-seed"):
        if flag in given:
            raise InputError(f"--{flag}: the benchmark runs every seed of --seeds; give --seeds")
    out: dict[str, dict] = {name: {} for name in names}
    used = set()
    for name in names:
        for opt in get_method(name).options():
            if opt.flag in given:
                out[name][opt.field] = _convert(opt, given[opt.flag])
                used.add(opt.flag)
    unused = [flag for flag in given if flag not in used]
    if unused:
        raise InputError(f"--{unused[0]} is not an option of the methods chosen "
                         f"({', '.join(names)})")
    return out


def command_line(problems: str, methods: str | None, seeds: Sequence[int], output: str,
                 trajectories: str = "first", first_call: bool = False,
                 given: dict[str, object] | None = None) -> str:
    """The command as given (options in a fixed order), for the report; ``given``: the method
    options given (flag -> value)."""
    import shlex

    words = ["ikbench", "cartesian", "--problems", problems]
    if methods:
        words += ["--methods", methods]
    words += ["--seeds", ",".join(map(str, seeds)), "--output", output]
    if trajectories != "first":
        words += ["--trajectories", trajectories]
    if first_call:
        words += ["--first-call"]
    for flag, value in (given or {}).items():
        words += [f"--{flag}", str(value)]
    return " ".join(shlex.quote(w) for w in words)


def run(args: argparse.Namespace) -> int:
    from ikbench.core.problems import BENCHMARK

    problems = ",".join(args.problems) if args.problems else BENCHMARK
    return run_spec(spec_of(args, problems, args.methods, args.seeds, args.trajectories,
                            method_options=True), args)


def spec_of(args: argparse.Namespace, problems: str, methods: str | None, seeds: str,
            trajectories: str = "first", method_options: bool = False) -> CartesianSpec:
    """The benchmark's spec from the problems, methods and seeds given (``args``: threads,
    output, quiet, first call; with ``method_options``, ``ikbench cartesian``'s method
    options, else every method with its defaults): ``ikbench cartesian``'s and ``ikbench
    compare --problems``'."""
    from ikbench.core.problems import resolve_problems
    from ikbench.studies import cartesian as study

    check_threads(args.threads)
    files = resolve_problems(problems)
    names = study.parse_methods(methods)
    seed_list = study.parse_seeds(seeds)
    settings = method_settings(args, names) if method_options else {n: {} for n in names}
    given = _given(args) if method_options else {}
    return study.CartesianSpec(tuple(files), tuple(names), seed_list, settings,
                               progress=not args.quiet, first_call=args.first_call,
                               command=command_line(problems, methods, seed_list, args.output,
                                                    trajectories, args.first_call, given),
                               trajectories=trajectories)


def run_spec(spec: CartesianSpec, args: argparse.Namespace) -> int:
    """Validate, run and write ``spec`` into ``args.output``, then print its summary: the
    one path of ``ikbench cartesian`` and ``ikbench compare --problems``. Exit code 1 when a
    solve failed."""
    import sys
    from pathlib import Path

    from ikbench.core.io import check_folder_writable
    from ikbench.studies import cartesian as study

    spec.validate()  # each method's settings checked before anything runs
    folder = Path(args.output) / study.FOLDER
    check_folder_writable(folder)
    begin(args, threads=args.threads)
    result = study.run(spec)
    result.write(args.output)
    from ikbench.render.cartesian_report import summarise

    summary = summarise(result.table, result.first_calls)
    first = ["first_call_s"] if "first_call_s" in summary else []
    print(summary[["problem", "method", "valid_runs", "runs", "time_to_valid_median_s",
                   "duration_median_s", *first, "position_error_max_mm", "rotation_error_max_deg",
                   "max_joint_change_deg", "joint_path_length_median_rad",
                   "joint_path_length_over_torm"]].rename(
                       columns={"joint_path_length_over_torm": "length_over_torm_published"})
          .to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"written to {folder}/")
    failed = result.table[result.table["failure"].fillna("") != ""]
    if len(failed):
        print(f"ikbench: {len(failed)} solves failed; table.csv gives each failure",
              file=sys.stderr)
        return 1
    return 0
