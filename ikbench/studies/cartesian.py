"""The Cartesian path benchmark: methods on 6-D pose-path problems, several seeds each.

``cartesian(problems="cppflow")`` solves every problem (CppFlow's 13 CppFlow/TORM problems, or
names and files in CppFlow's format, :mod:`ikbench.core.problems`) with every method that
follows goal frames (``Capabilities.frames``; a method added later joins by setting it), once
per seed, through the study harness (each solve timed the same way, a failed solve kept as a
row). It returns the long-form table, one row per problem x method x seed, with CppFlow's
validity (:mod:`ikbench.core.validity`) and the time to a valid solution (every method stops at
its first valid solution or gives up). :func:`write` puts it under ``OUTPUT/cartesian/``:
``table.csv``, ``summary.csv``, the trajectories, a figure per problem, ``report.md`` and
``run.json`` (:mod:`.cartesian_report`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.errors import IkbenchError, InputError
from ikbench.core.metrics import frame_metrics
from ikbench.core.problems import BENCHMARK, load_problem, resolve_problems
from ikbench.methods.base import Method
from ikbench.methods.registry import available_methods, get_method, parse_names
from ikbench.render.cartesian_report import write_folder
from ikbench.runtime.harness import Outcome, solve_tasks
from ikbench.runtime.progress import Reporter
from ikbench.studies.first_call import first_path_call
from ikbench.studies.folders import WITHIN

DEFAULT_SEEDS = (1, 2, 3)
#: Seeds are integers in [0, 2^63) (numpy's and torch's generators).
MAX_SEED = 2**63
FOLDER = WITHIN["cartesian"]
#: table.csv's columns, in order.
COLUMNS = ["problem", "robot", "waypoints", "method", "seed", "valid", "time_to_valid_s",
           "duration_s", "iterations", "position_error_mean_mm", "position_error_max_mm",
           "rotation_error_mean_deg", "rotation_error_max_deg", "max_joint_change_deg",
           "max_joint_change_mm", "joint_path_length_deg", "prismatic_path_length_mm",
           "cartesian_path_length_mm", "target_path_length_mm", "failed_criteria", "failure",
           "trajectory", "obstacles", "avoids_obstacles", "self_collisions", "env_collisions",
           "min_clearance_mm", "min_self_clearance_mm", "first_collision_waypoint",
           "first_collision_pair", "collision_model", "initial_configuration_distance"]
#: The note beside a collision of a method without obstacle avoidance.
NO_AVOIDANCE = "does not avoid obstacles"


@dataclass
class CartesianResult:
    """What :func:`cartesian` produced: the table, the tasks and poses behind it.

    Attributes:
        table: one row per problem x method x seed (:data:`COLUMNS`).
        problems: problem name -> (robot, task, parsed problem).
        poses: (problem, method, seed) -> poses (n+1, dof) [pose units] of the solved runs.
        methods: the methods' names, in order; settings: name -> the settings used (seed 0).
        seeds: the seeds.
        wall_s: the whole study's wall time [s].
        runtimes: name -> what ran its solves (``Method.runtime()``: backend, threads).
        first_calls: name -> its first call in a fresh process (``import_s``, ``setup_s``,
            ``solve_s``, ``first_call_s`` or ``error``); empty when not measured.
    """

    table: pd.DataFrame
    problems: dict
    poses: dict
    methods: list[str]
    settings: dict
    seeds: tuple[int, ...]
    wall_s: float
    options: dict = field(default_factory=dict)
    runtimes: dict = field(default_factory=dict)
    first_calls: dict = field(default_factory=dict)
    #: The command line the report quotes ("" for none).
    command: str = ""
    #: Trajectory CSVs written: ``first`` (the first seed's) or ``all``.
    trajectories: str = "first"

    def write(self, folder: str | Path) -> Path:
        """Write ``folder/cartesian/`` whole (see :mod:`.cartesian_report`); return it."""
        return write_folder(self, Path(folder) / FOLDER, self.command, self.trajectories)


@dataclass(frozen=True)
class CartesianSpec:
    """A Cartesian benchmark: the problem files (:func:`resolve_problems`), the method names
    (:func:`parse_methods`), the seeds (:func:`parse_seeds`), each method's settings, the
    progress lines, the first-call timing, and what the written folder quotes and holds.
    :meth:`validate` checks the rest; :func:`run` runs it (:mod:`ikbench.studies.shape`)."""

    problems: tuple[Path, ...]
    methods: tuple[str, ...]
    seeds: tuple[int, ...] = DEFAULT_SEEDS
    options: dict[str, dict[str, Any]] = field(default_factory=dict)
    progress: bool = True
    first_call: bool = False
    command: str = ""
    trajectories: str = "first"

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for a method's settings it refuses,
        before any solve."""
        for name in self.methods:
            build_method(name, self.seeds[0], self.options.get(name))


