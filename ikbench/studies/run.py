"""Run a method on a robot's tasks and write trajectories, tables, figures and a report.

``run(method, ...)`` is what ``ikbench run`` calls; it returns the table as a DataFrame.
Output layout under ``output/<name>/`` (``name`` defaults to the method's name, e.g. ``ours``):
``trajectory_<id>.csv``, ``table.csv`` (the Table 1/2 columns), ``details.csv`` (smoothness,
solver figures, failures), ``run.json`` (:class:`ikbench.runtime.record.RunRecord`: method,
robot, settings, versions, the files written, the tasks' obstacles where they have any),
``trajectories_3d.png``, ``pointing_error.png``, ``animation.gif`` (the arm playing every
trajectory, :mod:`ikbench.render.animation`; ``animation=False`` skips it) and ``report.md``.

The folder is replaced whole or not at all (:meth:`ikbench.runtime.record.RunFolder.staged`): files
an earlier run wrote there and this one does not are gone, files it did not write (notes,
``ikbench plan``'s ``*.plan.csv``) are kept. The study harness times every solve and keeps a
failed solve as a row (NaN figures, the failure in details.csv); Ctrl-C while solving never
touches the output folder (a complete run there stays): the trajectories solved so far go
beside it, to ``output/<name>.interrupted/`` (run.json says ``"interrupted": true``), or
nothing is written.

Shapes other than the paper's line (``shape=``, see :func:`ikbench.core.task.build_tasks`)
use no touch poses: a letter shape gives one trajectory per letter (``trajectory_P.csv``), a
file shape one named after the file. Their table has the general-shape columns and their
figure is ``shapes.png``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.defaults import DEFAULT_DURATION_S, DEFAULT_ROBOT
from ikbench.core.errors import InputError
from ikbench.core.io import check_folder_writable
from ikbench.core.legibility import (
    LEGIBILITY_COLUMNS,
    constant_times_s,
    goal_points_mm,
    legibility_metrics,
    true_goal_index,
)
from ikbench.core.metrics import (
    DRAWN_COVERAGE_MIN_PCT,
    DRAWN_TOLERANCE_MM,
    frame_metrics,
    shape_metrics,
    trajectory_metrics,
)
from ikbench.core.problems import load_problem, shipped_problems
from ikbench.core.provenance import provenance
from ikbench.core.robot import Robot, as_robot
from ikbench.core.targets import ID_PATTERN, Targets, load_targets
from ikbench.core.task import Task, build_tasks, parse_shape
from ikbench.core.timing import check_timing
from ikbench.core.validity import describe
from ikbench.hw.limits import timing_limits
from ikbench.methods.base import Method
from ikbench.methods.registry import get_method
from ikbench.render.animation import write_animation
from ikbench.render.pose_paths import plot_pose_path, reached
from ikbench.render.run_report import (
    FRAME_TABLE_COLUMNS,
    SHAPE_TABLE_COLUMNS,
    TABLE_COLUMNS,
    markdown_table,
    plot_pointing_error,
    plot_shapes,
    plot_trajectories_3d,
    report_sections,
)
from ikbench.runtime.harness import Interrupted, Outcome, Progress, solve_tasks
from ikbench.runtime.record import (
    ANIMATION_FILE,
    RUN_FILES,
    RunFolder,
    RunRecord,
    TrajectoryFile,
    jsonable,
    obstacles_entry,
    robot_entry,
)
from ikbench.studies.folders import RESERVED_NAMES, default_output
from ikbench.studies.shape import run_and_write

if TYPE_CHECKING:
    from ikbench.core.problems import CartesianProblem

#: Where ad-hoc runs go by default (git ignores it); ``ikbench reproduce`` writes results/.
DEFAULT_OUTPUT = default_output("run")
def check_name(name: str) -> str:
    """``name`` if it can name a run's folder; InputError naming what is allowed otherwise.

    Args:
        name: folder name under the output directory (``sequential-ik-position``).
    """
    if not isinstance(name, str) or not ID_PATTERN.fullmatch(name):
        raise InputError(f"--name: {name!r} is not allowed; a name is letters, digits, '_', "
                         "'-' and '.' (not first), as it names a folder")
    if name in RESERVED_NAMES:
        raise InputError(f"--name: {name!r} is the folder of another command; reserved: "
                         f"{', '.join(RESERVED_NAMES)}")
    return name


def evaluate(robot: Robot, outcomes: Sequence[Outcome], trajectories: dict[str, TrajectoryFile],
             method_name: str, goals_mm: np.ndarray | None = None,
             duration_s: float = DEFAULT_DURATION_S
             ) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, np.ndarray]]:
    """Metrics of the trajectories as their files hold them (:func:`trajectory_files`):
    returns (table, details, points_by_id).

    Line tasks with ``goals_mm`` (K, 3) also get the legibility figures
    (:data:`ikbench.core.legibility.LEGIBILITY_COLUMNS`, on the files' constant timing over
    ``duration_s``) in details.

    Line tasks get :func:`ikbench.core.metrics.trajectory_metrics` and the Table 1/2 columns;
    tasks with a target curve :func:`ikbench.core.metrics.shape_metrics` and
    :data:`ikbench.render.run_report.SHAPE_TABLE_COLUMNS`. A failed solve gets a row of NaN and
    its failure in details.
    """
    shaped = any(o.task.goal.curve is not None for o in outcomes)
    framed = any(o.task.goal.rotations is not None for o in outcomes)
    columns = FRAME_TABLE_COLUMNS if framed else SHAPE_TABLE_COLUMNS if shaped \
        else TABLE_COLUMNS
    measure = frame_metrics if framed else shape_metrics if shaped else trajectory_metrics
    rows, details, points_by_id = [], [], {}
    # duration_s: the solve alone as the method timed it. The harness's time around the call
    # (details: harness_wall_s) also holds what the method sets up per call and, on the first
    # call of a process, library start-up (torch's first optimiser: seconds).
    for outcome in outcomes:
        task, solution = outcome.task, outcome.solution
        if solution is None:
            rows.append({"trajectory": task.name, "method": method_name,
                         "duration_s": outcome.wall_s, **({"drawn": False} if shaped else {})})
            details.append({"trajectory": task.name, "method": method_name,
                            "converged": False, "within_limits": np.nan,
                            "failure": outcome.failure})
            continue
        poses = trajectories[task.name].poses
        metrics = measure(robot, task, poses)
        if goals_mm is not None and not (shaped or framed):
            metrics.update(_legibility(robot, task, poses, goals_mm, duration_s))
        if framed:
            metrics["time_to_valid_s"] = solution.duration_s if metrics["valid"] else np.nan
        points_by_id[task.name] = robot.fk(poses).point_mm
        rows.append({
            "trajectory": task.name, "method": method_name,
            "iterations": solution.iterations, "duration_s": solution.duration_s,
            "loss": np.nan if solution.loss is None else solution.loss,
            **{k: metrics[k] for k in columns[5:]},
        })
        extra = {k: v for k, v in metrics.items() if k not in columns}
        details.append({"trajectory": task.name, "method": method_name,
                        "converged": solution.converged,
                        "within_limits": robot.within_limits(poses),
                        **extra, "method_duration_s": solution.duration_s,
                        "harness_wall_s": outcome.wall_s, **solution.info, "failure": ""})
    return pd.DataFrame(rows, columns=columns), pd.DataFrame(details), points_by_id


def _legibility(robot: Robot, task: Task, poses: np.ndarray, goals_mm: np.ndarray,
                duration_s: float) -> dict[str, float]:
    """The legibility figures of one line trajectory, its touch point the true goal."""
    fk = robot.fk(poses)
    goals, true = true_goal_index(goals_mm, task.goal.end_point_mm)
    return legibility_metrics(fk.point_mm, fk.direction, poses, goals, true,
                              constant_times_s(len(poses), duration_s))


def goals_of(robot: Robot, targets: Targets, record: dict) -> np.ndarray | None:
    """The goal set (K, 3) [mm] of a run: ``record["goals"]`` (a targets file or
    :class:`Targets`), else the run's targets; None for shapes other than the line and
    problems."""
    if record.get("shape", "line") != "line" or record.get("problem"):
        return None
    goals = record.get("goals")
    chosen = targets if goals is None else goals if isinstance(goals, Targets) \
        else load_targets(goals, robot)
    return goal_points_mm(robot, chosen)[1]


def prepare(method: str | Method, *, robot: Robot | str | None = None,
            targets: str | Path | Targets | None = None, only: str | None = None,
            steps: int | None = None, options: dict | None = None, shape: str = "line",
            size_mm: float | None = None, start_pose: npt.ArrayLike | None = None,
            direction: str | npt.ArrayLike | None = None
            ) -> tuple[Method, Robot, Targets, list[Task]]:
    """Validate everything a run needs and build its tasks, before any solve.

    Returns:
        (solver, robot, targets, tasks).
    """
    robot = as_robot(robot)
    if not isinstance(targets, Targets):
        targets = load_targets(targets, robot)
    if start_pose is not None:
        targets = replace(targets, start_pose=robot.check_pose(start_pose, "start_pose"))
    kind, _ = parse_shape(shape)
    if only and kind != "line":
        raise InputError(f"--only selects touch poses of the line shape; shape {shape!r} has "
                         "none (name the letters in the shape instead, e.g. letter:P,A)")
    targets = targets.select(only)
    if kind == "line":
        targets = targets.with_steps(steps)  # so targets.is_paper sees a changed n
    solver = method if isinstance(method, Method) else get_method(method)(**(options or {}))
    tasks = build_tasks(robot, targets, shape, steps, size_mm, direction)
    solver.check_tasks(robot, tasks)
    return solver, robot, targets, tasks


def prepare_problem(method: str | Method, problem: str | Path, *,
                    robot: Robot | str | None = None, options: dict | None = None
                    ) -> tuple[Method, Robot, Targets, list[Task], dict[str, Any]]:
    """Validate a Cartesian path problem run and build its task, before any solve.

    Args:
        method: a method name or a configured :class:`Method`.
        problem: a shipped problem's name or a problem file (CppFlow's YAML format, see
            :mod:`ikbench.core.problems`).
        robot: None, or the problem's own robot (another one is refused).
        options: the method's settings as keywords (when ``method`` is a name).

    Returns:
        (solver, robot, targets, tasks, record): targets are the robot's own (recorded only),
        record names the problem file.
    """

    problem_robot, task, parsed = load_problem(problem)
    if robot is not None:
        given = as_robot(robot)
        if given.name != problem_robot.name:
            raise InputError(f"--robot {given.name}: the problem {parsed.name} is for robot "
                             f"{problem_robot.name!r} (leave --robot out)")
    if problem_robot.config.targets.file is not None:
        targets = load_targets(None, problem_robot)
    else:
        assert task.hints.reference_pose is not None  # problem_task sets it
        targets = Targets(problem_robot.joint_names, task.hints.reference_pose, {}, task.goal.steps,
                          "problem")
    solver = method if isinstance(method, Method) else get_method(method)(**(options or {}))
    solver.check_tasks(problem_robot, [task])
    record = {"shape": "path", "problem": problem_label(parsed), "problem_name": parsed.name}
    return solver, problem_robot, replace(targets, steps=task.goal.steps), [task], record


def problem_label(problem: CartesianProblem) -> str:
    """How reports name a problem: ``NAME (shipped)`` or its file path."""

    if shipped_problems().get(problem.name) == problem.source:
        return f"{problem.name} (shipped, CppFlow/TORM)"
    return str(problem.source)


@dataclass(frozen=True)
class RunSpec:
    """A run, as :func:`run` takes it (:mod:`ikbench.studies.shape`): ``method`` a name or a
    configured :class:`Method`, the task options as :func:`run`'s keywords (a ``problem``
    instead of targets and shapes), ``output`` the directory of the run folder (None writes
    nothing). :meth:`validate` checks the values and builds the tasks (:attr:`prepared`) before
    any solve; :func:`run_spec` solves them; :meth:`RunResult.write` writes the folder."""

    method: str | Method
    robot: Robot | str | None = None
    targets: str | Path | Targets | None = None
    only: str | None = None
    steps: int | None = None
    output: str | Path | None = DEFAULT_OUTPUT
    duration_s: float = DEFAULT_DURATION_S
    options: dict | None = None
    progress: bool = True
    shape: str = "line"
    size_mm: float | None = None
    start_pose: npt.ArrayLike | None = None
    direction: str | npt.ArrayLike | None = None
    name: str | None = None
    animation: bool = True
    problem: str | Path | None = None
    timing: str = "constant"
    goals: str | Path | Targets | None = None

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for a duration, timing or name not allowed,
        a task option given with a problem, anything :func:`prepare` or
        :func:`prepare_problem` refuses, or an output folder that cannot be written."""
        if not (self.duration_s > 0 and np.isfinite(self.duration_s)):
            raise InputError(f"--duration: {self.duration_s!r} must be a positive number of "
                             "seconds")
        check_timing(self.timing)
        if self.name is not None:
            check_name(self.name)
        if self.problem is not None:
            check_problem_options(targets=self.targets, only=self.only, steps=self.steps,
                                  shape=self.shape, size=self.size_mm,
                                  start_pose=self.start_pose, direction=self.direction)
        solver = self.prepared[0]
        if self.output is not None:  # before the solve, not after minutes of it
            check_folder_writable(Path(self.output) / (self.name or solver.name))

    @cached_property
    def prepared(self) -> tuple[Method, Robot, Targets, list[Task], dict[str, Any]]:
        """(solver, robot, targets, tasks, record): the run built and its options as run.json
        records them (``shape``, ``direction``, ``duration_s``, ``size_mm``, ``timing``,
        ``goals``, ``name``, a problem's ``problem`` and ``problem_name``); InputError for
        what cannot be built."""
        if self.problem is not None:
            solver, robot, targets, tasks, record = prepare_problem(
                self.method, self.problem, robot=self.robot, options=self.options)
            return solver, robot, targets, tasks, {
                **record, "direction": None, "duration_s": self.duration_s,
                "timing": self.timing, "name": self.name}
        solver, robot, targets, tasks = prepare(
            self.method, robot=self.robot, targets=self.targets, only=self.only,
            steps=self.steps, options=self.options, shape=self.shape, size_mm=self.size_mm,
            start_pose=self.start_pose, direction=self.direction)
        return solver, robot, targets, tasks, {
            "shape": self.shape, "direction": self.direction, "duration_s": self.duration_s,
            "size_mm": self.size_mm, "timing": self.timing, "goals": self.goals,
            "name": self.name}

    @property
    def folder(self) -> Path | None:
        """``output/<name>`` (the method's name by default); None when nothing is written."""
        if self.output is None:
            return None
        return Path(self.output) / (self.name or self.prepared[0].name)


