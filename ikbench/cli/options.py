"""Options shared by the subcommands: ``--robot``, the methods' generated options, checks.

Method options are generated from each method's settings dataclass
(:func:`ikbench.methods.options.option`); an option name shared by several methods is added
once, its help naming each method. Values are checked by the settings themselves when the
chosen method is built (:func:`method_from_args`), so bad input fails before any solve.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any, TypeVar

from ikbench.cli.values import METHOD_INTEGER, OUTPUT, SEED, STEPS, THREADS, Text
from ikbench.core.defaults import DEFAULT_ROBOT
from ikbench.core.errors import InputError

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.targets import Targets
    from ikbench.methods.base import Method
    from ikbench.runtime.executors import Executor

#: A method class's own type (method_from_args returns an instance of the class it gets).
M = TypeVar("M", bound="Method")



def add_robot_arguments(parser: argparse.ArgumentParser) -> None:
    """``--robot NAME|PATH`` and ``--end-frame LINK``."""
    parser.add_argument("--robot", default=DEFAULT_ROBOT, metavar="NAME|PATH",
                        type=Text("a robot name or a config or URDF path"),
                        help="a shipped robot (ikbench robots lists them), a robot config "
                        "(*.toml) or a URDF with --end-frame; poses are in its units (motor "
                        f"degrees for NICO, else joint degrees, mm for prismatic joints) "
                        f"(default {DEFAULT_ROBOT})")
    parser.add_argument("--end-frame", default=None, metavar="LINK",
                        help="end link of the chain (required with a URDF; the chain runs from "
                        "its root to this link, whose --pointing-axis points)")
    parser.add_argument("--pointing-axis", default=None,
                        choices=("x", "y", "z", "-x", "-y", "-z"),
                        help="the end frame's axis that points, judged for pointing (default: "
                        "the robot config's, else z; ikbench robot init proposes one)")


def robot_from_args(args: argparse.Namespace) -> Robot:
    """The robot of ``--robot`` / ``--end-frame`` / ``--pointing-axis`` (validated; no heavy
    imports)."""
    from dataclasses import replace

    import numpy as np

    from ikbench.core.robot import load_robot
    from ikbench.core.robot_init import pointing_axis

    robot = load_robot(args.robot, args.end_frame)
    axis = getattr(args, "pointing_axis", None)
    if axis is None:
        return robot
    return replace(robot, pointing_axis=np.asarray(pointing_axis(axis), dtype=float))


def add_line_task_arguments(parser: argparse.ArgumentParser) -> None:
    """--robot, --end-frame, --targets, --only and --steps (the touch-pose line tasks)."""
    add_robot_arguments(parser)
    parser.add_argument("--targets", default=None,
                        help="targets JSON file (default: the robot's own; NICO: the paper's "
                        "seven touch poses)")
    parser.add_argument("--only", default=None, help="comma-separated trajectory ids, e.g. 1,3")
    parser.add_argument("--steps", type=STEPS, default=None,
                        help="number of segments n, 2..5000 (default: the targets file's; 50 "
                        "for NICO's)")


def targets_from_args(args: argparse.Namespace, robot: Robot) -> Targets:
    """The targets of --targets/--only/--steps for ``robot`` (validated)."""
    from ikbench.core.targets import select_targets

    return select_targets(args.targets, robot, args.only, args.steps)


def add_method_options(parser: argparse.ArgumentParser, methods: dict[str, Any]) -> None:
    """One argument group with every option of ``methods`` (shared names merged).

    Every option defaults to None, so an unset option keeps the method's own default.
    """
    by_flag: dict[str, list] = {}
    for name, cls in methods.items():
        for opt in cls.options():
            by_flag.setdefault(opt.flag, []).append((name, opt))
    if not by_flag:
        return
    group = parser.add_argument_group(
        "method options", f"{len(by_flag)} options of the methods, each applying to the "
        "methods it names: --help-methods shows them here, ikbench methods NAME one method's")
    group.add_argument("--help-methods", action=_HelpMethods, nargs=0,
                       help="show this help with every method's options, and exit")
    for flag, users in by_flag.items():
        types = {opt.value_type() for _, opt in users}
        value_type = types.pop() if len(types) == 1 else str
        if len(users) == 1:
            name, opt = users[0]
            text = f"{name}: {opt.help_text()}"
        elif len({opt.help_text() for _, opt in users}) == 1:
            text = f"{', '.join(n for n, _ in users)}: {users[0][1].help_text()}"
        else:
            text = "; ".join(f"{name}: {opt.help_text()}" for name, opt in users)
        metavar = ("|".join(map(str, users[0][1].spec.choices)) if len(users) == 1
                   and users[0][1].spec.choices else flag.upper().replace("-", "_"))
        if value_type is int:  # counts and caps; a settings field named seed is a seed
            value_type = SEED if users[0][1].field == "seed" else METHOD_INTEGER
        action = group.add_argument(f"--{flag}", dest=f"opt_{flag.replace('-', '_')}",
                                    default=None, type=value_type, metavar=metavar,
                                    help=argparse.SUPPRESS)
        setattr(action, HIDDEN_HELP, text.replace("%", "%%"))


#: Where a method option keeps the help text that --help leaves out.
HIDDEN_HELP = "ikbench_method_help"


class _HelpMethods(argparse.Action):
    """``--help-methods``: the command's help with the method options --help leaves out."""

    def __call__(self, parser, namespace, values, option_string=None):
        for action in parser._actions:
            action.help = getattr(action, HIDDEN_HELP, action.help)
        parser.print_help()
        parser.exit()


