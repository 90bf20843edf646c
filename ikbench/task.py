"""Tasks: the goal points and goal directions a trajectory must follow.

A :class:`Task` holds n+1 goal points P^g_i [mm] and unit goal directions v^g_i, plus the
start and end poses [motor deg] that the start/end loss terms pin. The paper's task is the
straight line of Eq. 1 from FK(start pose) to FK(touch pose), pointing along it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ikbench.errors import InputError
from ikbench.robot import Robot
from ikbench.targets import Targets

#: Below this distance [mm] start and touch points coincide and a line has no direction.
MIN_LINE_LENGTH_MM = 1e-6


@dataclass(frozen=True, eq=False)
class Task:
    """What a method must achieve for one trajectory.

    Attributes:
        name: trajectory id (e.g. ``"1"``).
        goal_points_mm: (n+1, 3) goal points P^g_i in the robot root frame [mm].
        goal_directions: (n+1, 3) unit goal pointing directions v^g_i.
        start_pose_deg: (dof,) start pose p^s [motor deg], or None when not constrained.
        end_pose_deg: (dof,) end (touch) pose p^e [motor deg], or None.
        shape: the shape's name (``"line"``, ...).
        pen_down: (n+1,) True where the point belongs to the drawn shape (metrics skip the
            others, e.g. pen-up moves between strokes).
    """

    name: str
    goal_points_mm: np.ndarray
    goal_directions: np.ndarray
    start_pose_deg: np.ndarray | None
    end_pose_deg: np.ndarray | None
    shape: str = "line"
    pen_down: np.ndarray = field(default=None)

    def __post_init__(self):
        if self.pen_down is None:
            object.__setattr__(self, "pen_down", np.ones(len(self.goal_points_mm), dtype=bool))

    @property
    def steps(self) -> int:
        """Number of segments n."""
        return len(self.goal_points_mm) - 1

    @property
    def start_point_mm(self) -> np.ndarray:
        """P^s = P^g_0 [mm]."""
        return self.goal_points_mm[0]

    @property
    def end_point_mm(self) -> np.ndarray:
        """P^e = P^g_n [mm]."""
        return self.goal_points_mm[-1]


def line_task(robot: Robot, start_pose_deg, end_pose_deg, steps: int, name: str = "") -> Task:
    """The paper's straight-line task (Eq. 1) from FK(start pose) to FK(end pose).

    Args:
        robot: the robot.
        start_pose_deg: (dof,) start pose [motor deg].
        end_pose_deg: (dof,) touch pose [motor deg].
        steps: number of segments n (n+1 goal points).
        name: trajectory id.
    """
    start = np.asarray(start_pose_deg, dtype=float)
    end = np.asarray(end_pose_deg, dtype=float)
    fk = robot.fk(np.stack([start, end]))
    p_start_mm, p_end_mm = fk.point_mm
    length_mm = float(np.linalg.norm(p_end_mm - p_start_mm))
    if length_mm < MIN_LINE_LENGTH_MM:
        raise InputError(
            f"trajectory {name!r}: start and touch points coincide ({length_mm:g} mm apart); "
            "a line task needs two distinct points"
        )
    direction = (p_end_mm - p_start_mm) / length_mm
    t = np.linspace(0.0, 1.0, steps + 1)[:, None]
    points_mm = p_start_mm + t * (p_end_mm - p_start_mm)
    directions = np.repeat(direction[None], steps + 1, axis=0)
    return Task(name, points_mm, directions, start, end, shape="line")


def line_tasks(robot: Robot, targets: Targets) -> list[Task]:
    """One line task per touch pose of ``targets`` (start pose shared)."""
    return [
        line_task(robot, targets.start_pose_deg, pose, targets.steps, name)
        for name, pose in targets.touch_poses_deg.items()
    ]