@dataclass
class RunResult:
    """A run solved in memory: the spec, its outcomes (all tasks, or those solved before
    Ctrl-C: ``interrupted``) and the wall time of the solves [s]."""

    spec: RunSpec
    outcomes: list[Outcome]
    interrupted: bool
    total_wall_time_s: float
    _table: pd.DataFrame | None = field(default=None, repr=False)

    @property
    def table(self) -> pd.DataFrame:
        """The run's table (:func:`evaluate`), as written to table.csv."""
        if self._table is None:
            solver, robot, _, _, record = self.spec.prepared
            files = trajectory_files(robot, self.outcomes,
                                     record.get("duration_s", DEFAULT_DURATION_S))
            self._table = evaluate(robot, self.outcomes, files, solver.name)[0]
        return self._table

    def write(self, folder: Path) -> Path:
        """Write the run folder ``folder/<name>`` whole (see the module doc), or
        ``folder/<name>.interrupted`` after Ctrl-C (a complete run there stays); return it."""
        solver, robot, targets, _, record = self.spec.prepared
        run_folder = Path(folder) / (self.spec.name or solver.name)
        written = run_folder.with_name(run_folder.name + INTERRUPTED_SUFFIX) \
            if self.interrupted else run_folder
        self._table = write_run(solver, robot, targets, self.outcomes, written, {
            **record, "name": run_folder.name, "interrupted": self.interrupted,
            "total_wall_time_s": self.total_wall_time_s},
            self.spec.animation)
        return written


