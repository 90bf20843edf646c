"""Compiling (or loading from numba's cache) every kernel of ours-lm and ours-exact once, ahead
of the first command that needs them: ``ikbench warmup``.

numba compiles a kernel for each argument layout it meets, the robot's joint count among
them (the chain's arrays are typed by it), and keeps the result in its on-disk cache
(:mod:`ikbench.runtime.numba_cache` says where), so the first command on a machine waits for
the compile (minutes) and every later one loads it (about a second). :func:`warm_up` runs
the warm-ups the methods run before their timed calls, one kernel group at a time, and says
per group how long it took and how many kernels numba compiled or loaded from its cache.
ours-exact has no kernels of its own: its pose paths are ours-lm's path search. The
single-pose group runs ``OursLMSolver.prepare`` (every layout the timed calls meet), so it
fills the cache for :func:`ikbench.solve_pose` too, whose first call loads one of them.
"""

from __future__ import annotations

import importlib
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from types import ModuleType
from typing import Any

#: The kernel groups, in the order they are warmed up, and the commands that run each.
GROUP_NAMES = ("single-pose", "path", "path-search")
GROUP_USES = {"single-pose": "ikbench ik, recommend",
              "path": "run, compare, sweep (ours-lm's path LM)",
              "path-search": "cartesian, compare, ours-exact (the pose-path search)"}
_MODULES = {
    "single-pose": ("ikbench.methods.ours_lm.single_pose_kernels",),
    "path": ("ikbench.methods.ours_lm.compiled", "ikbench.methods.ours_lm.compiled_chain"),
    "path-search": ("ikbench.methods.ours_lm.path_search", "ikbench.methods.ours_lm.compiled_paths",
                    "ikbench.methods.ours_lm.self_motion", "ikbench.methods.ours_lm.anchor_ik",
                    "ikbench.core.capsules"),
}


@dataclass(frozen=True)
class GroupWarmup:
    """One kernel group warmed up on one robot: seconds [s], kernels numba compiled and
    kernels it loaded from its cache (specialisations; ``skipped``: why it did not run)."""

    group: str
    robot: str
    seconds: float
    compiled: int
    loaded: int
    skipped: str | None = None

    def line(self) -> str:
        """The progress line: name, seconds, and compiled or cache hits."""
        if self.skipped:
            return f"{self.group:<12} {self.robot}: skipped ({self.skipped})"
        what = (f"compiled {self.compiled} kernel(s)" + (f", {self.loaded} from the cache"
                                                         if self.loaded else "")
                if self.compiled else f"already compiled ({self.loaded} from the cache)")
        return f"{self.group:<12} {self.robot}: {self.seconds:6.1f} s, {what}"


def check_groups(names: Iterable[str]) -> tuple[str, ...]:
    """``names`` if each is a kernel group (:data:`GROUP_NAMES`); InputError naming one not."""
    from ikbench.core.errors import InputError

    names = tuple(names)
    for name in names:
        if name not in _RUNS:
            raise InputError(f"--groups: {name!r} is not one of {', '.join(_RUNS)}")
    return names


def warm_up(robot: Any, groups: Iterable[str] = GROUP_NAMES,
            say: Callable[[str], None] | None = None) -> list[GroupWarmup]:
    """Compile (or load) the kernels of ``groups`` for ``robot``, one group at a time, each
    with its line given to ``say`` as it finishes. Raises the numba import's error when numba
    cannot import (there is nothing to compile: the numpy reference runs)."""
    import numba  # noqa: F401 - its failure is the caller's message

    done = []
    for group in check_groups(groups):
        started = time.perf_counter()
        before = _counts(group)
        skipped = _RUNS[group](robot)
        after = _counts(group)
        result = GroupWarmup(group, robot.name, time.perf_counter() - started,
                             after[0] - before[0], after[1] - before[1], skipped)
        done.append(result)
        if say is not None:
            say(result.line())
    return done


def _single_pose(robot: Any) -> str | None:
    from ikbench.methods.ours_lm.pose_solver import OursLMSolver

    for kind in ("pose", "position"):
        solver = OursLMSolver(robot, kind, (1.0, 1.0), 0.01)
        solver.prepare()
        if solver.compiled is None:
            return "numba does not import"
    return None


def _path(robot: Any) -> str | None:
    from ikbench.methods.ours_lm import compiled

    compiled.warm_up(robot)
    return None


def _path_search(robot: Any) -> str | None:
    from ikbench.methods.ours_lm import path_search

    if not path_search.available(robot):
        return "the robot's collision geometry is not capsules: the numpy search runs"
    path_search.warm_up(robot)
    return None


_RUNS: dict[str, Callable[[Any], str | None]] = {
    "single-pose": _single_pose, "path": _path, "path-search": _path_search}


def _counts(group: str) -> tuple[int, int]:
    """(specialisations compiled, loaded from the cache) so far in this process by the kernels
    of ``group``'s modules (those already imported)."""
    from numba.core.dispatcher import Dispatcher

    compiled = loaded = 0
    for module in _modules(group):
        for value in vars(module).values():
            if isinstance(value, Dispatcher) and value.targetoptions.get("inline") != "always":
                stats = value.stats
                compiled += sum(stats.cache_misses.values())
                loaded += sum(stats.cache_hits.values())
    return compiled, loaded


def _modules(group: str) -> list[ModuleType]:
    return [sys.modules[name] if name in sys.modules else importlib.import_module(name)
            for name in _MODULES[group]]
