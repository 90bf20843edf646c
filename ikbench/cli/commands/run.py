"""``ikbench run``: generate trajectories with a method and write tables, figures, report."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from ikbench.cli.options import (
    add_method_options,
    add_robot_arguments,
    add_threads_and_quiet,
    begin,
    check_threads,
    method_from_args,
    robot_from_args,
)
from ikbench.cli.values import INPUT_FILE, OUTPUT, STEPS, Number, Text, duration_s
from ikbench.core.defaults import DEFAULT_DURATION_S, DEFAULT_METHOD, DEFAULT_ROBOT
from ikbench.studies.folders import default_output

if TYPE_CHECKING:
    from pathlib import Path

    import pandas as pd

    from ikbench.methods.base import Method
    from ikbench.studies.run import RunSpec

HELP = "generate trajectories with a method; write CSVs, table, figures and report"
LINE_COLUMNS = ["trajectory", "iterations", "duration_s", "loss", "line_distance_mean_mm",
                "pointing_deviation_mean_deg", "end_point_error_mm"]
SHAPE_COLUMNS = ["trajectory", "iterations", "duration_s", "loss", "curve_distance_mean_mm",
                 "curve_distance_max_mm", "point_error_mean_mm", "pointing_deviation_mean_deg",
                 "stroke_coverage_pct", "drawn"]
PROBLEM_COLUMNS = ["trajectory", "iterations", "duration_s", "loss", "position_error_max_mm",
                   "rotation_error_max_deg", "max_joint_change_deg", "valid"]
DEFAULT_OUTPUT = default_output("run")
#: The console table's name of duration_s when it is a share of one batched solve.
BATCH_SHARE_COLUMN = "duration_s (batch share)"
#: A letter's height.
LETTER_SIZE_MM = Number("a letter height [mm]", 1.0, 10_000.0)


def description() -> str:
    """The paragraph of ``ikbench run --help`` (it names the methods available)."""
    from ikbench.methods.registry import available_methods

    methods = available_methods()
    return (
        "Generate one trajectory per touch pose (or per letter, or one along a polyline or "
        "spline) with a method and write, under OUTPUT/NAME/ (NAME: --name, default the "
        "method's name), trajectory_<id>.csv (poses in the robot's units), table.csv "
        "(line distance [mm], pointing deviation [deg], start/end errors; for other shapes "
        "the distance from the target curve), details.csv, run.json (robot, settings, "
        "versions), figures, animation.gif (the arm playing each trajectory; "
        "--no-animation skips it) and report.md. The folder is replaced whole: files an "
        "earlier run wrote there and this one does not are removed, other files are kept. A "
        "failed solve is reported as a row (exit code 1); Ctrl-C keeps the trajectories "
        "solved so far. Methods: " + ", ".join(methods) + " (ikbench methods lists them "
        "all, with those not installed; ikbench methods NAME gives one's options).")


#: The paragraph of --help.
DESCRIPTION = description


def arguments(parser: argparse.ArgumentParser) -> None:
    from ikbench.methods.registry import available_methods

    methods = available_methods()
    add_method_and_output(parser, methods, DEFAULT_OUTPUT)
    parser.add_argument("--name", default=None, type=Text("a run name", max_chars=200),
                        help="folder under OUTPUT for this run (default: the method's name), "
                        "e.g. sequential-ik-position; letters, digits, '_', '-', '.'")
    parser.add_argument("--problem", default=None, metavar="FILE.yaml|NAME",
                        help="a Cartesian path problem in CppFlow's format instead of targets "
                        "and shapes: a YAML file (robot, path_name, path_offset_frame, "
                        "path_xyz_offset, path_R_offset; path_name.csv next to it or shipped) "
                        "or a shipped one (fetch_arm__hello, ...); writes "
                        "trajectory_<problem>.csv with the end frame's quaternion, and a table "
                        "of pose errors, joint changes, path lengths and CppFlow's validity")
    add_task_arguments(parser, only_help="comma-separated trajectory ids, e.g. 1,3",
                       start_pose_default="the targets file's")
    parser.add_argument("--goals", default=None, metavar="FILE", type=INPUT_FILE,
                        help="line shape: goal set of the legibility figures in details.csv "
                        "and report.md, a targets file whose touch poses' fingertip points "
                        "are the goals (default: every touch point of --targets; "
                        "docs/legibility.md)")
    parser.add_argument("--init-model", default=None, metavar="MODEL", type=INPUT_FILE,
                        help="a trajectory model of ikbench learn --kind trajectory: the "
                        "method (one with warm starts: ours-lm, ours-exact) starts each line "
                        "from the model's predicted trajectory instead of its usual start; "
                        "the run folder is <method>-learned (docs/learned.md)")
    add_solve_arguments(parser, methods)


def add_task_arguments(parser: argparse.ArgumentParser, only_help: str,
                       start_pose_default: str) -> None:
    """--robot, --end-frame, --targets, --only, --shape, --size, --direction, --start-pose,
    --steps (run, sweep)."""
    add_robot_arguments(parser)
    parser.add_argument("--targets", default=None,
                        help="targets JSON file (default: the robot's own; NICO: the paper's "
                        "seven touch poses)")
    parser.add_argument("--only", default=None, help=only_help)
    parser.add_argument("--shape", default="line",
                        help="line (default: one per touch pose), polyline:FILE or spline:FILE "
                        "(CSV of x,y,z control points [mm], base frame), or letter:X[,Y...] "
                        "(letters A-Z, lower case drawn as upper case, on the robot's letter "
                        "plane through the end point at the start pose, one trajectory each)")
    add_size_and_direction(parser, "tangent (default for line, polyline, spline), normal (of "
                           "the drawing plane; default for letters) or a vector x,y,z")
    add_start_pose_argument(parser, start_pose_default)
    parser.add_argument("--steps", type=STEPS, default=None,
                        help="number of segments n, 2..5000 (default: the targets file's, 50, "
                        "for lines; 100 for other shapes)")


def add_size_and_direction(parser: argparse.ArgumentParser, directions: str) -> None:
    """--size and --direction (run, letters); ``directions``: the directions allowed and
    their default, in words for the help."""
    parser.add_argument("--size", type=LETTER_SIZE_MM, default=None,
                        help="letter height [mm] (default 300)")
    parser.add_argument("--direction", default=None,
                        help=f"goal pointing directions: {directions}")


def add_start_pose_argument(parser: argparse.ArgumentParser, default: str) -> None:
    parser.add_argument("--start-pose", default=None,
                        help=f"start pose, comma-separated values in the robot's units "
                        f"(default: {default}); write --start-pose=-24,... for a leading minus")


def add_method_and_output(parser: argparse.ArgumentParser, methods: dict, default_output: str,
                          folder: str = "<method> (or --name)") -> None:
    """--method and --output, the first options of ``run`` and ``letters``; ``folder``: the
    run folder's name under OUTPUT, in words for the help."""
    parser.add_argument("--method", default=DEFAULT_METHOD,
                        help=f"one of: {', '.join(methods)} (default: {DEFAULT_METHOD})")
    parser.add_argument("--output", default=default_output, type=OUTPUT,
                        help=f"directory of the run folder: writes OUTPUT/{folder}/ (default: "
                        f"{default_output}, which git ignores, so {default_output}/<method>/; "
                        "ikbench reproduce writes results/)")


