"""``ikbench compare``: every method on the same task contract, timed the same way, one table.

Every method receives the same line tasks with the same :class:`~ikbench.core.contract.
Contract` (``Task.contract``): fixed start and touch poses, the line, pointing over its judged
part, the speed limits, the tolerances. :func:`compare` solves each task alone ``repeat``
times per method through the study harness (:mod:`ikbench.runtime.harness`: its clock,
failures kept as rows); a method that batches (ours-lm) also solves all tasks in one call per
round, and that share is its own column. Each method's last repetition is serialised as its
trajectory CSVs (:class:`ikbench.runtime.record.TrajectoryFile`: the text and the poses read
back from it), every criterion is measured from those poses by
:func:`ikbench.core.metrics.contract_metrics` and judged by :func:`ikbench.core.contract.judge`
- success is never what the method reports, and it is what the written CSVs recompute to. The
same text is written as a run folder (``DIR/compare/<method>/``, as ``ikbench run`` writes it).
Inside, :func:`compare` builds one :class:`CompareSpec` and runs it (:func:`run`, then
:meth:`CompareResult.write`; :mod:`ikbench.studies.shape`).

Two tracks are judged from the same trajectories: ``paper`` (the contract as given: start and
touch poses fixed) and ``touch`` (touch pose only). A method whose scheme does not keep a
pose the paper's track fixes (``Method.fixed_poses``: the authors' walk from the touch pose)
has status ``does not honour: start pose`` there, never success.

Obstacles (a targets file's ``obstacles``, or ``obstacles=`` / ``--obstacles`` overriding them)
go on every task, and the contract then judges collisions too (``ok_collisions``: no
self-collision, no collision with an obstacle, from the robot's collision model);
``results.csv`` then gains :data:`OBSTACLE_COLUMNS` (whether the method avoids obstacles, the
waypoints in collision, the clearance, the first collision, and the judge's check itself: its
geometry and its time per trajectory, ``collision_check_ms``, taken after the solve and outside
every method's clock; a method's own avoidance stays inside its time). Without obstacles the
columns and the tables are exactly those of an obstacle-free comparison.

Output ``DIR/compare/``: ``results.csv`` (long form: one row per method, robot, task and
trajectory, one ``ok_<criterion>`` column per criterion, ``success`` for the paper's track and
``success_touch`` for the touch-pose-only track), ``leaderboard.md`` / ``leaderboard.csv``
(one table per track, :mod:`ikbench.render.leaderboard`), ``pareto.png`` (with ours-lm's
weight sweep, ``pareto_sweep.csv``), ``run.json`` (the contract, settings, library versions,
machine) and the per-method folders.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.core.collision import collision_model
from ikbench.core.contract import (
    COLLISION_CRITERION,
    CRITERIA,
    DEFAULT_TOLERANCES,
    Contract,
    contract_for,
    judge,
)
from ikbench.core.defaults import DEFAULT_DURATION_S, REFERENCE_METHOD
from ikbench.core.errors import IkbenchError, InputError
from ikbench.core.legibility import (
    LEGIBILITY_COLUMNS,
    constant_times_s,
    goal_points_mm,
    legibility_metrics,
    pointing_probabilities,
    position_probabilities,
    true_goal_index,
)
from ikbench.core.metrics import contract_metrics
from ikbench.core.obstacles import read_obstacles
from ikbench.core.provenance import library_versions, provenance
from ikbench.core.robot import Robot, as_robot
from ikbench.core.targets import Targets, select_targets
from ikbench.core.task import Task, line_tasks
from ikbench.methods.base import Method, hearing_fraction, report_fraction
from ikbench.methods.registry import get_method, method_status, parse_names
from ikbench.render.leaderboard import (
    leaderboard,
    leaderboard_markdown,
    plot_pareto,
    with_first_calls,
)
from ikbench.render.legibility_plots import plot_legibility_summary, plot_method_legibility
from ikbench.runtime.executors import Executor, LocalExecutor, portable_robot
from ikbench.runtime.harness import Outcome, Progress, describe, solve_tasks
from ikbench.runtime.record import (
    RunFolder,
    RunRecord,
    RunStage,
    TrajectoryFile,
    keep_nothing,
)
from ikbench.studies.first_call import first_path_call
from ikbench.studies.folders import RUNS, WITHIN
from ikbench.studies.run import trajectory_files, write_run
from ikbench.studies.shape import run_and_write

#: Two methods' trajectories are the same when every pose agrees within this [pose units].
IDENTICAL_TOLERANCE = 1e-6
#: The default tolerances (kept under their old name; the contract states them).
TOLERANCES = DEFAULT_TOLERANCES
#: Metric columns of results.csv, from ikbench.core.metrics.contract_metrics.
METRICS = ["line_distance_mean_mm", "line_distance_std_mm", "pointing_deviation_mean_deg",
           "pointing_deviation_std_deg", "start_point_error_mm", "end_point_error_mm",
           "start_pose_error_deg", "end_pose_error_deg", "max_joint_step_deg",
           "mean_sq_jerk_deg2", "mean_sq_joint_step_deg2"]
#: Metric columns added with the task contract.
CONTRACT_METRICS = ["line_distance_max_mm", "pointing_deviation_judged_mean_deg",
                    "pointing_deviation_judged_max_deg", "speed_limit_use",
                    "max_step_limit_deg"]
#: One column per criterion: True/False, empty where the track does not judge it.
OK_COLUMNS = ["ok_solved", "ok_honours", *(f"ok_{name}" for name in CRITERIA)]
#: The columns of results.csv, in order (the first ones as before the contract).
COLUMNS = ["method", "library", "library_version", "robot", "task", "trajectory", "status",
           "success", "failure", "time_median_s", "time_min_s", "time_max_s", "repetitions",
           "iterations", "within_limits", *METRICS,
           "track", "scheme", "fixed_poses", "success_touch", "time_batched_s",
           *CONTRACT_METRICS, *OK_COLUMNS, *LEGIBILITY_COLUMNS]
#: Columns results.csv gains when the tasks carry obstacles (after :data:`COLUMNS`).
OBSTACLE_COLUMNS = ["obstacles", "avoids_obstacles", "self_collisions", "env_collisions",
                    "min_clearance_mm", "first_collision_waypoint", "first_collision_pair",
                    f"ok_{COLLISION_CRITERION}", "collision_geometry", "collision_check_ms"]
#: The collision figures of contract_metrics copied into results.csv (``collision_check_ms``:
#: the judge's check of the trajectory, timed by itself after the solve, outside every
#: method's clock; ``collision_geometry``: what it checked, the same for every method).
COLLISION_METRICS = ["self_collisions", "env_collisions", "min_clearance_mm",
                     "first_collision_waypoint", "first_collision_pair", "collision_geometry",
                     "collision_check_ms"]
#: The note beside a collision of a method that does not avoid obstacles.
NO_AVOIDANCE = "does not avoid obstacles"
#: Statuses that make ``ikbench compare`` exit with 1.
FAILING = ("failed", "refused", "does not honour", "not installed")


@dataclass
class CompareResult:
    """What :func:`compare` measured: ``results`` (results.csv), ``leaderboard`` (one row per
    method and track), the ``record`` written as run.json and the ``contract``."""

    results: pd.DataFrame
    leaderboard: pd.DataFrame
    record: dict
    contract: Contract | None = None
    #: What :meth:`write` writes besides the tables (set by :func:`run`; None: nothing).
    pending: _Pending | None = field(default=None, repr=False, compare=False)

    def write(self, folder: str | Path) -> Path:
        """Write ``folder/compare/`` (replaced whole: the run folders of the methods, the
        tables, pareto.png, run.json) from the trajectories :func:`run` judged; return it."""
        if self.pending is None:
            raise ValueError("this comparison was not made by ikbench.studies.compare.run")
        spec, pending = self.pending.spec, self.pending
        root = Path(folder) / WITHIN["compare"]
        with RunFolder(root).staged(keep=keep_nothing) as stage:
            for name, outcomes in pending.last.items():
                write_run(pending.built[name], spec.robot, spec.targets, outcomes,
                          stage.path / name,
                          {"shape": "line", "name": name, "duration_s": spec.contract.duration_s,
                           "goals": spec.goals},
                          trajectories=pending.files[name])
            pending.record.total_wall_time_s = time.perf_counter() - pending.started
            _write_tables(stage, self.results, self.leaderboard, pending.record, spec.contract,
                          pending.sweep_frame)
            _write_legibility_figures(stage, spec, pending.files)
        pending.log.note(f"written to {root}/ in {time.perf_counter() - pending.started:.1f} s")
        self.record = pending.record.to_dict()
        return root

    @property
    def failed(self) -> bool:
        """True when a solve failed, a method refused the tasks or did not honour the
        contract (``ikbench compare`` then exits with 1)."""
        return bool(self.results["status"].astype(str).str.startswith(FAILING).any())


def parse_methods(text: str | list[str]) -> list[str]:
    """``"ours-lm,ikpy"`` -> names, each registered (available or not; the missing ones become
    rows that say so); InputError otherwise (:func:`~ikbench.methods.registry.parse_names`)."""
    return parse_names(text, installed=False)


def check_repeat(repeat) -> int:
    """``--repeat``: an integer >= 1."""
    if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
        raise InputError(f"--repeat: {repeat!r} must be an integer >= 1")
    return repeat


def columns_for(contract: Contract) -> list[str]:
    """The columns of results.csv: :data:`COLUMNS`, then :data:`OBSTACLE_COLUMNS` when the
    contract judges collisions."""
    return [*COLUMNS, *(OBSTACLE_COLUMNS if contract.obstacles else [])]


def avoids_obstacles(cls: type[Method] | Method | None, tasks: Sequence[Task]) -> bool:
    """True when the method ``cls`` (None: not installed) keeps clear of the obstacles of these
    tasks: ``Capabilities.obstacles`` covers pose paths (goal frames) only, so on line tasks
    no method avoids them today."""
    return (cls is not None and cls.capabilities.obstacles
            and all(t.goal.has_frames for t in tasks))


def with_obstacles(targets: Targets, obstacles: str | Path | Sequence | None,
                   robot: Robot) -> Targets:
    """``targets`` with the obstacles of ``obstacles`` (a file, a named set of the robot such
    as ``touchscreen``, ``none``, or parsed obstacles) instead of their own; None keeps
    theirs. InputError when obstacles are given for a robot without collision geometry."""

    if obstacles is not None:
        source = str(obstacles) if isinstance(obstacles, (str, Path)) else "given"
        targets = targets.with_obstacles(read_obstacles(obstacles, robot), source)
    if targets.obstacles and collision_model(robot) is None:
        raise InputError(f"obstacles ({targets.obstacles_source}): robot {robot.name} has no "
                         "collision geometry (a collision file in its config or <collision> "
                         "elements in its URDF), so collisions cannot be judged; give "
                         "--obstacles none")
    return targets


@dataclass(frozen=True)
class CompareSpec:
    """A comparison, validated: what :func:`compare` builds from its keywords and
    :func:`run_comparison` runs.

    Attributes:
        methods: registered method names, in order (available or not).
        robot: the robot.
        targets: the targets (with the obstacles every task gets).
        tasks: the line tasks, each carrying :attr:`contract`.
        contract: the task contract (the ``paper`` track; ``touch`` is judged beside it).
        reference: the method the time ratios are against.
        repeat: timed solves of each task alone per method.
        warmup: untimed rounds before.
        solvers: configured methods by name, replacing the defaults.
        executor: where the methods run.
        sweep: solve ours-lm's weight sweep for pareto.png (when ours-lm is compared).
        output: the results directory (``output/compare/``); None writes nothing.
        progress: progress lines on stderr.
        goals: the goal set of the legibility columns (:mod:`ikbench.core.legibility`):
            a targets file's touch poses; None: the targets' own (all their ids).
        first_call: after the timed solves, time each method's first call in a fresh
            process (import, set-up on the robot, the first task solved once:
            :func:`ikbench.studies.first_call.first_path_call`); the leaderboard's
            ``first_call_s``.
    """

    methods: list[str]
    robot: Robot
    targets: Targets
    tasks: list[Task]
    contract: Contract
    reference: str
    repeat: int = 5
    warmup: int = 1
    solvers: dict[str, Method] = field(default_factory=dict)
    executor: Executor = field(default_factory=LocalExecutor)
    sweep: bool = True
    output: Path | None = None
    progress: bool = True
    goals: Targets | None = None
    first_call: bool = False

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for no method, an unregistered method, a
        repeat below 1 or a reference not among the methods."""
        parse_methods(list(self.methods))
        check_repeat(self.repeat)
        if self.reference not in self.methods:
            raise InputError(f"--reference: {self.reference!r} is not among --methods "
                             f"{', '.join(self.methods)}")


