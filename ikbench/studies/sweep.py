"""Weight sweep: the paper's objective with other weights, solved by ours-lm, on any shape.

:func:`sweep` takes a grid of loss weights (``{"L0": [1, 10, 100], "L1": [5, 50]}``), solves
every setting on every task in one batched ``ours-lm`` call and measures each trajectory with
:mod:`ikbench.core.metrics`. Terms not in the grid keep the *reference* weights: the paper's for the
line (its targets) and for polylines and splines, the paper's letter setting (c0=1, c1=50,
c6=1, others 0: ``Task.hints.default_weights``) for letters. The reference setting is always one of
the settings (column ``paper_weights`` True; ``paper_loss`` is the objective with the reference
weights). Per setting, the figures are averaged over the tasks (errors: worst task). A setting
whose weights are all 0 for the tasks is refused.

The accuracy axis is the mean *line distance* for lines and the mean *point error* (distance
of each fingertip point from its own goal point, pen-down points only) for other shapes; a
setting is *Pareto-optimal* when no other setting has both a smaller accuracy figure and a
smaller mean pointing deviation.

Output (:func:`write`): ``sweep.csv`` (one row per setting), ``sweep_trajectories.csv`` (one
row per setting and task), ``pareto.png`` (accuracy vs pointing deviation, smoothness as
colour), ``sweep.json`` (settings, provenance) and ``sweep.md`` (findings).
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pandas as pd

from ikbench.core.budget import check_memory
from ikbench.core.errors import InputError
from ikbench.core.io import write_study_files
from ikbench.core.letters import DEFAULT_SIZE_MM
from ikbench.core.losses import PAPER_WEIGHTS, TERMS, objective
from ikbench.core.metrics import shape_metrics, trajectory_metrics
from ikbench.core.provenance import provenance
from ikbench.core.robot import Robot, as_robot
from ikbench.core.targets import Targets, load_targets
from ikbench.core.task import build_tasks, letter_start_pose, parse_shape
from ikbench.methods.ours_exact import ExactSettings, OursExact
from ikbench.methods.ours_lm import LMSettings, OursLM
from ikbench.render.run_report import markdown_table
from ikbench.runtime.executors import Executor, LocalExecutor
from ikbench.runtime.parallel import solve_parts
from ikbench.runtime.progress import Reporter
from ikbench.studies.batch import MAX_COUNT

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ikbench.core.task import Task
    from ikbench.methods.ours_lm.solver import BatchResult

#: The methods a sweep runs, named by their classes: ours-lm (the paper's objective, every
#: weight) and ours-exact (the path and poses exact: the pointing and smoothness weights).
OURS_LM, OURS_EXACT = OursLM.name, OursExact.name
#: Per-trajectory figures averaged (mean) or taken at the worst target (max) per setting.
MEAN_COLUMNS = ("line_distance_mean_mm", "pointing_deviation_mean_deg",
                "mean_sq_joint_step_deg2", "loss", "paper_loss", "iterations")
MAX_COLUMNS = ("line_distance_std_mm", "start_point_error_mm", "end_point_error_mm",
               "end_pose_error_deg", "max_joint_step_deg")
#: The same for shapes other than the line (letters, polylines, splines).
SHAPE_MEAN_COLUMNS = ("point_error_mean_mm", "curve_distance_mean_mm",
                      "pointing_deviation_mean_deg", "mean_sq_joint_step_deg2", "loss",
                      "paper_loss", "iterations")
SHAPE_MAX_COLUMNS = ("point_error_max_mm", "curve_distance_max_mm", "pointing_deviation_max_deg",
                     "max_joint_step_deg")


@dataclass(frozen=True)
class Measures:
    """What a sweep summarises: line tasks or general shapes.

    Attributes:
        accuracy: the per-setting column of the Pareto front's accuracy axis [mm].
        accuracy_name: its name in sentences and axis labels.
        target: what the fingertip should follow (``"line"``, ``"shape"``).
        mean_columns / max_columns: per-trajectory figures averaged / maximised per setting.
        table_columns: the columns of sweep.md's tables.
        unit / log: the accuracy axis' unit and scale.
        colour / colour_name: the column shown as colour in pareto.png, and its label.
    """

    accuracy: str
    accuracy_name: str
    target: str
    mean_columns: tuple
    max_columns: tuple
    table_columns: tuple
    unit: str = "mm"
    log: bool = True
    colour: str = "mean_sq_joint_step_deg2"
    colour_name: str = "smoothness: mean squared joint step [deg$^2$]"


LINE_MEASURES = Measures(
    "line_distance_mean_mm", "line distance", "line", MEAN_COLUMNS, MAX_COLUMNS,
    ("setting", "line_distance_mean_mm", "pointing_deviation_mean_deg",
     "mean_sq_joint_step_deg2", "max_joint_step_deg", "end_point_error_mm",
     "end_pose_error_deg", "loss", "paper_loss", "converged", "pareto"))
SHAPE_MEASURES = Measures(
    "point_error_mean_mm", "point error", "shape", SHAPE_MEAN_COLUMNS, SHAPE_MAX_COLUMNS,
    ("setting", "point_error_mean_mm", "point_error_max_mm", "curve_distance_mean_mm",
     "curve_distance_max_mm", "pointing_deviation_mean_deg", "pointing_deviation_max_deg",
     "mean_sq_joint_step_deg2", "max_joint_step_deg", "loss", "paper_loss", "converged",
     "pareto"))


#: ours-exact holds the path exactly: its trade-off is smoothness against pointing.
EXACT_LINE_MEASURES = replace(
    LINE_MEASURES, accuracy="mean_sq_joint_step_deg2",
    accuracy_name="smoothness (mean squared joint step)", unit="deg^2", log=False,
    colour="max_joint_step_deg", colour_name="largest joint step [deg]")
EXACT_SHAPE_MEASURES = replace(
    SHAPE_MEASURES, accuracy="mean_sq_joint_step_deg2",
    accuracy_name="smoothness (mean squared joint step)", unit="deg^2", log=False,
    colour="max_joint_step_deg", colour_name="largest joint step [deg]")


def measures_of(frame: pd.DataFrame, method: str = OURS_LM) -> Measures:
    """:data:`SHAPE_MEASURES` for a frame of shape figures, else :data:`LINE_MEASURES` (their
    ``EXACT_`` forms for ``ours-exact``, whose path is exact)."""
    shape = "point_error_mean_mm" in frame.columns
    if method == OURS_EXACT:
        return EXACT_SHAPE_MEASURES if shape else EXACT_LINE_MEASURES
    return SHAPE_MEASURES if shape else LINE_MEASURES


def parse_grid(items: list[str] | str) -> dict[str, list[float]]:
    """``["c0=1,10,100", "c1=5,50"]`` -> ``{"L0": [1, 10, 100], "L1": [5, 50]}``."""
    items = [items] if isinstance(items, str) else list(items or [])
    if not items:
        raise InputError("--weight: give at least one term and its values, e.g. c0=1,10,100")
    grid = {}
    for item in items:
        key, sep, values = str(item).partition("=")
        term = key.strip().upper().replace("C", "L", 1)
        try:
            numbers = [float(v) for v in values.split(",")] if sep else []
        except ValueError:
            numbers = []
        if term not in TERMS or not numbers or not all(np.isfinite(v) and v >= 0
                                                        for v in numbers):
            raise InputError(f"--weight: {item!r} is not term=v1,v2,... with term in c0..c6 "
                             "(or L0..L6) and values finite numbers >= 0, e.g. c0=1,10,100")
        if term in grid:
            raise InputError(f"--weight: term {key.strip()!r} is given twice")
        grid[term] = list(dict.fromkeys(numbers))
    return grid


def setting_label(weights: dict[str, float], grid_terms: Iterable[str]) -> str:
    """``"c0=100,c1=50"`` for the grid's terms of a weights dict."""
    return ",".join(f"c{t[1]}={weights[t]:g}" for t in grid_terms)