def frame_methods() -> dict[str, type]:
    """name -> class of every available method that follows goal frames (registry order)."""
    return {name: cls for name, cls in available_methods().items() if cls.capabilities.frames}


def parse_seeds(text: str | int | Sequence[int | str]) -> tuple[int, ...]:
    """``"1,2,3"``, ``"1-5"`` (a range, both ends included) or a mix such as ``"1-3,7"`` (or
    a sequence) -> (1, 2, 3, ...); InputError for anything but distinct integers in
    [0, 2^63)."""
    items = text if isinstance(text, (list, tuple)) else str(text).split(",")
    seeds: tuple[int, ...] = ()
    try:
        for item in (str(s).strip() for s in items):
            if not item:
                continue
            first, dash, last = item.partition("-")
            if dash and first:  # a range a-b (a leading "-" is a negative number: refused)
                low, high = int(first), int(last)
                seeds += tuple(range(low, high + 1)) if low <= high else (-1,)
            else:
                seeds += (int(item),)
    except ValueError:
        seeds = ()
    if not seeds or any(not 0 <= s < MAX_SEED for s in seeds) or len(set(seeds)) != len(seeds):
        raise InputError(f"--seeds: {text!r} must be distinct integers in [0, 2^63), "
                         "comma-separated or as ranges, e.g. 1,2,3 or 1-5")
    return seeds


def parse_methods(text: str | Sequence[str] | None) -> list[str]:
    """Method names (comma-separated or a list); None: every method that follows goal frames.

    Raises:
        InputError: an unknown or unavailable method, or one that cannot follow goal frames
            (:func:`~ikbench.methods.registry.parse_names`).
    """
    return parse_names(text, accepts=follows_frames, default=lambda: list(frame_methods()))


def follows_frames(cls: type[Method]) -> str:
    """Why ``cls`` cannot take part in a Cartesian study ("" when it follows goal frames)."""
    if cls.capabilities.frames:
        return ""
    return ("cannot follow goal frames (6-D pose paths); methods that can: "
            f"{', '.join(frame_methods()) or 'none'}")


def build_method(name: str, seed: int, options: dict[str, Any] | None = None) -> Method:
    """The method ``name`` with ``options`` (its settings' fields) and, when its settings
    have a ``seed`` field, ``seed``."""
    cls = get_method(name)
    fields = {f.name for f in dataclasses.fields(cls.Settings)}
    settings = dict(options or {})
    if "seed" in fields:
        settings["seed"] = seed
    return cls(**settings)


def cartesian(problems: str | Path | Sequence[str | Path] = BENCHMARK,
              methods: str | Sequence[str] | None = None,
              seeds: str | int | Sequence[int | str] = DEFAULT_SEEDS,
              options: dict[str, dict[str, Any]] | None = None,
              progress: bool = True, first_call: bool = False) -> CartesianResult:
    """Run the benchmark (see the module docstring); nothing is written.

    Args:
        problems: ``"cppflow"`` (CppFlow's 13), ``"shipped"`` (every shipped problem), names
            and files (comma-separated or a list).
        methods: method names; None: every available method that follows goal frames.
        seeds: seeds (each method with a ``seed`` setting gets each; the others run once per
            seed too, as repetitions of the same solve).
        options: method name -> settings (keywords) for that method.
        progress: print a line per solve to stderr.
        first_call: after the solves, time each method's first call in a fresh process
            (import, set-up on the first problem's robot, the first problem solved once with
            the first seed: :func:`ikbench.studies.first_call.first_path_call`).

    Returns:
        A :class:`CartesianResult` (``table`` has :data:`COLUMNS`).
    """
    spec = CartesianSpec(tuple(resolve_problems(problems)), tuple(parse_methods(methods)),
                         parse_seeds(seeds), dict(options or {}), progress, first_call)
    spec.validate()
    return run(spec)


