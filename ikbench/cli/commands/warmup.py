"""``ikbench warmup``: compile ours-lm's and ours-exact's numba kernels once for this machine."""

from __future__ import annotations

import argparse

from ikbench.cli.options import add_robot_arguments, begin, robot_from_args
from ikbench.cli.values import Text

HELP = "compile ours-lm's and ours-exact's kernels once for this machine (minutes, then cached)"


def DESCRIPTION() -> str:  # noqa: N802 - the protocol's name for the paragraph
    from ikbench.methods.ours_lm.warmup import GROUP_NAMES, GROUP_USES

    groups = "; ".join(f"{g}: {GROUP_USES[g]}" for g in GROUP_NAMES)
    return ("Compile (or load from numba's on-disk cache) every numba kernel of ours-lm and "
            "ours-exact for the robot's joint count, one kernel group at a time with a line "
            "each (seconds, kernels compiled or loaded), and say the total. The first run on "
            "a machine (or after a numba upgrade or a solver change) compiles, minutes; "
            "every later run, and every later command, loads the cache in about a second. "
            "Without it the first command that needs a group compiles it, saying so. "
            f"Groups: {groups}.")


def arguments(parser: argparse.ArgumentParser) -> None:
    add_robot_arguments(parser)
    parser.add_argument("--all-robots", action="store_true",
                        help="every shipped robot's joint count (one robot per count: the "
                        "kernels are typed by it), not only --robot's")
    parser.add_argument("--groups", default=None, metavar="NAME[,NAME]",
                        type=Text("comma-separated kernel groups"),
                        help="only these kernel groups (default all: single-pose,path,"
                        "path-search)")


def run(args: argparse.Namespace) -> int:
    import time

    from ikbench.core.errors import InputError
    from ikbench.methods.ours_lm.devices import numba_unavailable
    from ikbench.methods.ours_lm.warmup import GROUP_NAMES, check_groups, warm_up
    from ikbench.runtime.numba_cache import cache_dir

    groups = (check_groups(g.strip() for g in args.groups.split(",") if g.strip())
              if args.groups else GROUP_NAMES)
    if not groups:
        raise InputError(f"--groups: {args.groups!r} names no group")
    robots = _robots(args)
    begin(args)
    if numba_unavailable() is not None:
        print(f"nothing to compile: numba cannot import ({numba_unavailable()}); ours-lm "
              "runs its numpy reference")
        return 0
    folder, why = cache_dir()
    print(f"numba's cache: {folder} ({why})", flush=True)
    started = time.perf_counter()
    compiled = loaded = 0
    for robot in robots:
        for result in warm_up(robot, groups, say=lambda line: print(line, flush=True)):
            compiled += result.compiled
            loaded += result.loaded
    total = time.perf_counter() - started
    if compiled:
        print(f"one-time compile: {total:.1f} s ({compiled} kernel(s) compiled, {loaded} "
              "loaded); later commands load them from the cache")
    else:
        print(f"already compiled: {total:.1f} s, {loaded} kernel(s) loaded from the cache")
    return 0


def _robots(args: argparse.Namespace) -> list:
    """--robot's robot, or (--all-robots) one shipped robot per joint count."""
    if not args.all_robots:
        return [robot_from_args(args)]
    from ikbench.core.robot import load_robot, shipped_robots

    by_dof: dict[int, object] = {}
    for name in shipped_robots():
        robot = load_robot(name)
        by_dof.setdefault(robot.dof, robot)
    return [by_dof[k] for k in sorted(by_dof)]