def grid_settings(grid: dict[str, list[float]], base: dict | None = None) -> list[dict]:
    """Every combination of the grid on top of ``base`` (default the paper's), ``base`` first.

    Raises:
        InputError: a combination sets every weight to 0 (its loss would be empty).
    """
    base = dict(base or PAPER_WEIGHTS)
    out = [base]
    for values in itertools.product(*grid.values()):
        weights = {**base, **dict(zip(grid, values))}
        if not any(weights.values()):
            rest = sorted(set(TERMS) - set(grid))
            others = (f" and the other terms ({', '.join(f'c{t[1]}' for t in rest)}) are 0"
                      if rest else "")
            raise InputError(f"--weight: the setting {setting_label(weights, grid)!r}{others}: "
                             "every weight is 0 and the loss would be empty; give each "
                             "setting at least one weight > 0")
        if weights not in out:
            out.append(weights)
    return out


def effective_weights(weights: dict[str, float], task: Task) -> dict[str, float]:
    """``weights`` with c2 / c3 set to 0 where ``task`` pins no start / end pose."""
    return {**weights, "L2": weights["L2"] if task.required.start_pose is not None else 0.0,
            "L3": weights["L3"] if task.required.end_pose is not None else 0.0}


@dataclass
class SweepResult:
    """Per-setting summary, per-trajectory rows, and the record (grid, provenance).
    :meth:`write` writes the files."""

    settings: pd.DataFrame
    trajectories: pd.DataFrame
    record: dict

    def write(self, folder: str | Path) -> Path:
        """Write sweep.csv, sweep_trajectories.csv, pareto.png, sweep.json and sweep.md into
        ``folder``; return sweep.csv's path."""
        pareto = partial(plot_pareto, self.settings,
                         reference=self.record.get("reference", "the paper's weights"),
                         method=self.record.get("method", OURS_LM))
        return write_study_files(folder, "sweep",
                                 {"sweep.csv": (self.settings, "%.6g"),
                                  "sweep_trajectories.csv": (self.trajectories, "%.6g")},
                                 self.record, lambda: markdown(self), {"pareto.png": pareto})