def run(spec: CartesianSpec) -> CartesianResult:
    """Run the benchmark ``spec`` (validated: :meth:`CartesianSpec.validate`); nothing is
    written (:meth:`CartesianResult.write` writes it)."""
    started = time.perf_counter()
    files, names, seeds, options = spec.problems, list(spec.methods), spec.seeds, spec.options
    progress, first_call = spec.progress, spec.first_call
    loaded = {f.stem: load_problem(f) for f in files}
    rows, poses = [], {}
    total = len(loaded) * len(names) * len(seeds)
    log = Reporter(FOLDER, total=total, unit="solve", enabled=progress)
    for problem, (robot, task, _) in loaded.items():
        for name in names:
            for seed in seeds:
                method = build_method(name, seed, options.get(name))
                try:
                    outcome = solve_tasks(method, robot, [task])[0]
                except IkbenchError as exc:  # refused before solving: a row saying why
                    outcome = Outcome(task, None, 0.0, f"refused: {exc}")
                if outcome.solution is not None:  # the table describes the poses as written
                    outcome.solution.poses = as_written(outcome.solution.poses)
                    poses[(problem, name, seed)] = outcome.solution.poses
                row = _row(problem, robot, task, name, seed, outcome)
                rows.append(row)
                verdict = "valid" if row["valid"] else f"not valid ({row['failed_criteria']})"
                log.advance(1, f"{problem} {name} seed {seed}: {verdict}, "
                            f"{row['duration_s']:.2f} s")
    built = {name: build_method(name, seeds[0], options.get(name)) for name in names}
    first_calls = {}
    if first_call:  # after the solves: numba's cache as they left it
        robot, task, _ = next(iter(loaded.values()))
        for name in names:
            log.note(f"{name}: timing its first call in a fresh process")
            first_calls[name] = first_path_call(robot, name, built[name].settings, task)
    log.close()
    return CartesianResult(pd.DataFrame(rows, columns=COLUMNS), loaded, poses, names,
                           {n: m.settings for n, m in built.items()}, seeds,
                           time.perf_counter() - started, options,
                           {n: m.runtime() for n, m in built.items()}, first_calls,
                           spec.command, spec.trajectories)


def as_written(poses: npt.ArrayLike) -> np.ndarray:
    """Poses rounded to the 10 significant digits a trajectory CSV holds."""
    return np.array([[float(f"{v:.10g}") for v in row] for row in np.asarray(poses)])


def _row(problem, robot, task, method, seed, outcome) -> dict:
    avoids = get_method(method).capabilities.obstacles
    base = {"problem": problem, "robot": robot.name, "waypoints": task.goal.steps + 1,
            "method": method, "seed": seed, "duration_s": outcome.wall_s,
            "trajectory": f"{method}/trajectory_{problem}_seed{seed}.csv",
            "obstacles": len(task.required.obstacles), "avoids_obstacles": avoids}
    if not outcome.ok:
        return {**base, "valid": False, "failed_criteria": "failure",
                "failure": outcome.failure, "trajectory": ""}
    metrics = frame_metrics(robot, task, outcome.solution.poses)
    failure = ""
    if metrics["env_collisions"] and not avoids:
        failure = NO_AVOIDANCE
    return {**base, **{k: v for k, v in metrics.items() if k in COLUMNS},
            "iterations": outcome.solution.iterations, "failure": failure,
            "time_to_valid_s": outcome.wall_s if metrics["valid"] else np.nan}


def write(result: CartesianResult, output: str | Path, command: str = "",
          trajectories: str = "first") -> Path:
    """Write ``OUTPUT/cartesian/`` whole (see :mod:`.cartesian_report`); return the folder.
    ``trajectories``: ``first`` (the first seed's trajectory CSVs) or ``all``."""
    return replace(result, command=command, trajectories=trajectories).write(output)