def add_solve_arguments(parser: argparse.ArgumentParser, methods: dict) -> None:
    """--duration, --no-animation, --timing, --threads, progress options and every method's
    own options (shown by --help-methods; shared with ``letters``)."""
    parser.add_argument("--duration", type=duration_s(), default=DEFAULT_DURATION_S,
                        help="movement duration T [s] for the time_s column, 0.001 to 3600 "
                        f"(default {DEFAULT_DURATION_S:g})")
    parser.add_argument("--no-animation", action="store_true",
                        help="do not write animation.gif (the arm playing each trajectory; "
                        "1-3 s for seven trajectories)")
    parser.add_argument("--timing", default="constant", metavar="NAME",
                        help="timing of animation.gif: constant (the paper's T/n segments), "
                        "min-jerk or topp (time-optimal within the robot's limits); the "
                        "trajectory files keep their poses (default constant; docs/timing.md)")
    add_threads_and_quiet(parser)
    add_method_options(parser, methods)


def _seconds(value: float) -> str:
    """A time [s] in 3 significant digits (0.000312, not 0.000)."""
    return f"{value:.3g}"


def lowercase_letters_note(shape: str) -> str | None:
    """A note when a letter shape names lower-case letters (they are drawn upper case)."""
    kind, _, arg = str(shape).partition(":")
    if kind.strip().lower() == "letter" and any(c.islower() for c in arg):
        return f"note: {shape}: letters are drawn upper case ({arg.upper()})"
    return None