def _given(args) -> dict[str, object]:
    """flag -> value of every method option given on the command line."""
    return {key[4:].replace("_", "-"): value for key, value in vars(args).items()
            if key.startswith("opt_") and value is not None}


def reject_foreign_options(args: argparse.Namespace, cls: type[Method],
                           methods: dict[str, Any] | None = None) -> None:
    """InputError if an option of another method was given (it would be silently ignored)."""
    own = {opt.flag for opt in cls.options()}
    for flag in _given(args):
        if flag not in own:
            owners = [n for n, c in (methods or {}).items()
                      if any(o.flag == flag for o in c.options())]
            by = f"--method {', '.join(owners)}" if owners else "another method"
            raise InputError(f"--{flag} is an option of {by}, not of --method {cls.name}")


def method_from_args(args: argparse.Namespace, cls: type[M], methods: dict[str, Any] | None = None,
                     **fixed: Any) -> M:
    """Build ``cls`` from the options given (each converted by the method's own settings);
    ``fixed`` settings go on top. InputError for options of other methods."""
    reject_foreign_options(args, cls, methods)
    values = {opt.field: _convert(opt, value) for opt in cls.options()
              if (value := _given(args).get(opt.flag)) is not None}
    return cls(**{**values, **fixed})


def _convert(opt, value):
    if isinstance(value, str) and opt.value_type() is not str:
        try:
            return opt.value_type()(value)
        except ValueError:
            raise InputError(f"--{opt.flag}: {value!r} is not a valid "
                             f"{opt.value_type().__name__}") from None
    return value


def method_names_help(methods: dict[str, Any]) -> str:
    """``ours, ours-lm, sequential-ik`` (the available methods)."""
    return ", ".join(methods)


def add_threads_and_quiet(parser: argparse.ArgumentParser) -> None:
    """--threads (torch threads, default 1), --quiet and --log."""
    parser.add_argument("--threads", type=THREADS, default=1,
                        help="torch threads (default 1: the tensors are tiny, and on a busy "
                        "2-core machine 2 threads ran ours 15x slower than 1)")
    add_progress_arguments(parser)