@dataclass(frozen=True)
class SweepSpec:
    """A weight sweep: the grid (:func:`parse_grid`), the robot, the targets as swept and the
    tasks of one setting with the shape's kind (:func:`sweep_tasks`), the shape and its
    options, ours-lm's settings, the executor, the method and the progress lines.
    :meth:`validate` checks the rest; :func:`run` runs it (:mod:`ikbench.studies.shape`)."""

    grid: dict[str, list[float]]
    robot: Robot
    targets: Targets
    tasks: tuple[Task, ...]
    kind: str
    shape: str = "line"
    size_mm: float | None = None
    direction: str | npt.ArrayLike | None = None
    lm_settings: LMSettings | None = None
    executor: Executor | None = None
    method: str = OURS_LM
    progress: bool = True

    def validate(self) -> None:
        """InputError (the CLI's one-line message) for a method the sweep cannot run or a grid
        term it has no weight for, or a grid too large, before anything runs."""
        check_sweep_method(self.method, self.grid, self.executor)
        check_grid_size(self.grid, list(self.tasks), self.robot.dof)


def sweep(grid: dict[str, list[float]], *, targets: str | Path | Targets | None = None,
          only: str | None = None, steps: int | None = None, shape: str = "line",
          size_mm: float | None = None, start_pose: npt.ArrayLike | None = None,
          direction: str | npt.ArrayLike | None = None, lm_settings: LMSettings | None = None,
          progress: bool = True, robot: Robot | str | None = None,
          executor: Executor | None = None, method: str = OURS_LM) -> SweepResult:
    """Solve the tasks of a shape for every weight setting of ``grid`` (module docstring).

    Args:
        grid: term (L0..L6) -> weights to try; other terms keep the reference weights.
        targets: a targets file, :class:`Targets`, or None for the paper's (the line's touch
            poses and the start pose).
        only: trajectory ids to keep (``"1,3"``; the line only).
        steps: number of segments n (default: the targets file's for the line, 100 for
            other shapes).
        shape: ``line``, ``polyline:FILE``, ``spline:FILE`` or ``letter:X[,Y...]``
            (:func:`ikbench.core.task.build_tasks`).
        size_mm: letter height [mm] (default 300).
        start_pose: (dof,) start pose [pose units] replacing the targets file's (default for
            letters: the robot's letter start pose, NICO's the paper's).
        direction: goal directions ``"tangent"``, ``"normal"`` or a vector (default: the
            shape's own).
        lm_settings: ours-lm settings (their weights are replaced by the grid's).
        progress: progress lines on stderr.
        robot: the robot or its name/config/URDF (default NICO's right arm).
        executor: where the solve runs (:mod:`ikbench.runtime.executors`; default: one
            batched call in this process); the numbers do not depend on it.
        method: ``ours-lm`` (the paper's objective) or ``ours-exact`` (the path and poses
            exact; the grid may hold only c1, the pointing weight, and c6, the smoothness
            weight; the reference is ours-exact's default c1 and c6; in this process only).

    Raises:
        InputError: bad shape, options or a setting whose weights are all 0 for the tasks.
    """

    check_sweep_method(method, grid, executor)
    robot = as_robot(robot)
    swept, tasks, kind = sweep_tasks(robot, targets, shape, only, steps, size_mm, start_pose,
                                     direction)
    spec = SweepSpec(grid, robot, swept, tuple(tasks), kind, shape, size_mm, direction,
                     lm_settings, executor, method, progress)
    spec.validate()
    return run(spec)