@dataclass
class _Pending:
    """What :meth:`CompareResult.write` needs besides the tables: the spec, the methods built,
    their last repetition and its trajectory files, the sweep, the record, the clock's start
    and the progress log."""

    spec: CompareSpec
    built: dict[str, Method]
    last: dict[str, list[Outcome]]
    files: dict[str, dict[str, TrajectoryFile]]
    sweep_frame: pd.DataFrame | None
    record: RunRecord
    started: float
    log: Progress


def compare(methods: list[str] | str, *, robot: Robot | str | None = None,
            targets: str | Path | Targets | None = None, only: str | None = None,
            steps: int | None = None, repeat: int = 5, warmup: int = 1,
            output: str | Path | None = RUNS,
            reference: str | None = None, progress: bool = True,
            solvers: dict[str, Method] | None = None, executor: Executor | None = None,
            contract: Contract | None = None, tolerances: str | dict | None = None,
            pointing: str | bool = "auto", duration_s: float = DEFAULT_DURATION_S,
            sweep: bool = True,
            obstacles: str | Path | Sequence | None = None,
            goals: str | Path | Targets | None = None,
            first_call: bool = False) -> CompareResult:
    """Run every method on every task ``repeat`` times; write ``output/compare/``.

    Args:
        methods: registered method names (list or comma-separated); unavailable ones become
            rows saying why.
        robot: the robot or its name/config/URDF (default NICO's right arm).
        targets: a targets file, :class:`Targets`, or None for the robot's own.
        only: trajectory ids to keep (``"1,3"``).
        steps: number of segments n (default the targets file's).
        repeat: timed solves of each task alone per method; times are the median, min, max.
        warmup: untimed rounds before (caches, lazy imports, JIT).
        output: the results directory (``output/compare/`` is replaced whole); None writes
            nothing.
        reference: the method the time ratios are against (default ``ours-lm`` if compared,
            else the first method).
        progress: progress lines on stderr.
        solvers: configured methods by name, replacing the defaults.
        executor: where the methods run (:mod:`ikbench.runtime.executors`; default this
            process). Compare times only from runs with one method per machine at a time.
        contract: the task contract (default :func:`ikbench.core.contract.contract_for` the
            robot with ``tolerances``, ``pointing`` and ``duration_s``).
        tolerances: overrides of the default tolerances (``"start_pose_deg=0.5,..."``).
        pointing: ``auto`` (on for robots whose config names a pointing axis), ``on``, ``off``.
        duration_s: the trajectories' duration T [s] the speed limits are judged at.
        sweep: with ours-lm among the methods, solve its weight sweep for pareto.png.
        obstacles: obstacles for every task instead of the targets' (a file, a named set of
            the robot such as ``"touchscreen"``, ``"none"``, or parsed obstacles); None keeps
            the targets file's. With obstacles the contract judges collisions.
        goals: the goal set of the legibility columns: a targets file (or
            :class:`Targets`) whose touch poses' fingertip points are the goals; None: the
            targets' own touch points, every id (NICO's: the seven touch points).
        first_call: time each method's first call in a fresh process (import, set-up, the
            first trajectory solved once) after the timed solves: the leaderboard's
            ``first_call_s``.

    Returns:
        A :class:`CompareResult`.

    Raises:
        ikbench.runtime.harness.Interrupted: Ctrl-C while solving (nothing written).
    """
    names = parse_methods(methods)
    robot = as_robot(robot)
    goal_set = select_targets(goals if goals is not None else targets, robot, None, None)
    targets = with_obstacles(select_targets(targets, robot, only, steps), obstacles, robot)
    contract = contract or contract_for(robot, tolerances=tolerances, pointing=pointing,
                                        duration_s=duration_s)
    spec = line_spec(names, robot, targets, contract, reference, repeat, warmup=warmup,
                     solvers=dict(solvers or {}), executor=executor or LocalExecutor(),
                     sweep=sweep, output=None if output is None else Path(output),
                     progress=progress, goals=goal_set, first_call=first_call)
    return run_and_write(spec, run, spec.output)