def run(args: argparse.Namespace, shape: str | None = None, fixed: dict | None = None) -> int:
    """Parse the arguments into a :class:`ikbench.studies.run.RunSpec`, validate it, then
    solve, write and print; ``fixed``: method settings on top."""
    import sys

    from ikbench.core.targets import load_targets, parse_pose
    from ikbench.studies.run import RunSpec

    check_threads(args.threads)
    if getattr(args, "problem", None) is not None:
        return run_problem(args, fixed)
    robot = robot_from_args(args)
    start_pose = None if args.start_pose is None else parse_pose(args.start_pose, robot,
                                                                 "--start-pose")
    shape = shape or args.shape
    solver = _solver(args, fixed)
    if getattr(args, "init_model", None) is not None:
        solver = _learned_start(solver, args.init_model, shape)
    # the goal set: --goals, else every id of the targets (not --only's)
    goals = load_targets(getattr(args, "goals", None) or args.targets, robot) \
        if shape == "line" else None
    spec = RunSpec(solver, robot=robot, targets=args.targets, only=getattr(args, "only", None),
                   steps=args.steps, output=args.output, duration_s=args.duration,
                   progress=not args.quiet, shape=shape, size_mm=args.size,
                   start_pose=start_pose, direction=args.direction,
                   name=getattr(args, "name", None), animation=not args.no_animation,
                   timing=args.timing, goals=goals)
    spec.validate()
    note = lowercase_letters_note(shape)
    if note:
        print(note, file=sys.stderr)
    begin(args, threads=args.threads)
    if shape != "line" and getattr(args, "goals", None) is not None:  # letters has no --goals
        from ikbench.core.errors import InputError

        raise InputError("--goals applies to the line shape only (the touch poses' goals)")
    return solve_write_report(spec)


def _solver(args: argparse.Namespace, fixed: dict | None) -> Method:
    """The method of --method configured by its options and ``fixed``."""
    from ikbench.methods.registry import available_methods, get_method

    return method_from_args(args, get_method(args.method), available_methods(),
                            **(fixed or {}))


def _learned_start(solver: Method, model: str, shape: str) -> Method:
    """``solver`` refining the trajectory model's start (:class:`LearnedStart`); the query
    runs on --threads torch threads (default 1: a second costs its wake-up on a loaded
    machine)."""
    from ikbench.core.errors import InputError
    from ikbench.learned.starts import LearnedStart

    if shape != "line":
        raise InputError(f"--init-model: the trajectory model learned lines; --shape {shape} "
                         "is not one")
    return LearnedStart(solver, model)