def run(spec: SweepSpec) -> SweepResult:
    """Solve the tasks of ``spec`` for every weight setting of its grid (validated:
    :meth:`SweepSpec.validate`); nothing is written (:meth:`SweepResult.write` writes it)."""
    grid, robot, targets, tasks, kind = (spec.grid, spec.robot, spec.targets, list(spec.tasks),
                                         spec.kind)
    shape, size_mm, direction, lm_settings = (spec.shape, spec.size_mm, spec.direction,
                                              spec.lm_settings)
    executor, method, progress = spec.executor, spec.method, spec.progress
    base, settings = _sweep_settings(tasks, grid, shape, method)
    all_tasks = [task for _ in settings for task in tasks]
    all_weights = [w for w in settings for _ in tasks]
    log = Reporter("sweep", total=len(all_tasks), unit="trajectory", enabled=progress)
    how = ("one batched ours-lm solve" if method == OURS_LM
           else f"{len(settings)} batched ours-exact solves")
    log.note(f"{len(settings)} weight settings x {len(tasks)} tasks ({shape}): {how} of "
             f"{len(all_tasks)} trajectories, then each measured")
    log.say("solving")
    result: BatchResult | _ExactBatch
    if method == OURS_LM:
        result, _ = solve_parts(executor, robot, all_tasks, lm_settings or LMSettings(),
                                all_weights)
    else:
        result = _solve_exact(robot, tasks, settings)
    log.note(f"solved in {result.duration_s:.2f} s; measuring")
    with log:
        per_traj = pd.DataFrame(_trajectory_rows(robot, kind, grid, base, all_tasks,
                                                 all_weights, result, log))
    record = {"grid": {f"c{t[1]}": v for t, v in grid.items()}, "robot": robot.describe(),
              "targets": targets.source,
              "shape": shape, "size_mm": (size_mm or DEFAULT_SIZE_MM) if kind == "letter" else None,
              "direction": direction, "start_pose_deg": targets.start_pose.tolist(),
              "reference_weights": {f"c{t[1]}": base[t] for t in TERMS},
              "reference": reference_name(kind) if method == OURS_LM
              else "ours-exact's default weights", "method": method,
              "trajectories": [t.name for t in tasks], "steps": tasks[0].goal.steps,
              "solve_wall_time_s": result.duration_s, "trajectories_solved": len(all_tasks),
              **(executor or LocalExecutor()).describe(), **provenance()}
    return SweepResult(summarise(per_traj, method), per_traj, record)


def sweep_tasks(robot: Robot, targets: str | Path | Targets | None, shape: str,
                only: str | None, steps: int | None, size_mm: float | None,
                start_pose: npt.ArrayLike | None, direction: str | npt.ArrayLike | None
                ) -> tuple[Targets, list[Task], str]:
    """(the targets as swept, the tasks of one setting, the shape's kind) for :func:`sweep`'s
    options: letters start from the robot's letter start pose unless ``start_pose`` is given;
    ``only`` selects touch poses (the line only) and ``steps`` sets the line's segments.

    Raises:
        InputError: bad targets, shape or options.
    """
    if not isinstance(targets, Targets):
        targets = load_targets(targets, robot)
    kind, _ = parse_shape(shape)
    if kind == "letter" and start_pose is None:
        start_pose = letter_start_pose(robot, targets)
    if start_pose is not None:
        targets = replace(targets, start_pose=robot.check_pose(start_pose, "start_pose"))
    if only and kind != "line":
        raise InputError(f"--only selects touch poses of the line shape; shape {shape!r} has "
                         "none (name the letters in the shape instead, e.g. letter:P,A)")
    targets = targets.select(only)
    if kind == "line":
        targets = targets.with_steps(steps)
    return targets, build_tasks(robot, targets, shape, steps, size_mm, direction), kind