def line_spec(names: list[str], robot: Robot, targets: Targets, contract: Contract,
              reference: str | None, repeat: int, **settings) -> CompareSpec:
    """The :class:`CompareSpec` of ``names`` on the line tasks of ``targets`` under
    ``contract`` (judging collisions when the targets carry obstacles), against ``reference``
    (default :func:`default_reference`); ``settings``: the spec's other fields. Not
    validated: call its ``validate()``."""
    contract = replace(contract, obstacles=bool(targets.obstacles))
    return CompareSpec(names, robot, targets, line_tasks(robot, targets, contract), contract,
                       default_reference(reference, names), repeat, **settings)


def run(spec: CompareSpec) -> CompareResult:
    """Solve, measure and judge ``spec`` in memory (nothing written; :meth:`CompareResult.
    write` writes the folder from the same serialised trajectories it judged)."""
    log = Progress("compare", enabled=spec.progress, unit="method")
    started = time.perf_counter()
    with hearing_fraction(log.within if spec.progress else None):  # a method's solves done
        rows, built, last = _solve_methods(spec, log)
    sweep_frame = (ours_lm_sweep(spec.robot, spec.tasks, spec.contract, spec.solvers)
                   if spec.sweep and REFERENCE_METHOD in built else None)
    files = {name: trajectory_files(spec.robot, outcomes, spec.contract.duration_s)
             for name, outcomes in last.items()}
    results = measure(spec, pd.DataFrame(rows), built, files)
    first_calls = _first_calls(spec, built, log) if spec.first_call else {}
    board = with_first_calls(leaderboard(results, spec.reference, spec.contract), first_calls)
    record = _record(spec, built, rows, last)
    if spec.first_call:
        record.study["first_calls"] = first_calls
    return CompareResult(results, board, record.to_dict(), spec.contract,
                         _Pending(spec, built, last, files, sweep_frame, record, started, log))


