"""What can be designed, and which points move it: a line, a letter, a 6-D pose path.

Each kind holds the state the user changes, builds the task from it exactly as ``ikbench run``
builds it from the saved files (:func:`ikbench.core.task.build_tasks` for lines and letters,
:func:`ikbench.core.problems.problem_task` for pose paths), and names its draggable points
(:meth:`handles`, base frame [mm]):

- :class:`LineDesign`: ``touch`` (the touch point: a touch pose by :func:`.reach.reach`,
  pointing along the line) and ``start`` (the start point: a start pose by the same IK,
  position only); the start pose may also be a recorded one (:meth:`LineDesign.use_pose`);
- :class:`LetterDesign`: ``centre`` (the letter's centre: the fingertip at the pose the
  letter is placed from) and its size (:meth:`LetterDesign.set_size`);
- :class:`PathDesign`: ``waypoint`` (the chosen waypoint; moving it moves its neighbours
  too, less the further they are, over :data:`WAYPOINT_SPAN` of the path each way).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.core.letters import DEFAULT_SIZE_MM, DEFAULT_STEPS, parse_letters
from ikbench.core.robot import Robot
from ikbench.core.targets import Targets, load_targets
from ikbench.core.task import Task, build_tasks, letter_start_pose, parse_shape
from ikbench.viewer.design.reach import Reach, reach

#: A moved waypoint drags its neighbours within this share of the path (each way) along.
WAYPOINT_SPAN = 0.15
#: A new line's touch point lies this far from the start point along the pointing axis [mm]
#: (robots without targets).
NEW_LINE_MM = 150.0
#: Letter heights the designer accepts [mm].
SIZE_RANGE_MM = (20.0, 1000.0)


def _own_targets(robot: Robot, targets: str | Path | Targets | None) -> Targets | None:
    """The targets given, else the robot's own, else None (a URDF without targets)."""
    if isinstance(targets, Targets):
        return targets
    if targets is None and robot.config.targets.file is None:
        return None
    return load_targets(targets, robot)


def _middle_pose(robot: Robot) -> np.ndarray:
    """(dof,) the middle of each joint's range (0 for a joint without limits)."""
    lower, upper = robot.lower, robot.upper
    finite = np.isfinite(lower) & np.isfinite(upper)
    return np.where(finite, (np.where(finite, lower, 0.0) + np.where(finite, upper, 0.0)) / 2,
                    0.0)


class LineDesign:
    """A line from the start pose's fingertip to the touch pose's (the paper's task).

    Args:
        robot: the robot.
        targets: a targets file or :class:`Targets` (default: the robot's own; a robot
            without any starts from ``start_pose`` or the middle of its joint ranges).
        trajectory: the touch pose to start from (default the first); names the saved one.
        start_pose: (dof,) [pose units] replacing the targets' start pose.
        steps: n (default the targets').
    """

    kind = "line"

    def __init__(self, robot: Robot, targets: str | Path | Targets | None = None,
                 trajectory: str | None = None, start_pose: npt.ArrayLike | None = None,
                 steps: int | None = None) -> None:
        self.robot = robot
        own = _own_targets(robot, targets)
        start = (robot.check_pose(start_pose, "--start-pose") if start_pose is not None
                 else own.start_pose if own is not None else _middle_pose(robot))
        if own is None:
            tip = robot.fk(start)
            found = reach(robot, tip.point_mm[0] + NEW_LINE_MM * tip.direction[0], start)
            own = Targets(robot.joint_names, start, {"design": found.pose}, steps or 50,
                          "design")
        self.trajectory = trajectory or own.ids[0]
        if self.trajectory not in own.touch_poses:
            raise InputError(f"--trajectory {self.trajectory!r} is not a touch pose of the "
                             f"targets; available: {', '.join(own.ids)}")
        self.targets = own.with_steps(steps)
        self.start_pose = np.asarray(start, dtype=float)
        self.touch_pose = np.asarray(own.touch_poses[self.trajectory], dtype=float)

    @property
    def recorded_poses(self) -> dict[str, np.ndarray]:
        """The targets' poses by name (``start``, then every touch pose's id)."""
        return {"start": self.targets.start_pose, **self.targets.touch_poses}

    def handles(self) -> dict[str, np.ndarray]:
        points = self.robot.fk(np.stack([self.touch_pose, self.start_pose])).point_mm
        return {"touch": points[0], "start": points[1]}

    def saved_targets(self) -> Targets:
        """The targets ``ikbench run`` gets from the saved file: this start and touch pose."""
        return replace(self.targets, start_pose=self.start_pose,
                       touch_poses={self.trajectory: self.touch_pose})

    def task(self) -> Task:
        return build_tasks(self.robot, self.saved_targets(), "line", self.targets.steps)[0]

    def move(self, handle: str, point_mm: npt.ArrayLike, poses: np.ndarray | None = None
             ) -> Reach:
        """Move the ``touch`` or ``start`` point; the pose found is kept (reached or not).
        ``poses``: the trajectory now (unused: the IK starts from the pose it moves)."""
        points = self.handles()
        if handle == "touch":
            direction = np.asarray(point_mm, dtype=float) - points["start"]
            found = reach(self.robot, point_mm, self.touch_pose, direction)
            self.touch_pose = found.pose
        elif handle == "start":
            found = reach(self.robot, point_mm, self.start_pose)
            self.start_pose = found.pose
        else:
            raise InputError(f"a line has the points touch and start, not {handle!r}")
        return found

    def use_pose(self, pose: npt.ArrayLike) -> None:
        """Start from ``pose`` (dof,) [pose units], e.g. a recorded one."""
        self.start_pose = self.robot.check_pose(pose, "start pose")

    def warm(self, previous: np.ndarray, task: Task) -> np.ndarray:
        """The previous poses (n+1, dof) with their ends moved onto the task's start and touch
        poses, the change spread linearly along the path."""
        t = np.linspace(0.0, 1.0, len(previous))[:, None]
        start = np.asarray(task.required.start_pose, dtype=float)
        end = np.asarray(task.required.end_pose, dtype=float)
        return previous + (1.0 - t) * (start - previous[0]) + t * (end - previous[-1])


