"""The run folders that ``ikbench report DIR`` compares, read back and measured.

:func:`load_comparison` reads every run folder that ``ikbench run --output DIR [--name NAME]``
wrote (``DIR/<name>/run.json`` + ``trajectory_<id>.csv``, through
:class:`ikbench.runtime.record.RunFolder`; the folders of other commands,
:data:`ikbench.studies.folders.RESERVED_NAMES`, and folders without trajectories are not runs),
recomputes every figure with :mod:`ikbench.core.metrics` from the trajectory CSVs (only the
solver's own duration and iteration count come from ``table.csv``, the count of points that
missed the IK tolerance from ``details.csv``) and summarises each run: the tables
:mod:`ikbench.paper.baseline_claims` judges and :mod:`ikbench.paper.comparison` renders.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ikbench.core.errors import InputError
from ikbench.core.metrics import pointing_deviations_deg, trajectory_metrics
from ikbench.core.robot import Robot
from ikbench.core.targets import Targets
from ikbench.core.task import Task, line_tasks
from ikbench.paper.baseline_claims import (
    BASELINE,
    BASELINE_METHODS,
    IKPY,
    METHOD_FAMILIES,
    OURS,
    SCHEME_ORDER,
    check_claims,
    scheme_of,
    task_text,
)
from ikbench.runtime.record import RECORD_FILE, RunFolder, RunRecord, robot_from_record
from ikbench.studies.folders import RESERVED_NAMES


@dataclass
class MethodRun:
    """One run folder read back from disk.

    Attributes:
        name: the folder's name (``sequential-ik-position``); how the reports call the run.
        record: its run.json.
        poses: trajectory id -> (n+1, dof) poses [motor deg] read from the CSVs.
        solver: trajectory id -> {"duration_s", "iterations"} from table.csv.
        details: its details.csv (None when missing or unreadable).
    """

    name: str
    record: RunRecord
    poses: dict
    solver: dict
    details: pd.DataFrame | None = None

    @property
    def method(self) -> str:
        """The registered method that produced the run (run.json's ``method``)."""
        return str(self.record.method or self.name)

    @property
    def family(self) -> str:
        """The baseline family of the method (``sequential-ik`` for ``sequential-ik-walk``,
        ``ikpy`` for ``ikpy-walk``), else the method itself."""
        return METHOD_FAMILIES.get(self.method, self.method)

    @property
    def is_baseline(self) -> bool:
        """Whether the run is one of the paper's baseline families (:data:`BASELINE_METHODS`)."""
        return self.family in BASELINE_METHODS

    @property
    def orientation(self) -> str | None:
        """The baseline's ``--orientation`` mode from run.json (None for other methods)."""
        mode = self.record.method_settings().get("orientation")
        return str(mode) if mode is not None else None

    @property
    def scheme(self) -> str | None:
        """``walk`` or ``track``: run.json's settings ``scheme``; a baseline run that records
        none is a walk (:data:`DEFAULT_SCHEME`); None for other methods without one."""
        return scheme_of(self.method, self.record)

    @property
    def task(self) -> str:
        """The task the run solved, in words: ``walk from the touch pose (touch-pose-only
        task: the start pose is free)`` or ``track from the start pose (the paper's task:
        start and touch poses fixed)``; "" when the run has no scheme."""
        return task_text(self.scheme)

    @property
    def mode_flag(self) -> str:
        """The option naming the run's mode: ``--orientation`` or ``--ikpy-orientation``."""
        return BASELINE_METHODS.get(self.family, ("--orientation",))[0]

    @property
    def description(self) -> str:
        """``sequential-ik-walk, --orientation position; walk from the touch pose:
        touch-pose-only task``: the method (when not the folder's name), the mode and the
        task solved; "" when none applies."""
        parts = [] if self.method == self.name else [self.method]
        if self.orientation:
            parts.append(f"{self.mode_flag} {self.orientation}")
        text = ", ".join(parts)
        if self.scheme:
            text += ("; " if text else "") + task_text(self.scheme, short=True)
        return text

    @property
    def label(self) -> str:
        """``sequential-ik-position (sequential-ik-walk, --orientation position; walk from the
        touch pose: touch-pose-only task)`` or the name (:attr:`description`)."""
        return f"{self.name} ({self.description})" if self.description else self.name


def _method_folders(output_dir: Path) -> dict[Path, RunRecord]:
    """The run folders of ``output_dir`` and their records: a run.json naming a method and its
    trajectories, and trajectory CSVs beside it; the folders of other commands are skipped by
    name."""
    folders = {}
    for path in sorted(output_dir.glob(f"*/{RECORD_FILE}")):
        folder = RunFolder(path.parent)
        if folder.path.name in RESERVED_NAMES or not folder.has_trajectories():
            continue
        record = folder.read_record("report")
        if isinstance(record.method, str) and record.trajectories is not None:
            folders[folder.path] = record
    return folders


def load_method_run(folder: Path, robot: Robot, record: RunRecord | None = None) -> MethodRun:
    """Read run.json (unless given), the trajectory CSVs, the solver columns of table.csv and
    details.csv."""
    run = RunFolder(folder)
    record = record or run.read_record("report")
    try:
        table = run.read_table("table.csv")
    except (OSError, ValueError) as exc:
        raise InputError(f"report: cannot read {folder}: {exc}") from None
    try:
        details = run.read_table("details.csv")
    except (OSError, ValueError):
        details = None
    poses, solver = {}, {}
    for tid in record.trajectories or []:
        poses[tid] = run.read_poses(tid, robot)
        row = table[table["trajectory"] == tid]
        solver[tid] = {"duration_s": float(row["duration_s"].iloc[0]) if len(row) else np.nan,
                       "iterations": float(row["iterations"].iloc[0]) if len(row) else np.nan}
    return MethodRun(run.path.name, record, poses, solver, details)


def baseline_names(runs: dict) -> list[str]:
    """The baseline runs (method families :data:`BASELINE_METHODS`) in report order: by
    family, then by scheme (the walk, the paper's Table 2, first), then by mode
    (:data:`ORIENTATION_MODES`, :data:`IKPY_MODES`), the folder named after the family first
    within a mode."""
    families = list(BASELINE_METHODS)

    def key(name):
        run = runs[name]
        modes = list(BASELINE_METHODS[run.family][1])
        mode, scheme = run.orientation, run.scheme
        return (families.index(run.family),
                SCHEME_ORDER.index(scheme) if scheme in SCHEME_ORDER else len(SCHEME_ORDER),
                modes.index(mode) if mode in modes else len(modes), name != run.family, name)

    return sorted((n for n, r in runs.items() if r.is_baseline), key=key)


def table2_run(runs: dict) -> str:
    """The baseline run set beside the paper's Table 2: the first walk of the
    ``sequential-ik`` family in ``frame`` mode (the folder ``sequential-ik`` when it is
    one), else the first baseline walk, else the first baseline run."""
    names = baseline_names(runs)
    return next((n for n in names if runs[n].family == BASELINE and runs[n].scheme == "walk"
                 and runs[n].orientation == "frame"),
                next((n for n in names if runs[n].scheme == "walk"), names[0]))


def ikpy_table2_run(runs: dict) -> str | None:
    """The run of the authors' call beside the paper's Table 2: the first walk of the
    ``ikpy`` family in ``position`` mode, or None."""
    return next((n for n in baseline_names(runs) if runs[n].family == IKPY
                 and runs[n].scheme == "walk" and runs[n].orientation == "position"), None)


def load_runs(output_dir: str | Path) -> tuple[dict[str, MethodRun], list[Task], Targets]:
    """Every run in ``output_dir`` and the shared tasks; InputError if unusable.

    Returns:
        (runs: folder name -> MethodRun in report order (``ours``, the baseline runs, the
        others by name), tasks: the tasks of the trajectories all runs share, targets)
    """
    output_dir = Path(output_dir)
    if not output_dir.is_dir():
        raise InputError(f"report: {str(output_dir)!r} is not a directory; give the --output "
                         "directory of `ikbench run`")
    folders = _method_folders(output_dir)
    names = [f.name for f in folders]
    baselines = {r.method for r in folders.values()} & set(METHOD_FAMILIES)
    missing = [m for m, ok in ((OURS, OURS in names), (BASELINE, bool(baselines))) if not ok]
    if missing:
        raise InputError(
            f"report: {str(output_dir)!r} has no {' or '.join(missing)} results (method folders "
            f"found: {', '.join(names) or 'none'}); run `ikbench run --method "
            f"{missing[0]} --output {output_dir}` first")
    robot = robot_from_record(folders[output_dir / OURS])
    runs = {f.name: load_method_run(f, robot, record) for f, record in folders.items()}
    shaped = [n for n, r in runs.items() if r.record.shape != "line"]
    if shaped:
        raise InputError(f"report: compares line runs (touch poses) only; {', '.join(shaped)} "
                         f"in {str(output_dir)!r} drew another shape")
    turned = [n for n, r in runs.items() if r.record.direction is not None]
    if turned:
        raise InputError(f"report: compares runs pointing along the line only; "
                         f"{', '.join(turned)} in {str(output_dir)!r} used --direction")
    keys = {name: (str(r.record.targets), r.record.steps, tuple(r.record.start_pose_deg or ()))
            for name, r in runs.items()}
    if len(set(keys.values())) > 1:
        raise InputError("report: the method folders were run on different targets, steps or "
                         "start poses: " + "; ".join(f"{n}: targets {t}, n = {s}, start {p}"
                                                     for n, (t, s, p) in keys.items()))
    shared = [t for t in runs[OURS].poses if all(t in r.poses for r in runs.values())]
    if not shared:
        raise InputError("report: the method folders share no trajectory id")
    targets = runs[OURS].record.run_targets(robot).select(shared).with_steps(
        int(runs[OURS].record.steps or 0))
    order = [OURS, *baseline_names(runs)]
    order += sorted(n for n in runs if n not in order)
    return {n: runs[n] for n in order}, line_tasks(robot, targets), targets


def evaluate_runs(runs: dict[str, MethodRun], tasks: Sequence[Task]) -> pd.DataFrame:
    """One row per (trajectory, run): solver figures + :func:`trajectory_metrics`."""
    robot = robot_from_record(next(iter(runs.values())).record)
    rows = []
    for task in tasks:
        for name, run in runs.items():
            poses = run.poses[task.name]
            if len(poses) != task.goal.steps + 1:
                raise InputError(f"report: {name}/trajectory_{task.name}.csv has {len(poses)} "
                                 f"poses; run.json says n = {task.goal.steps}")
            metrics = trajectory_metrics(robot, task, poses)
            rows.append({"trajectory": task.name, "method": name, **run.solver[task.name],
                         **metrics, "start_point_mm": robot.fk(poses[0]).point_mm[0],
                         **_missed(run, task.name)})
    return pd.DataFrame(rows)


def _missed(run: MethodRun, trajectory: str) -> dict:
    """Points that missed the IK tolerance and points solved, from details.csv (NaN if none)."""
    details = run.details
    if details is None or "points_not_converged" not in details.columns:
        return {"points_not_converged": np.nan, "points_solved": np.nan}
    row = details[details["trajectory"] == trajectory]
    if not len(row):
        return {"points_not_converged": np.nan, "points_solved": np.nan}
    solved = row["points_solved"].iloc[0] if "points_solved" in row else np.nan
    return {"points_not_converged": float(row["points_not_converged"].iloc[0]),
            "points_solved": float(solved)}


def pointing_per_step(runs: dict[str, MethodRun], tasks: Sequence[Task]
                      ) -> dict[tuple[str, str], np.ndarray]:
    """(run, trajectory id) -> (n+1,) pointing deviation [deg] of each pose."""
    robot = robot_from_record(next(iter(runs.values())).record)
    return {(name, task.name): pointing_deviations_deg(robot.fk(run.poses[task.name]).direction,
                                                       task.goal.directions)
            for name, run in runs.items() for task in tasks}


def summarise(frame: pd.DataFrame, runs: dict) -> pd.DataFrame:
    """Per-run summary over the trajectories (medians unless the column says otherwise)."""
    rows = []
    for name, run in runs.items():
        sub = frame[frame["method"] == name]
        start_poses = np.stack([run.poses[t][0] for t in sub["trajectory"]])
        start_points = np.stack(sub["start_point_mm"].to_numpy())
        missed = sub.get("points_not_converged", pd.Series(np.nan, index=sub.index))
        solved = sub.get("points_solved", pd.Series(np.nan, index=sub.index))
        rows.append({
            "method": name,
            "median duration [s]": sub["duration_s"].median(),
            "median iterations": sub["iterations"].median(),
            "mean line distance [mm]": sub["line_distance_mean_mm"].mean(),
            "mean pointing deviation [deg]": sub["pointing_deviation_mean_deg"].mean(),
            "max |P_0 - P_s| [mm]": sub["start_point_error_mm"].max(),
            "max |p_0 - p^s| [deg]": sub["start_pose_error_deg"].max(),
            "median |p_0 - p^s| [deg]": sub["start_pose_error_deg"].median(),
            "start pose spread [deg]": float(np.max(np.ptp(start_poses, axis=0))),
            "start point spread [mm]": float(np.max(np.linalg.norm(
                start_points[:, None] - start_points[None], axis=-1))),
            "max |P_n - P_e| [mm]": sub["end_point_error_mm"].max(),
            "median mean sq. joint step [deg^2]": sub["mean_sq_joint_step_deg2"].median(),
            "median mean sq. jerk [deg^2]": sub["mean_sq_jerk_deg2"].median(),
            "median max joint step [deg]": sub["max_joint_step_deg"].median(),
            "median velocity sign changes": sub["velocity_sign_changes"].median(),
            "points missing the IK tolerance": missed.sum(min_count=1),
            "points solved": solved.sum(min_count=1),
        })
    return pd.DataFrame(rows)
@dataclass
class Comparison:
    """Every run of an output directory, measured and judged (:func:`load_comparison`).

    Attributes:
        runs: folder name -> :class:`MethodRun`, in report order.
        tasks: the shared tasks.
        targets: their targets.
        frame: :func:`evaluate_runs` (one row per trajectory and run).
        summary: :func:`summarise` (one row per run).
    """

    runs: dict[str, MethodRun]
    tasks: list[Task]
    targets: Targets
    frame: pd.DataFrame
    summary: pd.DataFrame

    @property
    def baselines(self) -> list[str]:
        """The baseline runs, in report order (:func:`baseline_names`)."""
        return baseline_names(self.runs)

    def claims(self, baseline: str) -> pd.DataFrame:
        """:func:`check_claims` of one baseline run against ``ours``."""
        return check_claims(self.summary, baseline)


def load_comparison(output_dir: str | Path) -> Comparison:
    """Load, measure and summarise every run in ``output_dir`` (see :func:`load_runs`): what
    ``ikbench report`` shows (:func:`ikbench.paper.comparison.write_comparison_report`)."""
    runs, tasks, targets = load_runs(output_dir)
    frame = evaluate_runs(runs, tasks)
    return Comparison(runs, tasks, targets, frame, summarise(frame, runs))