def run_comparison(spec: CompareSpec) -> CompareResult:
    """:func:`run`, then :meth:`CompareResult.write` into ``spec.output`` (unless None)."""
    result = run(spec)
    if spec.output is not None:
        result.write(spec.output)
    return result


def _first_calls(spec: CompareSpec, built: dict[str, Method], log: Progress
                 ) -> dict[str, dict]:
    """Each method built: its first call in a fresh process on the spec's robot and first
    task (after the timed solves: numba's cache as they left it)."""
    out = {}
    for name, solver in built.items():
        log.say(f"{name}: timing its first call in a fresh process")
        out[name] = first_path_call(spec.robot, name, solver.settings, spec.tasks[0])
    return out


def default_reference(reference: str | None, names: list[str]) -> str:
    """The method the time ratios are against: ``reference``, else
    :data:`~ikbench.methods.registry.REFERENCE_METHOD` (ours-lm) when compared, else the first
    method (:meth:`CompareSpec.validate` checks it is among ``names``)."""
    return reference or (REFERENCE_METHOD if REFERENCE_METHOD in names else names[0])


def _solve_methods(spec: CompareSpec, log: Progress
                   ) -> tuple[list[dict], dict[str, Method], dict[str, list[Outcome]]]:
    """Build the methods and time each one on the spec's executor (:func:`solve_method`).

    Returns:
        (rows of results.csv so far: one per method and task, unmeasured; the methods built,
        by name; each built method's last repetition, its outcomes by task, by name).
    """
    rows, built = _build(spec, log)
    executor = spec.executor
    portable = spec.robot if executor.workers == 1 else portable_robot(spec.robot)
    work = [(name, solver, portable, spec.tasks, spec.warmup, spec.repeat)
            for name, solver in built.items()]
    log.say(f"solving {len(spec.tasks)} trajectories with {len(built)} method(s), each "
            f"trajectory alone, {spec.warmup} warm-up + {spec.repeat} timed round(s) "
            f"({executor.name} executor)")
    last = {}
    log.set_total(len(built))
    for (name, solver), (single, batched) in zip(built.items(),
                                                 executor.map(solve_method, _begun(work, log))):
        last[name] = single[-1]
        rows += _timed_rows(spec, name, solver, single, batched)
        median_s = np.median([r["time_median_s"] for r in rows[-len(spec.tasks):]])
        log.advance(1, f"{name}: {spec.repeat} x {len(spec.tasks)} trajectories solved alone, "
                    f"median {median_s:.4f} s per trajectory")
    return rows, built, last


