"""Run a method on targets and write trajectories, tables, figures and a report.

``run(...)`` is what ``ikbench run`` calls; it returns the table as a DataFrame. Output layout
under ``output/<name>/`` (``name`` defaults to the method's name, e.g. ``ours``):
``trajectory_<id>.csv``, ``table.csv`` (the Table 1/2 columns), ``details.csv`` (smoothness
and solver figures), ``run.json`` (method, folder name, settings and versions),
``trajectories_3d.png``, ``pointing_error.png`` and ``report.md``. After a successful write,
``trajectory_*.csv`` files of earlier runs in that folder that this run did not write are
removed, so the folder's trajectories are exactly those its table.csv lists.

Shapes other than the paper's line (``shape=``, see :func:`ikbench.task.build_tasks`) use no
touch poses: a letter shape gives one trajectory per letter (``trajectory_P.csv``), a file
shape one named after the file. Their table has the general-shape columns
(:data:`ikbench.report.SHAPE_TABLE_COLUMNS`) and their figure is ``shapes.png`` (the drawn
curve on the drawing plane over the target curve, and the 3-D view).
"""

from __future__ import annotations

import json
import re
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.errors import InputError
from ikbench.io import atomic_savefig, atomic_write_csv, atomic_write_text, check_writable
from ikbench.methods import Method, get_method
from ikbench.metrics import shape_metrics, trajectory_metrics
from ikbench.provenance import provenance
from ikbench.report import (
    PAPER_STEPS,
    SHAPE_TABLE_COLUMNS,
    TABLE_COLUMNS,
    markdown_table,
    plot_pointing_error,
    plot_shapes,
    plot_trajectories_3d,
    table1_comparison,
)
from ikbench.robot import Robot, load_robot
from ikbench.targets import ID_PATTERN, Targets, load_targets
from ikbench.task import build_tasks, parse_shape
from ikbench.trajectory import DEFAULT_DURATION_S, read_trajectory_poses, write_trajectory_csv

DEFAULT_OUTPUT = "results"
#: Folders other commands write into an output directory; no method run may take them.
RESERVED_NAMES = ("ablation", "sweep", "batch", "letters")
#: A trajectory CSV that a run writes (``trajectory_<id>.csv``).
TRAJECTORY_FILE = re.compile(r"trajectory_(.+)\.csv")


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


def remove_stale_trajectories(folder: Path, keep) -> list[Path]:
    """Delete ``trajectory_<id>.csv`` files in ``folder`` whose id is not in ``keep``.

    Args:
        folder: a run's folder.
        keep: the trajectory ids the run wrote.

    Returns:
        The removed paths (sorted).
    """
    keep = {str(k) for k in keep}
    stale = sorted(p for p in Path(folder).glob("trajectory_*.csv")
                   if p.is_file() and (m := TRAJECTORY_FILE.fullmatch(p.name))
                   and m.group(1) not in keep)
    for path in stale:
        path.unlink()
    return stale


class Progress:
    """Progress lines on stderr: one per trajectory start/end, one per progress update."""

    def __init__(self, label: str, stream=None, enabled: bool = True):
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled

    def _print(self, text: str) -> None:
        if self.enabled:
            print(f"[{self.label}] {text}", file=self.stream, flush=True)

    def start(self, task, index: int, total: int) -> None:
        self._print(f"trajectory {task.name} ({index + 1}/{total}): solving, n = {task.steps}")

    def update(self, task, iteration: int, loss: float) -> None:
        self._print(f"trajectory {task.name}: iteration {iteration}, loss {loss:.4f}")

    def done(self, task, solution) -> None:
        loss = "" if solution.loss is None else f", loss {solution.loss:.4f}"
        flag = "" if solution.converged else " (did not meet its stopping criterion)"
        self._print(f"trajectory {task.name}: done in {solution.iterations} iterations, "
                    f"{solution.duration_s:.2f} s{loss}{flag}")


def evaluate(robot: Robot, tasks, method_dir: Path, method_name: str, solutions):
    """Metrics of the written trajectories: returns (table, details, points_by_id).

    Line tasks get :func:`ikbench.metrics.trajectory_metrics` and the Table 1/2 columns;
    tasks with a target curve :func:`ikbench.metrics.shape_metrics` and
    :data:`ikbench.report.SHAPE_TABLE_COLUMNS`.
    """
    shaped = any(task.curve is not None for task in tasks)
    columns = SHAPE_TABLE_COLUMNS if shaped else TABLE_COLUMNS
    measure = shape_metrics if shaped else trajectory_metrics
    rows, details, points_by_id = [], [], {}
    for task, solution in zip(tasks, solutions):
        poses = read_trajectory_poses(method_dir / f"trajectory_{task.name}.csv", robot)
        metrics = measure(robot, task, poses)
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
                        **extra, **solution.info})
    return pd.DataFrame(rows, columns=columns), pd.DataFrame(details), points_by_id