def _sweep_settings(tasks: list[Task], grid: dict[str, list[float]], shape: str, method: str
                    ) -> tuple[dict[str, float], list[dict]]:
    """(the reference weights, every setting of ``grid`` on top of them, the reference
    first): the tasks' own default weights (the paper's when they have none), or ours-exact's
    defaults for ``method`` ours-exact.

    Raises:
        InputError: the tasks have different default weights, or a setting weights nothing
            but poses the tasks do not pin (its loss would be empty).
    """
    defaults = {json.dumps(t.hints.default_weights, sort_keys=True) for t in tasks}
    if len(defaults) != 1:  # not for any shape ikbench makes today
        raise InputError(f"--shape: {shape!r} makes tasks with different default weights; "
                         "sweep one kind of shape at a time")
    base = dict(tasks[0].hints.default_weights or PAPER_WEIGHTS)
    if method == OURS_EXACT:
        base = exact_reference_weights()
    settings = grid_settings(grid, base)
    for weights in settings:
        if not any(any(effective_weights(weights, t).values()) for t in tasks):
            raise InputError(f"--weight: the setting {setting_label(weights, grid)!r} weights "
                             f"only the start/end pose terms c2, c3, which shape {shape!r} "
                             "does not pin: the loss would be empty; give another term a "
                             "weight > 0")
    return base, settings


def _trajectory_rows(robot: Robot, kind: str, grid: dict[str, list[float]],
                     base: dict[str, float], all_tasks: list[Task], all_weights: list[dict],
                     result: BatchResult | _ExactBatch, log: Reporter | None = None
                     ) -> list[dict]:
    """One row of sweep_trajectories.csv per solved trajectory (setting x task, in solve
    order): the setting and its weights, the loss with them and with the reference weights,
    iterations, convergence, limits, and the line's or shape's metrics."""
    measure = trajectory_metrics if kind == "line" else shape_metrics
    rows = []
    for k, (task, weights) in enumerate(zip(all_tasks, all_weights)):
        poses = result.poses[k]
        metrics = measure(robot, task, poses)
        rows.append({"setting": setting_label(weights, grid), "paper_weights": weights == base,
                     "trajectory": task.name,
                     **{f"c{t[1]}": weights[t] for t in TERMS},
                     "loss": float(result.loss[k]),
                     "paper_loss": objective(robot, task, poses, base)[0],
                     "iterations": int(result.iterations[k]),
                     "converged": bool(result.converged[k]),
                     "within_limits": robot.within_limits(poses), **metrics})
        if log is not None:
            log.advance(1, f"measured trajectory {task.name}, setting "
                        f"{setting_label(weights, grid)}")
    return rows


#: Memory a trajectory of the batch needs per pose and joint while it is solved and measured,
#: 8-byte numbers (about 5 KB were measured for a 51-pose NICO trajectory; 4x that).
NUMBERS_PER_POSE_JOINT = 50


def check_grid_size(grid: dict[str, list[float]], tasks: list[Task], dof: int) -> int:
    """The number of trajectories the sweep solves (every setting of ``grid``, the reference
    included, times ``tasks``); InputError, before any setting is built, when they are more
    than one batch takes (:data:`ikbench.studies.batch.MAX_COUNT`) or than memory holds
    (``dof``: the robot's joints)."""

    count = (math.prod(len(v) for v in grid.values()) + 1) * len(tasks)
    if count > MAX_COUNT:
        raise InputError(f"weight: the grid makes {count:,} trajectories ({count // len(tasks):,} "
                         f"settings x {len(tasks)} tasks), more than one batch takes, "
                         f"{MAX_COUNT:,}; give fewer values")
    size = (tasks[0].goal.steps + 1) * dof * 8 * NUMBERS_PER_POSE_JOINT
    check_memory("weight", count, "trajectories", size)
    return count