def _begun(work: list, log: Progress) -> Iterator:
    """The jobs, each counted as begun when the executor takes it (the local one: just
    before it runs; a pool: all at once)."""
    for job in work:
        log.say(f"{job[0]}: solving")  # the status names the method now running
        log.begin(1)
        yield job


def _record(spec: CompareSpec, built: dict[str, Method], rows: list[dict],
            last: dict[str, list[Outcome]]) -> RunRecord:
    """What run.json records: the methods and settings, the robot, targets and contract,
    each method's scheme and backend, the methods whose trajectories are the same, the
    libraries' versions, the provenance and any obstacles."""
    targets, contract = spec.targets, spec.contract
    obstacles = ({"source": targets.obstacles_source,
                  "items": [o.to_dict() for o in targets.obstacles]}
                 if targets.obstacles else None)
    return RunRecord(
        kind="compare", methods=list(spec.methods), robot=spec.robot.describe(),
        targets=targets.source, trajectories=targets.ids, steps=targets.steps,
        obstacles=obstacles, provenance=provenance(),
        study={"reference": spec.reference, "repeat": spec.repeat, "warmup": spec.warmup,
               "contract": contract.to_dict(), "tolerances": dict(contract.tolerances),
               "schemes": {name: solver.scheme_label() for name, solver in built.items()},
               "runtimes": {name: solver.runtime() for name, solver in built.items()},
               "collision_avoidance": _collision_avoidance(spec.robot, built),
               "identical": identical_methods(last),
               "libraries": library_versions(sorted({r["library"] for r in rows
                                                     if r["library"]}))})


