"""Run folders read back for the viewer: robot, trajectories, fingertip and goal paths.

A run folder is what ``ikbench run`` (or ``letters``, ``compare``) writes, read through
:class:`ikbench.runtime.record.RunFolder`: ``run.json`` names the robot
(:func:`ikbench.runtime.record.robot_from_record`) and the trajectories;
``trajectory_<id>.csv`` holds the poses and ``time_s``. Fingertip paths are recomputed from
the poses (FK). Goal paths are rebuilt from run.json where it allows: line tasks from the
recorded targets, start pose and n (as ``ikbench report`` does), other shapes from the
recorded shape, start pose, n, direction and letter size; when that fails (e.g. the targets
file is not found from here) a line run falls back to the straight line between each
trajectory's first and last fingertip points, and another shape shows no goal.
:attr:`ViewRun.goal_source` says which. Obstacles come from run.json's ``obstacles``
(:meth:`ikbench.runtime.record.RunRecord.trajectory_obstacles`: one list for every trajectory,
or one per trajectory id); a run folder written without them has none.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.defaults import DEFAULT_DURATION_S
from ikbench.core.errors import InputError
from ikbench.core.robot import Robot, unwrap_continuous
from ikbench.core.task import Task, build_tasks
from ikbench.core.timing import retime
from ikbench.runtime.record import RunFolder, RunRecord, robot_from_record

if TYPE_CHECKING:
    from ikbench.core.timing import Limits


@dataclass
class ViewTrajectory:
    """One trajectory of a run, ready to draw.

    Attributes:
        name: trajectory id (``"1"``, ``"P"``).
        poses: (n+1, dof) poses [pose units].
        duration_s: time of the last pose [s] (the CSV's ``time_s``); poses evenly apart.
        tip_mm: (n+1, 3) fingertip points [mm], base frame.
        goal_mm: (n+1, 3) goal points [mm] or None.
        goal_segments_mm: (S, 2, 3) the goal path's drawn segments [mm] (pen-up moves left
            out) or None.
        times_s: (n+1,) when each pose is reached under ``--timing min-jerk`` or ``topp``
            [s] (None: evenly apart, the paper's timing).
        obstacles: the obstacles of this trajectory's task
            (:class:`ikbench.core.obstacles.Obstacle`, base frame [mm]); empty: none.
    """

    name: str
    poses: np.ndarray
    duration_s: float
    tip_mm: np.ndarray
    goal_mm: np.ndarray | None = None
    goal_segments_mm: np.ndarray | None = None
    times_s: np.ndarray | None = None
    obstacles: tuple = ()

    @property
    def steps(self) -> int:
        """Number of segments n."""
        return len(self.poses) - 1

    def index_at(self, t_s: float) -> int:
        """The pose shown at time ``t_s`` [s]: the nearest, held after the end."""
        if self.times_s is not None:
            k = int(np.searchsorted(self.times_s, t_s))
            if k <= 0 or k >= len(self.times_s):
                return min(max(k, 0), self.steps)
            return k if self.times_s[k] - t_s < t_s - self.times_s[k - 1] else k - 1
        if self.duration_s <= 0:
            return 0
        return int(min(round(t_s * self.steps / self.duration_s), self.steps))

    def retime(self, robot: Robot, timing: str, limits: Limits | None = None,
               duration_s: float | None = None) -> None:
        """Play under ``timing`` (``min-jerk`` over ``duration_s``, default this trajectory's
        own; ``topp`` within ``limits``): sets ``times_s`` and ``duration_s``."""

        if timing == "constant":
            if duration_s is not None:
                self.duration_s = float(duration_s)
            return
        timed = retime(robot, self.poses, timing, duration_s=duration_s or self.duration_s,
                       limits=limits, tip_mm=self.tip_mm)
        self.times_s, self.duration_s = timed.times_s, timed.duration_s


@dataclass
class ViewRun:
    """A run folder read back: its label (folder name, and the method when it differs),
    trajectories by id (run.json's order), where its goal paths come from, and the
    obstacles every trajectory shares (:class:`ikbench.core.obstacles.Obstacle`, base frame
    [mm]; empty when there are none or they differ between trajectories: then each
    :attr:`ViewTrajectory.obstacles` holds its own)."""

    folder: Path
    label: str
    trajectories: dict[str, ViewTrajectory]
    goal_source: str
    obstacles: tuple = ()


def check_folders(folders: Iterable[str | Path]) -> list[Path]:
    """The run folders as Paths (cheap, no imports): a folder of run folders (``compare``'s
    OUTPUT/compare/, one per method) stands for them, in name order; InputError for one that
    is neither."""
    paths = [Path(f) for f in folders]
    if not paths:
        raise InputError("folders: give at least one run folder (e.g. results/ours)")
    runs: list[Path] = []
    for path in paths:
        inner = sorted(p for p in path.iterdir() if p.is_dir() and RunFolder(p).has_record) \
            if path.is_dir() else []
        if inner:
            runs.extend(inner)
        elif RunFolder(path).has_record:
            runs.append(path)
        else:
            what = "does not exist" if not path.exists() else "has no run.json"
            raise InputError(f"folders: {str(path)!r} {what}; give folders written by ikbench "
                             "run or compare (OUTPUT/NAME/ with run.json and "
                             "trajectory_<id>.csv, or compare's OUTPUT/compare/)")
    return runs


def _record(folder: Path) -> RunRecord:
    run = RunFolder(folder)
    record = run.read_record("view")
    if record.trajectories is None:
        raise InputError(f"view: {run.record_path} names no trajectories")
    return record


def _same_robot(a: Robot, b: Robot) -> bool:
    return (a.urdf_sha256, a.joint_names, a.root_link, a.end_frame) == (
        b.urdf_sha256, b.joint_names, b.root_link, b.end_frame)


def load_runs(folders: Iterable[str | Path]) -> tuple[Robot, list[ViewRun]]:
    """The shared robot and every folder's run.

    Raises:
        InputError: a folder is not a run folder, holds no readable trajectory, or the runs
            do not share the robot.
    """
    paths = check_folders(folders)
    robot, runs = None, []
    for path in paths:
        record = _record(path)
        own = robot_from_record(record)
        if robot is None:
            robot = own
        elif not _same_robot(robot, own):
            raise InputError(f"view: {paths[0]} is a run of robot {robot.name} but {path} of "
                             f"{own.name} ({own.urdf_path.name}, {own.root_link} -> "
                             f"{own.end_frame}); the runs shown together must share the robot")
        runs.append(_load_run(path, record, own))
    assert robot is not None
    labels = [r.label for r in runs]
    for run in runs:  # e.g. results/letters/ours and results/letters/c0-100/ours
        if labels.count(run.label) > 1:
            run.label = f"{run.folder.parent.name}/{run.label}"
    return robot, runs


def _load_run(folder: Path, record: RunRecord, robot: Robot) -> ViewRun:
    run = RunFolder(folder)
    ids = record.trajectories or []
    trajectories = {}
    for tid in ids:
        if not run.trajectory_path(tid).is_file():  # a failed solve writes no trajectory
            continue
        frame = run.read_trajectory(tid, robot)
        # a file an older ikbench wrote wrapped: shown turning the short way, as written now
        poses = unwrap_continuous(robot, frame[list(robot.joint_names)].to_numpy(dtype=float))
        duration = float(frame["time_s"].iloc[-1]) if "time_s" in frame else float(
            record.duration_s or DEFAULT_DURATION_S)
        trajectories[tid] = ViewTrajectory(tid, poses, duration, robot.fk(poses).point_mm)
    if not trajectories:
        raise InputError(f"view: {folder} holds no trajectory CSV of run.json's trajectories "
                         f"({', '.join(ids) or 'none'})")
    source = _add_goals(robot, record, trajectories)
    shared, own = record.trajectory_obstacles(list(trajectories),
                                              f"view: {run.record_path} obstacles")
    for tid, traj in trajectories.items():
        traj.obstacles = own[tid]
    method, name = record.method or folder.name, folder.name
    return ViewRun(folder, name if method == name else f"{name} ({method})", trajectories,
                   source, shared)


def _add_goals(robot: Robot, record: RunRecord, trajectories: dict) -> str:
    """Set each trajectory's goal path; return where it came from."""
    shape = str(record.shape or "line")
    try:
        tasks = {t.name: t for t in _tasks(robot, record, list(trajectories))}
    except (InputError, OSError, KeyError, TypeError, ValueError) as exc:
        if shape != "line":
            return f"no goal path: shape {shape} could not be rebuilt ({exc})"
        for traj in trajectories.values():
            goal = np.linspace(traj.tip_mm[0], traj.tip_mm[-1], traj.steps + 1)
            traj.goal_mm, traj.goal_segments_mm = goal, np.stack([goal[:-1], goal[1:]], 1)
        return ("goal: the straight line between each trajectory's first and last fingertip "
                f"points (the tasks could not be rebuilt: {exc})")
    for tid, traj in trajectories.items():
        task = tasks[tid]
        goal, down = task.goal.points_mm, np.asarray(task.goal.pen_down, dtype=bool)
        keep = down[:-1] & down[1:]
        traj.goal_mm, traj.goal_segments_mm = goal, np.stack([goal[:-1], goal[1:]], 1)[keep]
    size = "" if shape.split(":")[0] != "letter" or "size_mm" not in record.absent else (
        "; letter size not recorded, the default 300 mm assumed")
    return f"goal: rebuilt from run.json (shape {shape}, targets {record.targets}{size})"


def _tasks(robot: Robot, record: RunRecord, ids: list[str]) -> list[Task]:
    """The run's tasks, rebuilt from run.json (see the module doc)."""
    shape = str(record.shape or "line")
    targets = record.run_targets(robot)
    if shape == "line":
        targets = targets.select(ids)
    if record.steps is None:
        raise KeyError("steps")
    tasks = build_tasks(robot, targets, shape, int(record.steps), record.size_mm,
                        record.direction)
    missing = [i for i in ids if i not in {t.name for t in tasks}]
    if missing:
        raise InputError(f"trajectories {', '.join(missing)} are not tasks of the targets")
    return tasks