def run_spec(spec: RunSpec) -> RunResult:
    """Solve ``spec``'s tasks through the harness, in memory (nothing written).

    Raises:
        Interrupted: Ctrl-C before any trajectory was solved (after one: the result says
            ``interrupted``).
    """
    solver, robot, _, tasks, _ = spec.prepared
    started = time.perf_counter()
    interrupted = False
    folder = spec.folder
    try:
        outcomes = solve_tasks(solver, robot, tasks,
                               Progress(folder.name if folder else "run",
                                        enabled=spec.progress))
    except Interrupted as stop:
        if not stop.outcomes:
            raise
        outcomes, interrupted = stop.outcomes, True
    return RunResult(spec, list(outcomes), interrupted, time.perf_counter() - started)


def run_and_write_spec(spec: RunSpec) -> RunResult:
    """``spec.validate()``, :func:`run_spec` and, unless ``spec.output`` is None,
    :meth:`RunResult.write`; then Interrupted when Ctrl-C cut the solves short (with the
    folder written, if any)."""
    result = run_and_write(spec, run_spec, None if spec.output is None else Path(spec.output))
    if result.interrupted:
        written = None if spec.folder is None else \
            spec.folder.with_name(spec.folder.name + INTERRUPTED_SUFFIX)
        raise Interrupted(result.outcomes, written)
    return result