def _collision_avoidance(robot: Robot, built: dict[str, Method]) -> dict[str, str]:
    """By method, what it does itself about collisions, inside its own time (a method's
    ``collision_avoidance(robot)``, e.g. ours-lm's "avoids self-collision (convex hulls of the
    URDF meshes, coal)"); methods that do nothing are left out."""
    labels = {name: getattr(solver, "collision_avoidance", lambda _: None)(robot)
              for name, solver in built.items()}
    return {name: label for name, label in labels.items() if label}


def identical_methods(last: dict[str, list[Outcome]], tolerance: float = IDENTICAL_TOLERANCE
                      ) -> list[list[str]]:
    """Groups of two or more methods whose trajectories are the same on every task (every pose
    within ``tolerance`` [pose units]): they ran the same scheme on the same solver, so their
    rows are one result shown twice (pink and mink: the shared tracking scheme over the same
    QP)."""
    def poses(outcomes: list[Outcome]) -> list[np.ndarray] | None:
        if any(o.solution is None for o in outcomes):
            return None
        return [np.asarray(o.solution.poses) for o in outcomes]  # type: ignore[union-attr]

    solved = {name: p for name, outcomes in last.items() if (p := poses(outcomes)) is not None}
    groups: list[list[str]] = []
    for name, mine in solved.items():
        for group in groups:
            theirs = solved[group[0]]
            if len(mine) == len(theirs) and all(
                    a.shape == b.shape and np.max(np.abs(a - b)) <= tolerance
                    for a, b in zip(mine, theirs)):
                group.append(name)
                break
        else:
            groups.append([name])
    return [g for g in groups if len(g) > 1]


def _write_tables(stage: RunStage, results: pd.DataFrame, board: pd.DataFrame,
                  record: RunRecord, contract: Contract, sweep_frame: pd.DataFrame | None
                  ) -> None:
    """Write results.csv, leaderboard.csv / .md, pareto_sweep.csv (with a sweep), pareto.png
    and run.json (the method folders are :func:`ikbench.studies.run.write_run`'s)."""
    stage.csv("results.csv", results, float_format="%.10g")
    stage.csv("leaderboard.csv", board, float_format="%.6g")
    stage.text("leaderboard.md", leaderboard_markdown(board, record.to_dict(), contract))
    if sweep_frame is not None:
        stage.csv("pareto_sweep.csv", sweep_frame, float_format="%.8g")
    stage.figure("pareto.png", plot_pareto(results, sweep_frame, contract))
    stage.record(record)


def _build(spec: CompareSpec, log: Progress) -> tuple[list[dict], dict[str, Method]]:
    """Rows for the methods that cannot run (unavailable, refused) and the others built."""
    status = method_status()
    rows, built = [], {}
    for k, name in enumerate(spec.methods):
        cls = status[name].cls
        if cls is None:
            log.note(f"{name} ({k + 1}/{len(spec.methods)}): not installed: "
                     f"{status[name].reason}")
            rows += [_row(spec, name, "", task, "not installed", status[name].reason)
                     for task in spec.tasks]
            continue
        try:
            solver = spec.solvers.get(name) or cls()
            solver.check_tasks(spec.robot, spec.tasks)
        except IkbenchError as exc:  # a method that cannot take these tasks is a row too
            rows += [_row(spec, name, cls.library, task, "refused", str(exc))
                     for task in spec.tasks]
            continue
        except Exception as exc:  # a bug in the method: a failed row, not "refused"
            rows += [_row(spec, name, cls.library, task, "failed", describe(exc))
                     for task in spec.tasks]
            continue
        built[name] = solver
    return rows, built


def solve_method(job: tuple) -> tuple[list, list]:
    """``warmup + repeat`` rounds of one method (in a worker): each task solved alone, and,
    for a batched method, all tasks in one call too. Returns the timed rounds (single, each a
    list of outcomes; batched, likewise, empty for methods that do not batch)."""
    name, solver, robot, tasks, warmup, repeat = job
    quiet = Progress(name, enabled=False)
    single: list[list[Outcome]] = []
    batched: list[list[Outcome]] = []
    both = solver.capabilities.batched and len(tasks) > 1
    solves, done = (warmup + repeat) * len(tasks) * (2 if both else 1), 0
    for _ in range(warmup + repeat):
        single.append([])
        for task in tasks:
            single[-1].append(solve_tasks(solver, robot, [task], quiet)[0])
            done += 1
            report_fraction(done, solves)  # the trajectories solved of the method's rounds
        if both:
            batched.append(solve_tasks(solver, robot, tasks, quiet))
            done += len(tasks)
            report_fraction(done, solves)
    return single[warmup:], batched[warmup:]