def run(method: str | Method = "ours", *, targets: str | Path | Targets | None = None,
        only: str | None = None, steps: int | None = None,
        output: str | Path | None = DEFAULT_OUTPUT, duration_s: float = DEFAULT_DURATION_S,
        options: dict | None = None, robot: Robot | None = None,
        progress: bool = True, shape: str = "line", size_mm: float | None = None,
        start_pose=None, direction=None, name: str | None = None) -> pd.DataFrame:
    """Solve every selected target with ``method`` and write the results.

    Args:
        method: a method name (``"ours"``, ...) or a configured :class:`Method`.
        targets: a targets file, a loaded :class:`Targets`, or None for the paper's.
        only: comma-separated trajectory ids to keep (``"1,3"``).
        steps: number of segments n (default: the targets file's).
        output: output directory (the run writes to ``output/<name>/``); None writes
            nothing and returns the table computed in a temporary directory.
        duration_s: movement duration T [s] for the ``time_s`` column.
        options: keyword options of the method (when ``method`` is a name).
        robot: the robot (default NICO's right arm).
        progress: print progress to stderr.
        shape: ``line`` (one trajectory per touch pose), ``polyline:FILE``, ``spline:FILE``
            or ``letter:X[,Y...]``; see :func:`ikbench.task.build_tasks`.
        size_mm: letter height [mm] (default 300).
        start_pose: (dof,) start pose [motor deg] replacing the targets file's.
        direction: goal directions ``"tangent"``, ``"normal"`` or a vector (default: the
            shape's own, see :func:`ikbench.task.build_tasks`).
        name: the run's folder under ``output`` (default: the method's name); letters,
            digits, ``_``, ``-``, ``.``, not one of :data:`RESERVED_NAMES`. Trajectory CSVs of
            earlier runs in that folder that this run does not write are removed.

    Returns:
        The table (one row per trajectory, columns :data:`ikbench.report.TABLE_COLUMNS`,
        or :data:`ikbench.report.SHAPE_TABLE_COLUMNS` for shapes other than the line).
    """
    if not (duration_s > 0 and np.isfinite(duration_s)):
        raise InputError(f"--duration: {duration_s!r} must be a positive number of seconds")
    if name is not None:
        check_name(name)
    robot = robot or load_robot()
    if not isinstance(targets, Targets):
        targets = load_targets(targets, robot)
    if start_pose is not None:
        targets = replace(targets, start_pose_deg=robot.check_pose(start_pose, "--start-pose"))
    kind, _ = parse_shape(shape)
    if only and kind != "line":
        raise InputError(f"--only selects touch poses of the line shape; shape {shape!r} has "
                         "none (name the letters in the shape instead, e.g. letter:P,A)")
    targets = targets.select(only)
    if kind == "line":
        targets = targets.with_steps(steps)  # so targets.is_paper sees a changed n
    tasks = build_tasks(robot, targets, shape, steps, size_mm, direction)
    solver = method if isinstance(method, Method) else get_method(method)(**(options or {}))

    if output is None:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            return _solve_and_write(robot, targets, tasks, solver, Path(tmp), duration_s,
                                    progress, shape, direction, name)
    return _solve_and_write(robot, targets, tasks, solver, Path(output), duration_s, progress,
                            shape, direction, name)