def run(method: str | Method, *, robot: Robot | str | None = None,
        targets: str | Path | Targets | None = None, only: str | None = None,
        steps: int | None = None, output: str | Path | None = DEFAULT_OUTPUT,
        duration_s: float = DEFAULT_DURATION_S, options: dict | None = None,
        progress: bool = True, shape: str = "line", size_mm: float | None = None,
        start_pose: npt.ArrayLike | None = None, direction: str | npt.ArrayLike | None = None,
        name: str | None = None,
        animation: bool = True, problem: str | Path | None = None,
        timing: str = "constant", goals: str | Path | Targets | None = None) -> pd.DataFrame:
    """Solve every selected target (or a Cartesian path problem) with ``method`` and write
    the results: builds a :class:`RunSpec` (:func:`run_and_write_spec`).

    Args:
        method: a method name (``"ours-lm"``, ...) or a configured :class:`Method`.
        robot: a :class:`Robot`, a robot name/config/URDF path, or None for NICO's right arm.
        targets: a targets file, a loaded :class:`Targets`, or None for the robot's own.
        only: comma-separated trajectory ids to keep (``"1,3"``).
        steps: number of segments n (default: the targets file's).
        output: output directory (the run writes to ``output/<name>/``); None writes
            nothing and returns the table measured in memory.
        duration_s: movement duration T [s] for the ``time_s`` column.
        options: the method's settings as keywords (when ``method`` is a name).
        progress: print progress to stderr.
        shape: ``line`` (one trajectory per touch pose), ``polyline:FILE``, ``spline:FILE``
            or ``letter:X[,Y...]``; see :func:`ikbench.core.task.build_tasks`.
        size_mm: letter height [mm] (default 300).
        start_pose: (dof,) start pose [pose units] replacing the targets file's.
        direction: goal directions ``"tangent"``, ``"normal"`` or a vector (default: the
            shape's own, see :func:`ikbench.core.task.build_tasks`).
        name: the run's folder under ``output`` (default: the method's name); letters,
            digits, ``_``, ``-``, ``.``, not one of :data:`RESERVED_NAMES`.
        animation: write ``animation.gif`` (the arm playing each trajectory; about 1-3 s
            for NICO's seven trajectories).
        problem: a Cartesian path problem (a shipped name such as ``fetch_arm__hello`` or a
            YAML file in CppFlow's format) instead of targets and shapes; the run writes
            ``trajectory_<problem name>.csv`` and :data:`FRAME_TABLE_COLUMNS`.
        timing: the timing of ``animation.gif``: ``constant``, ``min-jerk`` or ``topp``
            (:mod:`ikbench.core.timing`; the trajectory files are not retimed).
        goals: the line shape's goal set of the legibility figures (details.csv,
            report.md): a targets file or :class:`Targets` whose touch points are the goals;
            None: the run's targets (those ``only`` keeps).

    Returns:
        The table (one row per trajectory, columns :data:`ikbench.render.run_report.TABLE_COLUMNS`,
        or :data:`ikbench.render.run_report.SHAPE_TABLE_COLUMNS` for shapes other than the line).

    Raises:
        Interrupted: Ctrl-C while solving (after writing what was solved, if anything).
    """
    spec = RunSpec(method, robot=robot, targets=targets, only=only, steps=steps,
                   output=output, duration_s=duration_s, options=options, progress=progress,
                   shape=shape, size_mm=size_mm, start_pose=start_pose, direction=direction,
                   name=name, animation=animation, problem=problem, timing=timing,
                   goals=goals)
    return run_and_write_spec(spec).table


