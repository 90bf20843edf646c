"""Poses for dragged points: the inverse kinematics the designer runs on every move.

A dragged touch point needs a touch pose: the end point at the point and, for a line, the
pointing axis along the line (the contract judges pointing over the last part of the motion,
which ends at this pose). :func:`reach` asks for both at once, with the roll about the
pointing axis kept from the previous pose, trading 1 mm of position against
:data:`POINTING_TOLERANCE_DEG` of pointing (at most :data:`POINTING_ITERATIONS` iterations);
then the position alone is refined from there, to :data:`POSITION_STOP_MM`. A
point out of reach ends where the end point gets closest (a local minimum of the distance,
from the previous pose): :attr:`Reach.reachable` is False and :attr:`Reach.distance_mm` says
how far it is. Both solves are ours-lm's single-pose LM
(:func:`ikbench.methods.ours_lm.single_pose.solve_poses`), within the robot's joint limits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ikbench.core.robot import Robot
from ikbench.methods.ours_lm.single_pose import solve_poses

#: A dragged point is reached when the end point is within this distance of it [mm].
REACH_TOLERANCE_MM = 0.5
#: A pointing error of this many degrees costs as much as 1 mm of position error.
POINTING_TOLERANCE_DEG = 3.0
#: LM iterations of the solve with pointing, at most: it converges in about 6 where the
#: pointing can be had exactly, and where it cannot, the position is refined alone after it.
POINTING_ITERATIONS = 12
#: LM iterations of the position-only solve, at most, and the error it stops at [mm].
REACH_ITERATIONS = 40
POSITION_STOP_MM = 0.01


@dataclass(frozen=True)
class Reach:
    """The pose found for a dragged point.

    Attributes:
        pose: (dof,) the pose [pose units], within the joint limits.
        point_mm: (3,) where the end point is at ``pose`` [mm], base frame.
        goal_mm: (3,) the point asked for [mm].
    """

    pose: np.ndarray
    point_mm: np.ndarray
    goal_mm: np.ndarray

    @property
    def distance_mm(self) -> float:
        """How far the end point stays from the goal [mm]."""
        return float(np.linalg.norm(self.point_mm - self.goal_mm))

    @property
    def reachable(self) -> bool:
        """True when the end point is within :data:`REACH_TOLERANCE_MM` of the goal."""
        return self.distance_mm <= REACH_TOLERANCE_MM


def rotation_between(a: npt.ArrayLike, b: npt.ArrayLike) -> np.ndarray:
    """(3, 3) the smallest rotation taking direction ``a`` (3,) to direction ``b`` (3,)."""
    a = np.asarray(a, dtype=float) / np.linalg.norm(a)
    b = np.asarray(b, dtype=float) / np.linalg.norm(b)
    axis, cos = np.cross(a, b), float(np.dot(a, b))
    if np.linalg.norm(axis) < 1e-12:
        if cos > 0:
            return np.eye(3)
        # opposite: half a turn about any axis perpendicular to a
        other = np.eye(3)[int(np.argmin(np.abs(a)))]
        axis = np.cross(a, other) / np.linalg.norm(np.cross(a, other))
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    skew = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + skew + skew @ skew / (1.0 + cos)


def reach(robot: Robot, goal_mm: npt.ArrayLike, from_pose: npt.ArrayLike,
          direction: npt.ArrayLike | None = None) -> Reach:
    """The pose nearest ``from_pose`` (dof,) [pose units] that puts the end point at
    ``goal_mm`` (3,) [mm] and, with ``direction`` (3,), points along it (see the module doc).
    A point not reached gets a second round of both solves, with :data:`REACH_ITERATIONS`
    for each (a long jump, e.g. back from beyond the reach)."""
    goal = np.asarray(goal_mm, dtype=float).reshape(3)
    pose = np.asarray(from_pose, dtype=float).reshape(1, -1)
    for pointing_iterations in (POINTING_ITERATIONS, REACH_ITERATIONS):
        pose, point = _solve(robot, goal, pose, direction, pointing_iterations)
        if np.linalg.norm(point - goal) <= REACH_TOLERANCE_MM:
            break
    return Reach(pose[0], point, goal)


def _solve(robot: Robot, goal: np.ndarray, pose: np.ndarray, direction: npt.ArrayLike | None,
           pointing_iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """(pose (1, dof), its end point (3,) [mm]) after the pointing solve (with
    ``direction``) and the position-only refinement."""
    T_base_end = robot.fk_transform(pose)[0]
    if direction is not None and np.linalg.norm(direction) > 0:
        axis = T_base_end[:3, :3] @ robot.pointing_axis
        rotation = rotation_between(axis, direction) @ T_base_end[:3, :3]
        pose = solve_poses(robot, goal[None], rotation[None], pose,
                           (1.0, POINTING_TOLERANCE_DEG),
                           max_iterations=pointing_iterations).poses
    point = robot.fk(pose).point_mm[0]
    if np.linalg.norm(point - goal) > POSITION_STOP_MM:
        pose = solve_poses(robot, goal[None], T_base_end[None, :3, :3], pose,
                           position_only=True, max_iterations=REACH_ITERATIONS,
                           stop=POSITION_STOP_MM).poses
        point = robot.fk(pose).point_mm[0]
    return pose, point