#: Methods a sweep can run, and the terms of the grid each can take.
SWEEP_METHODS = {OURS_LM: TERMS, OURS_EXACT: ("L1", "L6")}


def check_sweep_method(method: str, grid: dict[str, list[float]], executor: Executor | None
                       ) -> None:
    """InputError for an unknown method, a grid term it has no weight for, or ours-exact on
    another executor than this process."""
    if method not in SWEEP_METHODS:
        raise InputError(f"--method: {method!r} is not one of {', '.join(SWEEP_METHODS)}")
    wrong = [t for t in grid if t not in SWEEP_METHODS[method]]
    if wrong:
        raise InputError(f"--weight c{wrong[0][1]}: ours-exact holds the path and the fixed "
                         "poses exactly (constraints, no weights); its grid may hold c1 "
                         "(pointing) and c6 (smoothness)")
    if method == OURS_EXACT and executor is not None and executor.workers != 1:
        raise InputError("--executor: the ours-exact sweep runs in this process; use "
                         "--executor local")


def exact_reference_weights() -> dict:
    """ours-exact's default c1 (pointing) and c6 (smoothness), the other terms 0."""

    defaults = ExactSettings()
    return {**{t: 0.0 for t in TERMS}, "L1": defaults.pointing_weight,
            "L6": defaults.smoothness_weight}


@dataclass
class _ExactBatch:
    """ours-exact's solutions in the shape of ours-lm's BatchResult (what sweep reads)."""

    poses: np.ndarray
    loss: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    duration_s: float


def _solve_exact(robot, tasks, settings) -> _ExactBatch:
    """ours-exact solved for every weight setting (one batched call each), in order."""

    solutions = []
    for weights in settings:
        method = OursExact(pointing_weight=weights["L1"], smoothness_weight=weights["L6"])
        solutions += method.solve_many(robot, tasks)
    return _ExactBatch(np.stack([s.poses for s in solutions]),
                       np.array([s.loss for s in solutions]),
                       np.array([s.iterations for s in solutions]),
                       np.array([s.converged for s in solutions]),
                       float(sum(s.duration_s for s in solutions)))


def reference_name(kind: str) -> str:
    """How sweep.md names the reference setting of a shape kind."""
    return "the paper's letter setting" if kind == "letter" else "the paper's weights"


def summarise(per_traj: pd.DataFrame, method: str = OURS_LM) -> pd.DataFrame:
    """One row per setting: means / worst values over the tasks, and the Pareto flag.

    Line figures (``line_distance_mean_mm``, ...) or shape figures (``point_error_mean_mm``,
    ...), whichever ``per_traj`` has (:func:`measures_of`).
    """
    m = measures_of(per_traj, method)
    weight_cols = [f"c{t[1]}" for t in TERMS]
    agg = {**{c: "first" for c in weight_cols + ["paper_weights"]},
           **{c: "mean" for c in m.mean_columns}, **{c: "max" for c in m.max_columns},
           "converged": "all", "within_limits": "all"}
    table = per_traj.groupby("setting", sort=False).agg(agg).reset_index()
    x = table[m.accuracy].to_numpy()
    y = table["pointing_deviation_mean_deg"].to_numpy()
    dominated = [bool(np.any((x <= x[i]) & (y <= y[i]) & ((x < x[i]) | (y < y[i]))))
                 for i in range(len(table))]
    table["pareto"] = ~np.array(dominated)
    return table