def check_problem_options(**given: Any) -> None:
    """InputError naming the first task option given with a problem (the problem defines the
    task: targets, shape, steps and start pose do not apply)."""
    defaults = {"shape": "line"}
    for key, value in given.items():
        if value is not None and value != defaults.get(key):
            flag = "--" + key.replace("_", "-")
            raise InputError(f"{flag} does not apply to --problem (the problem file defines "
                             "the path, its waypoints and the robot)")


#: The folder beside the output folder that an interrupted run writes to.
INTERRUPTED_SUFFIX = ".interrupted"


def trajectory_files(robot: Robot, outcomes: Sequence[Outcome], duration_s: float
                     ) -> dict[str, TrajectoryFile]:
    """The trajectory CSVs of the solved outcomes, by trajectory id, serialised in memory
    (:class:`ikbench.runtime.record.TrajectoryFile`: text and poses read back; pose paths
    with their end-frame orientation)."""
    return {o.task.name: TrajectoryFile.of(robot, o.task.name, o.solution.poses, duration_s,
                                           quaternion=o.task.goal.rotations is not None)
            for o in outcomes if o.solution is not None}


def write_run(solver: Method, robot: Robot, targets: Targets, outcomes: list[Outcome],
              folder: Path, record: dict, animation: bool = True,
              trajectories: dict[str, TrajectoryFile] | None = None) -> pd.DataFrame:
    """Write a run folder whole (trajectories, tables, run.json, figures, animation unless
    ``animation`` is False, report); return its table.

    Args:
        record: the run's options (:attr:`RunSpec.prepared`), ``interrupted`` and
            ``total_wall_time_s``.
        trajectories: the outcomes' :func:`trajectory_files` when the caller has them.
    """
    tasks = [o.task for o in outcomes]
    duration_s = record.get("duration_s", DEFAULT_DURATION_S)
    files = trajectory_files(robot, outcomes, duration_s) if trajectories is None \
        else trajectories
    with RunFolder(folder).staged() as stage:
        for file in files.values():
            stage.trajectory(file)
        table, details, points = evaluate(robot, outcomes, files, solver.name,
                                          goals_of(robot, targets, record), duration_s)
        stage.csv("table.csv", table)
        stage.csv("details.csv", details)
        solved = [o.task for o in outcomes if o.ok]
        title = f"{solver.name}: {solver.description}"
        figures = _figures(solver, robot, outcomes, files, points, title)
        for _, file, figure in figures:
            stage.figure(file, figure)
        if animation and solved:
            timing = record.get("timing", "constant")
            limits = None
            if timing == "topp":  # the robot's limits: NICO's motor table, else its URDF

                limits = timing_limits(robot)
            write_animation(stage.path / ANIMATION_FILE, robot, solved,
                            {t.name: files[t.name].poses for t in solved}, title, duration_s,
                            timing=timing, limits=limits)
            figures.append(("animation: the arm playing each trajectory", ANIMATION_FILE, None))
        full = RunRecord(
            kind="run", method=solver.name, name=record.get("name") or solver.name,
            library=solver.library, robot=robot_entry(robot), targets=targets.source,
            trajectories=[t.name for t in tasks],
            failed=[o.task.name for o in outcomes if not o.ok], steps=tasks[0].goal.steps,
            shape=record.get("shape", "line"), direction=record.get("direction"),
            size_mm=record.get("size_mm"), start_pose_deg=targets.start_pose.tolist(),
            # weights a task asks for (letters); ours applies --weights changes on top
            # and details.csv names the weights each trajectory was solved with
            task_default_weights=tasks[0].hints.default_weights, duration_s=duration_s,
            interrupted=bool(record.get("interrupted")),
            settings=jsonable({"settings": solver.settings_for(tasks[0])}),
            runtime=solver.runtime(), total_wall_time_s=record.get("total_wall_time_s"),
            files=sorted({*stage.files, *RUN_FILES, *(file for _, file, _ in figures)}),
            provenance=provenance(extra=(solver.library,)), problem=record.get("problem"),
            problem_name=record.get("problem_name"), obstacles=obstacles_entry(tasks))
        stage.record(full)
        stage.text("report.md", method_report(
            solver, table, details, targets, full,
            {caption: file for caption, file, _ in figures}))
    return table