class LetterDesign:
    """A letter on the robot's letter plane, centred on the fingertip at a reference pose.

    Args:
        robot: the robot.
        letter: one letter (``letter:P``'s P).
        targets: whose start pose is the default reference pose, as for ``ikbench run``.
        start_pose: (dof,) the reference pose (default the robot's letters start pose).
        steps: n (default 100); size_mm: the letter's height (default 300).
    """

    kind = "letter"

    def __init__(self, robot: Robot, letter: str, targets: str | Path | Targets | None = None,
                 start_pose: npt.ArrayLike | None = None, steps: int | None = None,
                 size_mm: float | None = None) -> None:
        letters = parse_letters(letter)
        if len(letters) != 1:
            raise InputError(f"--shape letter:{letter}: the designer draws one letter at a time")
        self.robot, self.letter = robot, letters[0]
        own = _own_targets(robot, targets)
        pose = (robot.check_pose(start_pose, "--start-pose") if start_pose is not None
                else letter_start_pose(robot, own) if own is not None or
                robot.config.letters.start_pose is not None
                else _middle_pose(robot))
        self.reference_pose = np.asarray(pose, dtype=float)
        self.targets = own if own is not None else Targets(
            robot.joint_names, self.reference_pose, {"centre": self.reference_pose},
            DEFAULT_STEPS, "design")
        self.steps = DEFAULT_STEPS if steps is None else self.targets.with_steps(steps).steps
        self.size_mm = DEFAULT_SIZE_MM
        if size_mm is not None:
            self.set_size(size_mm)

    @property
    def shape(self) -> str:
        """The ``--shape`` of the saved run."""
        return f"letter:{self.letter}"

    def handles(self) -> dict[str, np.ndarray]:
        return {"centre": self.robot.fk(self.reference_pose).point_mm[0]}

    def saved_targets(self) -> Targets:
        """The saved targets: the reference pose as the start pose (``ikbench run`` places
        letters from it); the one touch pose ``centre`` repeats it (a targets file needs one)."""
        return replace(self.targets, start_pose=self.reference_pose,
                       touch_poses={"centre": self.reference_pose})

    def task(self) -> Task:
        return build_tasks(self.robot, self.saved_targets(), self.shape, self.steps,
                           self.size_mm)[0]

    def move(self, handle: str, point_mm: npt.ArrayLike, poses: np.ndarray | None = None
             ) -> Reach:
        """Move the letter's ``centre``: the reference pose by IK, position only (``poses``:
        unused)."""
        if handle != "centre":
            raise InputError(f"a letter has the point centre, not {handle!r}")
        found = reach(self.robot, point_mm, self.reference_pose)
        self.reference_pose = found.pose
        return found

    def set_size(self, size_mm: float) -> None:
        """The letter's height [mm], within :data:`SIZE_RANGE_MM`."""
        low, high = SIZE_RANGE_MM
        if not low <= float(size_mm) <= high:
            raise InputError(f"--size {size_mm!r}: a letter is {low:g} to {high:g} mm high")
        self.size_mm = float(size_mm)

    def warm(self, previous: np.ndarray, task: Task) -> np.ndarray:
        """The previous poses as they are (the letter keeps its shape as it moves)."""
        return previous