def plot_pareto(table: pd.DataFrame, title: str = "", reference: str = "the paper's weights",
                method: str = OURS_LM) -> Figure:
    """Accuracy (line distance or point error) vs pointing deviation, smoothness as colour."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = measures_of(table, method)
    fig, ax = plt.subplots(figsize=(8, 5.5))
    smooth = table[m.colour]
    points = ax.scatter(table[m.accuracy], table["pointing_deviation_mean_deg"],
                        c=smooth, cmap="viridis", s=36, zorder=3)
    front = table[table["pareto"]].sort_values(m.accuracy)
    ax.plot(front[m.accuracy], front["pointing_deviation_mean_deg"], "-",
            color="0.5", lw=1, zorder=2, label="Pareto front")
    for _, row in front.iterrows():
        ax.annotate(row["setting"], (row[m.accuracy], row["pointing_deviation_mean_deg"]),
                    fontsize=6, xytext=(4, 3), textcoords="offset points")
    paper = table[table["paper_weights"]]
    ax.scatter(paper[m.accuracy], paper["pointing_deviation_mean_deg"],
               marker="*", s=260, facecolors="none", edgecolors="red", zorder=4,
               label=reference)
    if m.log:
        ax.set_xscale("log")
    ax.margins(x=0.25)
    over = "targets" if m.target == "line" else "pen-down points and tasks"
    scale = " (log)" if m.log else ""
    ax.set_xlabel(f"{m.accuracy_name}, mean over {over} [{m.unit}]{scale}")
    ax.set_ylabel(f"pointing deviation, mean over {over} [deg]")
    fig.colorbar(points, ax=ax, label=m.colour_name)
    ax.grid(alpha=0.3, which="both")
    # below the axes: inside, it can hide a setting
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2,
              frameon=False)
    ax.set_title(title or f"weight sweep ({method}): {m.accuracy_name} vs pointing")
    return fig


def _describe(row, m: Measures) -> str:
    if m.target == "line":
        accuracy = (f"line distance {row['line_distance_mean_mm']:.3g} mm, pointing deviation "
                    f"{row['pointing_deviation_mean_deg']:.2f} deg")
        error = f"worst end point error {row['end_point_error_mm']:.3f} mm"
    else:
        accuracy = (f"point error {row['point_error_mean_mm']:.3g} mm mean / "
                    f"{row['point_error_max_mm']:.3g} mm max, distance from the curve "
                    f"{row['curve_distance_mean_mm']:.3g} mm mean, pointing deviation "
                    f"{row['pointing_deviation_mean_deg']:.2f} deg")
        error = f"largest joint step {row['max_joint_step_deg']:.2f} deg"
    return (f"`{row['setting']}`: {accuracy}, mean squared joint step "
            f"{row['mean_sq_joint_step_deg2']:.2f} deg^2, {error}")


def findings(table: pd.DataFrame, reference: str = "the paper's weights",
             method: str = OURS_LM) -> list[str]:
    """Sentences saying what other weights achieve against the reference and at what cost."""
    m = measures_of(table, method)
    paper = table[table["paper_weights"]].iloc[0]
    if method == OURS_EXACT:
        return _exact_findings(table, paper, m, reference)
    objective_name = ("the paper's objective" if reference == "the paper's weights"
                      else f"the objective of {reference}")

    def describe(row) -> str:
        return _describe(row, m)

    best_line = table.loc[table[m.accuracy].idxmin()]
    best_point = table.loc[table["pointing_deviation_mean_deg"].idxmin()]
    cost = best_line["pointing_deviation_mean_deg"] - paper["pointing_deviation_mean_deg"]
    closer = paper[m.accuracy] / best_line[m.accuracy]
    lines = [f"- {reference[0].upper() + reference[1:]} ({describe(paper)}). This is the "
             f"optimum of {objective_name} itself, not an optimiser's shortfall.",
             f"- Smallest {m.accuracy_name}: {describe(best_line)}: {closer:.0f}x closer to "
             f"the {m.target}, at a cost of {cost:+.2f} deg in pointing.",
             f"- Smallest pointing deviation: {describe(best_point)}."]
    no_worse = table[table["pointing_deviation_mean_deg"]
                     <= paper["pointing_deviation_mean_deg"] + 1e-9]
    if len(no_worse):
        best = no_worse.loc[no_worse[m.accuracy].idxmin()]
        lines.append(f"- Best {m.accuracy_name} with pointing no worse than {reference}: "
                     f"{describe(best)}.")
    within_1 = table[table["pointing_deviation_mean_deg"]
                     <= paper["pointing_deviation_mean_deg"] + 1.0]
    best = within_1.loc[within_1[m.accuracy].idxmin()]
    lines.append(f"- Best {m.accuracy_name} for at most 1 deg more pointing deviation: "
                 f"{describe(best)}.")
    return lines


def write(result: SweepResult, output: str | Path) -> Path:
    """Write sweep.csv, sweep_trajectories.csv, pareto.png, sweep.json and sweep.md
    (:meth:`SweepResult.write`)."""
    return result.write(output)


def _exact_findings(table, reference_row, m: Measures, reference: str) -> list[str]:
    """ours-exact's sweep: the path is exact in every setting; smoothness against pointing."""
    error, name = (("line_distance_mean_mm", "mean line distance") if m.target == "line"
                   else ("point_error_max_mm", "largest point error"))
    smoothest = table.loc[table[m.accuracy].idxmin()]
    best_point = table.loc[table["pointing_deviation_mean_deg"].idxmin()]
    return [f"- Every setting keeps the path: the {name} is at most "
            f"{table[error].max():.2g} mm over the settings.",
            f"- {reference[0].upper() + reference[1:]}: {_describe(reference_row, m)}.",
            f"- Smoothest: {_describe(smoothest, m)}.",
            f"- Smallest pointing deviation: {_describe(best_point, m)}."]