def _figures(solver: Method, robot: Robot, outcomes: Sequence[Outcome],
             files: dict[str, TrajectoryFile], points: dict[str, np.ndarray], title: str
             ) -> list[tuple[str, str, Any]]:
    """A run's figures: (caption, file, figure) of its pose paths (tasks with goal frames),
    its lines (trajectories_3d.png, pointing_error.png) or its shapes."""
    solved = [o.task for o in outcomes if o.ok]
    if not solved:
        return []
    if solved[0].goal.rotations is not None:

        figures: list[tuple[str, str, Any]] = []
        for outcome in outcomes:
            if outcome.solution is not None:
                task = outcome.task
                curve = reached(robot, task, outcome.solution.poses)
                figures.append((f"pose path {task.name}", f"pose_path_{task.name}.png",
                                plot_pose_path(task, {solver.name: curve},
                                               f"{task.name}: {title}", robot)))
        return figures
    if solved[0].goal.curve is None:
        poses = {t.name: files[t.name].poses for t in solved}
        return [("trajectories", "trajectories_3d.png",
                 plot_trajectories_3d(solved, points, title, robot, poses)),
                ("criterion 2", "pointing_error.png",
                 plot_pointing_error(solved, points, title))]
    return [("shapes", "shapes.png", plot_shapes(solved, points, title))]