def _timed_rows(spec: CompareSpec, name: str, solver: Method, single: list, batched: list
                ) -> list[dict]:
    """One row per task of a method's timed rounds: status, times, iterations, scheme."""
    missing = [pose for pose in spec.contract.fixed_poses if pose not in solver.fixed_poses()]
    rows = []
    for j, outcome in enumerate(single[-1]):
        times = [run[j].wall_s for run in single]
        status = "failed" if not outcome.ok else (
            f"does not honour: {', '.join(p.replace('_', ' ') for p in missing)}"
            if missing else "solved")
        row = _row(spec, name, solver.library, outcome.task, status, outcome.failure or "")
        row.update(time_median_s=float(np.median(times)), time_min_s=float(min(times)),
                   time_max_s=float(max(times)), repetitions=spec.repeat,
                   iterations=outcome.solution.iterations if outcome.ok else np.nan,
                   scheme=solver.scheme_label(),
                   fixed_poses=" ".join(sorted(solver.fixed_poses())),
                   time_batched_s=float(np.median([run[j].wall_s for run in batched]))
                   if batched else np.nan)
        rows.append(row)
    return rows


def _row(spec: CompareSpec, method: str, library: str, task: Task, status: str,
         failure: str) -> dict:
    version = library_versions([library]).get(library) if library else None
    return {"method": method, "library": library, "library_version": version,
            "robot": spec.robot.name, "task": spec.targets.source, "trajectory": task.name,
            "status": status, "failure": failure, "repetitions": 0}


def measure(spec: CompareSpec, results: pd.DataFrame, built: dict[str, Method],
            files: dict[str, dict[str, TrajectoryFile]]) -> pd.DataFrame:
    """Measure every trajectory as its file holds it (``files``: by method, by trajectory,
    :func:`ikbench.studies.run.trajectory_files`) and judge it on both tracks."""
    contract = spec.contract
    by_name = {t.name: t for t in spec.tasks}
    figures = {(name, tid): {**contract_metrics(spec.robot, by_name[tid], file.poses, contract),
                             **_legibility(spec, by_name[tid], file.poses)}
               for name, method_files in files.items() for tid, file in method_files.items()}
    columns = ("within_limits", *METRICS, *CONTRACT_METRICS, *LEGIBILITY_COLUMNS,
               *(COLLISION_METRICS if contract.obstacles else ()))
    status = method_status()
    rows = []
    for row in results.to_dict("records"):
        measured = figures.get((row["method"], row["trajectory"]), {})
        out = {**row, "track": contract.track, **{c: measured.get(c, np.nan) for c in columns}}
        if contract.obstacles:
            cls = built[row["method"]] if row["method"] in built else \
                status[row["method"]].cls if row["method"] in status else None
            avoids = avoids_obstacles(cls, spec.tasks)
            out.update(obstacles=len(by_name[row["trajectory"]].required.obstacles),
                       avoids_obstacles=avoids)
            if (measured.get("env_collisions") or 0) > 0 and not avoids \
                    and not str(row.get("failure") or ""):
                out["failure"] = NO_AVOIDANCE
        rows.append(out)
    return judge_rows(pd.DataFrame(rows).reindex(columns=columns_for(contract)), contract,
                      contract.with_track("touch"))


def judge_rows(results: pd.DataFrame, contract: Contract, touch: Contract) -> pd.DataFrame:
    """The ``ok_*`` columns, ``success`` (the contract's track) and ``success_touch``."""
    status = results["status"].astype(str)
    honours = ~status.str.startswith("does not honour")
    solved = (status == "solved") | ~honours
    rows = []
    for row, ok in zip(results.to_dict("records"), solved):
        verdict = judge(contract, row) if ok else {}
        touch_verdict = judge(touch, row) if ok else {}
        out = {**row, "ok_solved": bool(ok),
               "ok_honours": (not str(row["status"]).startswith("does not honour"))
               if ok else None}
        for name in contract.criterion_names():
            out[f"ok_{name}"] = verdict.get(name, touch_verdict.get(name))
        out["success"] = bool(ok and out["ok_honours"] and all(verdict.values()))
        out["success_touch"] = bool(ok and all(touch_verdict.values()))
        rows.append(out)
    return pd.DataFrame(rows).reindex(columns=columns_for(contract))