def markdown(result: SweepResult) -> str:
    """sweep.md: the findings, the Pareto-optimal settings, and every setting."""
    rec, table = result.record, result.settings
    method = rec.get("method", OURS_LM)
    m = measures_of(table, method)
    reference = rec.get("reference", "the paper's weights")
    cols = list(m.table_columns)
    digits = {"loss": 3, "paper_loss": 3, "end_point_error_mm": 3, "end_pose_error_deg": 3,
              "line_distance_mean_mm": 3, "point_error_mean_mm": 3, "point_error_max_mm": 3,
              "curve_distance_mean_mm": 3, "curve_distance_max_mm": 3}
    grid = "; ".join(f"{k} = {', '.join(f'{v:g}' for v in vals)}"
                     for k, vals in rec["grid"].items())
    ref_weights = ", ".join(f"{k}={v:g}" for k, v in rec.get(
        "reference_weights", {f"c{t[1]}": PAPER_WEIGHTS[t] for t in TERMS}).items())
    shape = rec.get("shape", "line")
    if shape == "line":
        where = (f"on targets {rec['targets']} (trajectories {', '.join(rec['trajectories'])}, "
                 f"n = {rec['steps']})")
        figures = ("Figures are means over the targets (errors and max joint step: the worst "
                   "target)")
    else:
        size = f", {rec['size_mm']:g} mm high" if rec.get("size_mm") else ""
        direction = f", goal directions {rec['direction']}" if rec.get("direction") else ""
        where = (f"on shape `{shape}` (trajectories {', '.join(rec['trajectories'])}{size}"
                 f"{direction}, n = {rec['steps']}, start pose "
                 f"{','.join(f'{v:g}' for v in rec['start_pose_deg'])} [motor deg])")
        figures = ("Figures are over pen-down points, means over the tasks (max columns: the "
                   "worst task); `point_error`: distance of each fingertip point from its own "
                   "goal point, `curve_distance`: from the nearest point of the target curve")
    ordered = table.sort_values(m.accuracy)
    if rec.get("method", OURS_LM) == OURS_LM:
        what = "The paper's objective (L0..L6, cm and motor degrees) minimised by `ours-lm`"
        solved = "in one batched solve of"
    else:
        what = ("`ours-exact` (the path and fixed poses as hard constraints, c1 pointing over "
                "the judged part and c6 smoothness optimised)")
        solved = "solved (one batched call per setting) in"
    return "\n".join([
        "# Weight sweep", "",
        f"{what} for every "
        f"combination of {grid} (other terms keep {reference}: {ref_weights}), {where}. "
        f"{rec['trajectories_solved']} trajectories {solved} "
        f"{rec['solve_wall_time_s']:.2f} s. {figures}; `loss` is the setting's own objective, "
        f"`paper_loss` the objective with {reference} of the same poses.", "",
        "## Findings", "", *findings(table, reference, method), "",
        "![Pareto](pareto.png)", "",
        f"## Pareto-optimal settings ({m.accuracy_name} vs pointing deviation)", "",
        markdown_table(ordered[ordered["pareto"]][cols], digits), "",
        "## Every setting", "", markdown_table(ordered[cols], digits), "",
        f"Produced by ikbench (git {rec['git_revision']}) on {rec['cpu']}, "
        f"{rec['created_utc']}.", ""])