def method_report(solver: Method, table: pd.DataFrame, details: pd.DataFrame, targets: Targets,
                  record: RunRecord, figures: dict | None = None) -> str:
    """report.md of one method's run; ``figures`` maps captions to the PNG names written."""
    figures = {"trajectories": "trajectories_3d.png",
               "criterion 2": "pointing_error.png"} if figures is None else figures
    shape = record.shape
    where = (f"Targets: {targets.source}" if shape == "line" else
             f"Shape: {shape}, start pose {record.start_pose_deg}")
    if record.problem:
        where = (f"Problem: {record.problem}, a 6-D pose path in CppFlow's format (no "
                 "start pose given)")
    name = record.name or solver.name
    heading = solver.name if name == solver.name else f"{name} ({solver.name})"
    robot = record.robot or {}
    machine = record.provenance
    lines = [f"# {heading}: {solver.description}", "",
             f"Robot: {robot.get('name', DEFAULT_ROBOT)}. {where}; trajectories "
             f"{', '.join(record.trajectories or [])}; n = {record.steps} segments. Produced "
             f"by ikbench (git {machine.get('git_revision')}) on {machine['cpu']} "
             f"({machine['cpu_count']} cores), torch {machine['packages']['torch']}.", ""]
    if record.interrupted:
        lines += ["**Interrupted (Ctrl-C)**: this folder holds only the trajectories solved "
                  "before the interruption.", ""]
    if record.failed:
        lines += [f"**Failed solves**: {', '.join(record.failed)} (their rows are empty; "
                  "details.csv gives each failure).", ""]
    units = ("the 6-D objective's (mm, deg)" if record.problem else
             "the paper's units (cm, motor degrees)")
    digits = {"loss": 3, "duration_s": 4, "iterations": 0, "time_to_valid_s": 4,
              "max_joint_change_deg": 3, "max_joint_change_mm": 3,
              **{c: 5 for c in table.columns if c.startswith(("position_error",
                                                              "rotation_error"))}}
    lines += ["## Measured", "",
              "Computed by `ikbench.core.metrics` from the trajectory CSVs in this folder. "
              f"Distances in mm, angles in degrees, loss in {units}; duration_s is the wall "
              "time of the solve alone, as the method measured it (details.csv: "
              "method_duration_s; harness_wall_s is the harness's time around the call, with "
              "per-call set-up and, for the first trajectory, library start-up).",
              "", markdown_table(table.drop(columns=["method"]), digits), ""]
    if record.problem:

        lines += ["Position error: distance of the end frame from its goal [mm]; rotation "
                  "error: the SO(3) geodesic angle |log(R_goal^T R)| [deg]; joint changes "
                  "between waypoints (revolute wrapped, prismatic in mm); path lengths in joint "
                  "space (sum of absolute changes) and of the end point. valid: CppFlow's "
                  f"criteria: {describe()}. loss: the 6-D objective of the method (mm^2, "
                  "deg^2).", ""]
    elif shape != "line":
        lines += [f"drawn: the shape is judged by what the fingertip drew, not by the "
                  f"optimiser's convergence (Solver details): every pen-down point within "
                  f"{DRAWN_TOLERANCE_MM:g} mm of the target curve and at least "
                  f"{DRAWN_COVERAGE_MIN_PCT:g} % of the curve's strokes within "
                  f"{DRAWN_TOLERANCE_MM:g} mm of the fingertip's path (stroke_coverage_pct; a "
                  "letter stopped short is not drawn). "
                  "curve_distance: distance of each fingertip point from the target curve "
                  "(its nearest point); point_error: from the point's own goal point; "
                  "pointing deviation: from the goal direction (letters: the drawing plane's "
                  "normal). Points on pen-up moves are skipped.", ""]
    if "position_legibility" in details:
        legible = details[["trajectory", *LEGIBILITY_COLUMNS]]
        lines += ["## Legibility", "",
                  "How soon an observer of the fingertip's path (position) or of the pointing "
                  "finger (pointing) infers the touch point among the goal set, predictability "
                  "against the straight line and jerk, on the trajectory files' timing "
                  "(`ikbench.core.legibility`; docs/legibility.md).", "",
                  markdown_table(legible, {**{c: 3 for c in LEGIBILITY_COLUMNS},
                                          "dimensionless_jerk": 6,
                                          "peak_joint_jerk_deg_s3": 0}), ""]
    lines += report_sections("run", method=solver.name, table=table, record=record,
                             targets=targets)
    if figures:
        lines += ["## Figures", ""]
        for caption, file in figures.items():
            lines += [f"![{caption}]({file})", ""]
    lines += ["## Solver details", "",
              markdown_table(details.drop(columns=["method"]), {"iterations_per_s": 0}), ""]
    return "\n".join(lines)