#: c0 values of ours-lm's weight sweep drawn in pareto.png (the paper's other weights).
SWEEP_C0 = (0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0)


def ours_lm_sweep(robot: Robot, tasks: Sequence[Task], contract: Contract,
                  solvers: dict[str, Method]) -> pd.DataFrame:
    """ours-lm solved at each c0 of :data:`SWEEP_C0` (one batched call each), one row per c0:
    the median over the tasks of each trajectory's largest distance from the line
    (``line_distance_max_median_mm``) and the largest of them (``line_distance_max_worst_mm``,
    the leaderboard's figure), the median of the judged pointing means, the largest share of
    the speed limit used and the share of trajectories meeting the contract."""
    base = solvers.get(REFERENCE_METHOD)
    cls = type(base) if base is not None else get_method(REFERENCE_METHOD)
    rows = []
    for c0 in SWEEP_C0:
        solver = cls(weights=f"c0={c0:g}")
        outcomes = solve_tasks(solver, robot, tasks, Progress("sweep", enabled=False))
        figures = [contract_metrics(robot, o.task, o.solution.poses, contract)
                   for o in outcomes if o.solution is not None]
        met = [all(judge(contract, f).values()) for f in figures]
        rows.append({"c0": c0, "weights": f"c0={c0:g} (others the paper's)",
                     "line_distance_max_median_mm": float(np.median(
                         [f["line_distance_max_mm"] for f in figures])),
                     "line_distance_max_worst_mm": float(np.max(
                         [f["line_distance_max_mm"] for f in figures])),
                     "pointing_deviation_judged_mean_median_deg": float(np.median(
                         [f["pointing_deviation_judged_mean_deg"] for f in figures])),
                     "speed_limit_use": float(np.max([f["speed_limit_use"] for f in figures])),
                     "success_share": float(np.mean(met)) if met else 0.0,
                     "trajectories": len(figures)})
    return pd.DataFrame(rows)


# ----- legibility (ikbench.core.legibility) ----------------------------------------------------
def goal_set_mm(spec: CompareSpec) -> np.ndarray:
    """The goals (K, 3) [mm] of the legibility columns: the touch points of ``spec.goals``,
    else of the spec's targets."""
    return goal_points_mm(spec.robot, spec.goals or spec.targets)[1]


def _legibility(spec: CompareSpec, task: Task, poses: np.ndarray) -> dict[str, float]:
    """:data:`LEGIBILITY_COLUMNS` of one trajectory as its CSV holds it (constant timing over
    the contract's duration, the CSV's time column), its task's touch point the true goal."""
    fk = spec.robot.fk(poses)
    goals, true = true_goal_index(goal_set_mm(spec), task.goal.end_point_mm)
    return legibility_metrics(fk.point_mm, fk.direction, poses, goals, true,
                              constant_times_s(len(poses), spec.contract.duration_s))


def legibility_curves(spec: CompareSpec, files: dict[str, dict[str, TrajectoryFile]]
                      ) -> dict[str, dict[str, dict[str, np.ndarray]]]:
    """By method, by trajectory: ``times_s``, ``position`` and ``pointing`` P(true goal)
    (n+1,) of the position and pointing observers."""
    by_name = {t.name: t for t in spec.tasks}
    curves: dict[str, dict[str, dict[str, np.ndarray]]] = {}
    for name, method_files in files.items():
        for tid, file in method_files.items():
            fk = spec.robot.fk(file.poses)
            goals, true = true_goal_index(goal_set_mm(spec), by_name[tid].goal.end_point_mm)
            times_s = constant_times_s(len(file.poses), spec.contract.duration_s)
            curves.setdefault(name, {})[tid] = {
                "times_s": times_s,
                "position": position_probabilities(fk.point_mm, goals, times_s)[:, true],
                "pointing": pointing_probabilities(fk.point_mm, fk.direction, goals)[:, true]}
    return curves


def _write_legibility_figures(stage: RunStage, spec: CompareSpec,
                              files: dict[str, dict[str, TrajectoryFile]]) -> None:
    """legibility_<method>.png per method and legibility.png across methods."""
    curves = legibility_curves(spec, files)
    goals = len(goal_set_mm(spec))
    for name, by_trajectory in curves.items():
        stage.figure(f"legibility_{name}.png",
                     plot_method_legibility(name, by_trajectory, goals))
    if curves:
        stage.figure("legibility.png", plot_legibility_summary(curves, goals))