def solve_write_report(spec: RunSpec) -> int:
    """Solve, write the run folder and print its table; 130 after Ctrl-C."""
    import sys

    from ikbench.runtime.harness import Interrupted
    from ikbench.studies.run import INTERRUPTED_SUFFIX, run_and_write_spec

    folder = spec.folder
    assert folder is not None  # the CLI always writes
    earlier = folder.with_name(folder.name + INTERRUPTED_SUFFIX).is_dir()
    try:
        table = run_and_write_spec(spec).table
    except Interrupted as stop:
        if stop.outcomes:
            replaced = " (replacing an earlier interrupted run's)" if earlier else ""
            print(f"ikbench: interrupted: {folder}/ is unchanged; the {len(stop.outcomes)} "
                  f"trajectories solved before Ctrl-C are in {stop.written}/{replaced}",
                  file=sys.stderr)
        else:
            print(f"ikbench: interrupted before any trajectory was solved; {folder}/ is "
                  "unchanged", file=sys.stderr)
        return 130
    solver, _, _, tasks, _ = spec.prepared
    return report_table(table, folder, batch=len(tasks) if solver.capabilities.batched else None)


def run_problem(args: argparse.Namespace, fixed: dict | None = None) -> int:
    """``run --problem``: validate, solve the problem's pose path, write, print the table."""
    from ikbench.studies.run import RunSpec, check_problem_options

    spec = RunSpec(_solver(args, fixed), robot=None if args.robot == DEFAULT_ROBOT
                   else args.robot, targets=args.targets, only=args.only, steps=args.steps,
                   output=args.output, duration_s=args.duration, progress=not args.quiet,
                   shape=args.shape, size_mm=args.size, start_pose=args.start_pose,
                   direction=args.direction, name=getattr(args, "name", None),
                   animation=not args.no_animation, problem=args.problem, timing=args.timing)
    spec.validate()
    check_problem_options(end_frame=args.end_frame)  # not a RunSpec field
    begin(args, threads=args.threads)
    return solve_write_report(spec)


def report_table(table: pd.DataFrame, folder: Path, batch: int | None = None) -> int:
    """Print a run's table and where it went; exit code 1 when a solve failed. ``batch``: the
    trajectories a batched method solved in one call (their times are shares of it)."""
    import sys

    from ikbench.runtime.progress import loss_text

    columns = (PROBLEM_COLUMNS if "position_error_max_mm" in table else
               LINE_COLUMNS if "line_distance_mean_mm" in table else SHAPE_COLUMNS)
    shown = table[columns].assign(loss=[loss_text(v, 3) for v in table["loss"]])
    if batch and batch > 1:
        shown = shown.rename(columns={"duration_s": BATCH_SHARE_COLUMN})
    print(shown.to_string(index=False, float_format=lambda v: f"{v:.3f}",
                          formatters={"duration_s": _seconds, BATCH_SHARE_COLUMN: _seconds}))
    if batch and batch > 1:
        print(f"{BATCH_SHARE_COLUMN}: the {batch} trajectories were solved in one batched call "
              f"of {table['duration_s'].sum():.3g} s; each row shows its equal share")
    print(f"written to {folder}/")
    failed = table["trajectory"][table[columns[4]].isna()].tolist()
    if "drawn" in table:  # a shape is judged by what the fingertip drew, not by convergence
        from ikbench.core.metrics import DRAWN_COVERAGE_MIN_PCT, DRAWN_TOLERANCE_MM

        missed = table["trajectory"][~table["drawn"].astype(bool)
                                     & table[columns[4]].notna()].tolist()
        if missed:
            print(f"ikbench: {len(missed)} of {len(table)} shapes not drawn "
                  f"({', '.join(map(str, missed))}): drawn needs every pen-down point within "
                  f"{DRAWN_TOLERANCE_MM:g} mm of the shape and {DRAWN_COVERAGE_MIN_PCT:g} % of "
                  "its strokes covered", file=sys.stderr)
    if failed:
        print(f"ikbench: {len(failed)} of {len(table)} solves failed ({', '.join(failed)}); "
              f"details.csv gives each failure", file=sys.stderr)
        return 1
    return 0