def add_progress_arguments(parser: argparse.ArgumentParser) -> None:
    """--quiet, --log FILE and --verbose (how :func:`begin` reports progress and what the
    libraries print)."""
    parser.add_argument("--quiet", action="store_true",
                        help="no progress bar (there is none either when stderr is not a "
                        "terminal)")
    parser.add_argument("--log", dest="progress_log", type=OUTPUT, default=None,
                        metavar="FILE|-",
                        help="progress as machine-readable lines, one JSON object each (t_s, "
                        "label, event, done, total, text), to FILE ('-': stderr)")
    parser.add_argument("--verbose", action="store_true",
                        help="show what kinematics libraries print on their own (TRAC-IK's "
                        "KDL, Drake's URDF warnings) as it comes; by default one note per "
                        "library at the end")


def begin(args: argparse.Namespace, threads: int | None = None) -> None:
    """The command's input is checked and its work starts: torch on ``threads`` threads when
    given (:func:`set_threads`), progress to a bar on a terminal (not with --quiet) and as
    JSON lines to --log (:mod:`ikbench.runtime.progress`).

    Every command calls it between checking its input and its first long or writing step.
    """
    from ikbench.core.chatter import set_verbose
    from ikbench.runtime.progress import configure

    if threads is not None:
        set_threads(threads)
    target = getattr(args, "progress_log", None)
    if target not in (None, "-"):
        from ikbench.core.io import check_writable

        check_writable(target)
    inputs_checked(args)
    quiet = bool(getattr(args, "quiet", False))
    # a terminal: a bar; a log file or a pipe: a start line and one every ~10 s, unless the
    # JSON lines of --log - go there
    mode = ("off" if quiet else "bar" if sys.stderr.isatty()
            else "off" if target == "-" else "periodic")
    log = None
    if target == "-":
        log = sys.stderr
    elif target is not None:
        log = open(target, "w", encoding="utf-8")  # noqa: SIM115 - closed by progress.reset
    configure(mode, log, owned=log is not None and log is not sys.stderr)
    set_verbose(bool(getattr(args, "verbose", False)))


def inputs_checked(args: argparse.Namespace) -> None:
    """The moment a command has checked all of its input and nothing is written yet (a seam:
    tests/test_hostile_input.py stops every command here to see that bad input never gets
    further)."""


def check_threads(threads: int) -> int:
    """InputError unless ``--threads`` is an integer >= 1."""
    if threads < 1:
        raise InputError(f"--threads: {threads} must be an integer >= 1")
    return threads


def set_threads(threads: int) -> None:
    """torch on ``threads`` threads (imports torch: call after validating the input)."""
    import torch

    torch.set_num_threads(threads)


def add_study_arguments(parser: argparse.ArgumentParser, output: str) -> None:
    """The options a batched study (batch, sweep) ends with: ``--output`` (default
    ``output``, under runs/, which git ignores), the progress options
    (:func:`add_progress_arguments`) and the executor's (:func:`add_executor_arguments`)."""
    parser.add_argument("--output", default=output, type=OUTPUT,
                        help=f"output directory (default: {output}, which git ignores)")
    add_progress_arguments(parser)
    add_executor_arguments(parser)


def add_executor_arguments(parser: argparse.ArgumentParser) -> None:
    """``--executor local|ray`` and ``--ray-address ADDR`` (sweep, batch, dataset)."""
    parser.add_argument("--executor", default="local", choices=("local", "ray"),
                        help="where the work runs: local (this process) or ray (tasks on a "
                        "Ray cluster: a private local one, or --ray-address; needs "
                        "pip install 'ikbench[scale]'); the results are the same "
                        "(default local)")
    parser.add_argument("--ray-address", default=None, metavar="ADDR",
                        help="a running Ray cluster for --executor ray: HOST:PORT, "
                        "ray://HOST:PORT or auto (default: start a local Ray)")


def check_executor_args(args: argparse.Namespace) -> None:
    """Validate ``--executor`` / ``--ray-address`` (no heavy imports; Ray not started)."""
    from ikbench.runtime.executors import check_executor

    check_executor(args.executor, args.ray_address)


def executor_from_args(args: argparse.Namespace) -> Executor:
    """The executor of ``--executor`` / ``--ray-address`` (starts or joins Ray)."""
    from ikbench.runtime.executors import get_executor

    return get_executor(args.executor, args.ray_address)