class PathDesign:
    """A 6-D pose path of a problem file (CppFlow's format), one waypoint dragged at a time.

    Args:
        robot: the problem's robot.
        task: the problem's task (:func:`ikbench.core.problems.load_problem`).
        path_m: (n+1, 3) the problem's path positions [m] as its CSV gives them.
    """

    kind = "path"

    def __init__(self, robot: Robot, task: Task, path_m: np.ndarray) -> None:
        self.robot, self.base_task = robot, task
        self.path_m = np.asarray(path_m, dtype=float)
        self.offsets_mm = np.zeros_like(task.goal.points_mm)
        self.waypoint = task.goal.steps // 2

    def handles(self) -> dict[str, np.ndarray]:
        return {"waypoint": self.task().goal.points_mm[self.waypoint]}

    def select(self, waypoint: int) -> None:
        """Drag waypoint ``waypoint`` (0..n) from now on."""
        if not 0 <= int(waypoint) <= self.base_task.goal.steps:
            raise InputError(f"waypoint {waypoint}: the path has waypoints 0 to "
                             f"{self.base_task.goal.steps}")
        self.waypoint = int(waypoint)

    def task(self) -> Task:
        return replace(self.base_task, goal=replace(
            self.base_task.goal, points_mm=self.base_task.goal.points_mm + self.offsets_mm))

    def moved_path_m(self) -> np.ndarray:
        """(n+1, 3) the path CSV's positions [m] with the moves applied."""
        return self.path_m + self.offsets_mm / 1000.0

    def move(self, handle: str, point_mm: npt.ArrayLike, poses: np.ndarray | None = None
             ) -> Reach:
        """Move the chosen ``waypoint`` to ``point_mm``: its neighbours follow with a cosine
        weight falling to 0 over :data:`WAYPOINT_SPAN` of the path; ``poses`` (n+1, dof): the
        trajectory now (the reachability IK starts from the waypoint's pose)."""
        if handle != "waypoint":
            raise InputError(f"a pose path has the point waypoint, not {handle!r}")
        k, n = self.waypoint, self.base_task.goal.steps
        delta = np.asarray(point_mm, dtype=float) - self.handles()["waypoint"]
        span = max(2, int(round(WAYPOINT_SPAN * n)))
        distance = np.abs(np.arange(n + 1) - k) / span
        weight = np.where(distance < 1.0, 0.5 * (1.0 + np.cos(np.pi * distance)), 0.0)
        self.offsets_mm = self.offsets_mm + weight[:, None] * delta
        start = np.asarray(self.base_task.hints.reference_pose if poses is None else poses[k],
                           dtype=float)
        return reach(self.robot, point_mm, start, self.base_task.goal.directions[k])

    def warm(self, previous: np.ndarray, task: Task) -> np.ndarray:
        """The previous poses as they are."""
        return previous


def design_for(robot: Robot, shape: str, targets: str | Path | Targets | None = None,
               trajectory: str | None = None, start_pose: npt.ArrayLike | None = None,
               steps: int | None = None, size_mm: float | None = None
               ) -> LineDesign | LetterDesign:
    """A line or letter design for ``shape`` (``line`` or ``letter:X``)."""
    kind, arg = parse_shape(shape)
    if kind == "line":
        if size_mm is not None:
            raise InputError("--size: only letters are scaled")
        return LineDesign(robot, targets, trajectory, start_pose, steps)
    if kind != "letter":
        raise InputError(f"--shape {shape!r}: the designer draws line or letter:X (a polyline "
                         "or spline file is edited in the file)")
    return LetterDesign(robot, arg, targets, start_pose, steps, size_mm)