def _solve_and_write(robot, targets, tasks, solver, output: Path, duration_s, progress,
                     shape="line", direction=None, name=None):
    name = name or solver.name
    method_dir = output / name
    check_writable(method_dir / "table.csv")  # before the solve, not after minutes of it
    started = time.perf_counter()
    solutions = solver.solve_many(robot, tasks, Progress(name, enabled=progress))
    for task, solution in zip(tasks, solutions):
        write_trajectory_csv(method_dir / f"trajectory_{task.name}.csv", robot,
                             solution.poses_deg, duration_s)
    table, details, points = evaluate(robot, tasks, method_dir, solver.name, solutions)
    atomic_write_csv(method_dir / "table.csv", table, float_format="%.10g")
    atomic_write_csv(method_dir / "details.csv", details, float_format="%.10g")
    settings = {k: v for k, v in vars(solver).items() if not k.startswith("_")}
    if hasattr(solver, "settings_for"):  # the settings used: the task's weights under changes
        settings["settings"] = solver.settings_for(tasks[0])
    record = {"method": solver.name, "name": name, "targets": targets.source,
              "trajectories": [task.name for task in tasks], "steps": tasks[0].steps,
              "shape": shape, "direction": direction,
              "start_pose_deg": targets.start_pose_deg.tolist(),
              # weights a task asks for (letters); ours applies --weights changes on top and
              # details.csv names the weights each trajectory was solved with
              "task_default_weights": tasks[0].default_weights,
              "duration_s": duration_s,
              "settings": json.loads(json.dumps(settings, default=_jsonable)),
              "total_wall_time_s": time.perf_counter() - started, **provenance()}
    atomic_write_text(method_dir / "run.json", json.dumps(record, indent=2) + "\n")
    title = f"{solver.name}: {solver.description}"
    if tasks[0].curve is None:
        figures = [("trajectories", "trajectories_3d.png",
                    plot_trajectories_3d(tasks, points, title)),
                   ("criterion 2", "pointing_error.png", plot_pointing_error(tasks, points, title))]
    else:
        figures = [("shapes", "shapes.png", plot_shapes(tasks, points, title))]
    for _, file, figure in figures:
        atomic_savefig(method_dir / file, figure)
    atomic_write_text(method_dir / "report.md", method_report(
        solver, table, details, targets, record, {caption: file for caption, file, _ in figures}))
    remove_stale_trajectories(method_dir, [task.name for task in tasks])
    return table


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if hasattr(value, "__dict__"):
        return vars(value)
    return str(value)


def method_report(solver, table: pd.DataFrame, details: pd.DataFrame, targets: Targets,
                  record: dict, figures: dict | None = None) -> str:
    """report.md of one method's run; ``figures`` maps captions to the PNG names written."""
    figures = figures or {"trajectories": "trajectories_3d.png",
                          "criterion 2": "pointing_error.png"}
    shape = record.get("shape", "line")
    where = (f"Targets: {targets.source}" if shape == "line" else
             f"Shape: {shape}, start pose {record['start_pose_deg']} [motor deg]")
    name = record.get("name") or solver.name
    heading = solver.name if name == solver.name else f"{name} ({solver.name})"
    lines = [f"# {heading}: {solver.description}", "",
             f"{where}; trajectories {', '.join(record['trajectories'])}; "
             f"n = {record['steps']} segments. Produced by ikbench "
             f"(git {record.get('git_revision')}) on {record['cpu']} "
             f"({record['cpu_count']} cores), torch {record['packages']['torch']}.",
             "", "## Measured", "",
             "Computed by `ikbench.metrics` from the trajectory CSVs in this folder. Distances "
             "in mm, angles in degrees, loss in the paper's units (cm, motor degrees).", "",
             markdown_table(table.drop(columns=["method"]),
                            {"loss": 3, "duration_s": 4, "iterations": 0}), ""]
    if shape != "line":
        lines += ["curve_distance: distance of each fingertip point from the target curve "
                  "(its nearest point); point_error: from the point's own goal point; "
                  "pointing deviation: from the goal direction (letters: the drawing plane's "
                  "normal (-1, 0, 0)). Points on pen-up moves are skipped.", ""]
    # the paper's columns only beside the paper's task: its targets, start pose, n, line
    paper_task = (targets.is_paper and shape == "line"
                  and record.get("direction") is None)
    if paper_task and solver.name == "ours":
        lines += ["## Beside the paper's Table 1", "",
                  "Columns named *paper* are copied from the paper. Its \"distance from the "
                  "line [mm]\" values are in centimetres (its unit label is off by a factor of "
                  "ten, see shared/reference/README.md), so they are shown here x 10, in mm.",
                  ""]
        if record["steps"] != PAPER_STEPS:
            lines += [f"The paper used n = {PAPER_STEPS} segments; this run used "
                      f"n = {record['steps']}.", ""]
        lines += [markdown_table(table1_comparison(table), {"loss": 2, "duration [s]": 2}), ""]
    if paper_task and solver.name == "sequential-ik":
        from ikbench.compare import table2_section

        lines += table2_section(table, record["steps"])
    lines += ["## Figures", ""]
    for caption, name in figures.items():
        lines += [f"![{caption}]({name})", ""]
    lines += ["## Solver details", "",
              markdown_table(details.drop(columns=["method"]), {"iterations_per_s": 0}), ""]
    return "\n".join(lines)
