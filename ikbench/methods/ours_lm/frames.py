"""The least-squares 6-D pose-path objective (tasks with goal frames), for B trajectories.

``L = |r|^2`` with residuals (N = n+1 poses; P in mm, R the end frame's rotation):

- L0: sqrt(c0 / (3N)) (P_i - P^g_i)                       position [mm]
- L1: sqrt(c1 / (3N)) (180/pi) log(R^g_i^T R_i)           rotation [deg], the SO(3) log map
- L6: sqrt(c6 / (n dof)) (p_{i+1} - p_i)                  smoothness [pose units]

so L0 and L1 are the mean squared position and rotation errors (per component) and L6 the
paper's smoothness term; the default weights are :data:`ikbench.core.losses.FRAME_WEIGHTS`.
The rotation residual's Jacobian is exact: with E = R^g^T R and phi = log(E), a world-frame
rotation w of the end frame moves phi by Jr^-1(phi) R^T w (:func:`right_jacobian_inverse`).
Only L6 couples neighbouring poses, so J^T J keeps the block-tridiagonal form of
:mod:`.problem` and the same LM loop (:func:`.solver.solve_batch`) minimises it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.losses import TERMS
from ikbench.core.rotations import right_jacobian_inverse, so3_log
from ikbench.methods.ours_lm.problem import Evaluation, Index, Weights, gauss_newton_blocks

if TYPE_CHECKING:
    from ikbench.core.kinematics.chain import Frames
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

DEG_PER_RAD = 180.0 / np.pi
MM_PER_M = 1000.0


@dataclass
class FrameProblem:
    """B pose paths of N waypoints, per-trajectory weights, one set of joint limits.

    Attributes:
        goal_points_mm: (B, N, 3).  goal_rotations: (B, N, 3, 3).
        weights: (B, 7) c0..c6 (only c0, c1, c6 are used).
        lower_deg / upper_deg: (dof,) the box the poses stay in [pose units].
        frames: ``frames(poses (M, dof)) -> (point_m, rotation, J_point, J_angular)`` (see
            :meth:`ikbench.core.kinematics.chain.ChainKinematics.frames`).
    """

    goal_points_mm: np.ndarray
    goal_rotations: np.ndarray
    weights: np.ndarray
    lower_deg: np.ndarray
    upper_deg: np.ndarray
    frames: Any

    @classmethod
    def from_tasks(cls, robot: Robot, tasks: Sequence[Task], weights: Weights,
                   frames: Callable[[np.ndarray, bool], Frames]) -> FrameProblem:
        """Stack frame tasks of equal length and limits; ``weights``: a dict or one per task."""
        if any(t.goal.rotations is None for t in tasks):
            raise InputError("the 6-D objective needs tasks with goal frames")
        if len({t.goal.steps for t in tasks}) != 1:
            raise InputError("ours-lm batches pose paths of one length only")
        per_task = cast("Sequence[dict[str, float]]", weights if isinstance(weights, (list, tuple))
                        else [weights] * len(tasks))  # a list or tuple: one dict per task
        w = np.array([[float(ws.get(k, 0.0)) for k in TERMS] for ws in per_task])
        lower, upper = tasks[0].limits(robot)
        return cls(np.stack([t.goal.points_mm for t in tasks]),
                   np.stack([cast(np.ndarray, t.goal.rotations) for t in tasks]), w,
                   np.asarray(lower, dtype=float), np.asarray(upper, dtype=float), frames)

    def take(self, index: Index) -> FrameProblem:
        """The sub-problem of trajectories ``index``."""
        return FrameProblem(self.goal_points_mm[index], self.goal_rotations[index],
                            self.weights[index], self.lower_deg, self.upper_deg, self.frames)

    def residual_weights(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Squared residual scales (B,) each of L0, L1, L6 (see the module docstring)."""
        n_poses = self.goal_points_mm.shape[1]
        dof = len(self.lower_deg)
        c = self.weights.T
        return c[0] / (3 * n_poses), c[1] / (3 * n_poses), c[6] / ((n_poses - 1) * dof)


def pose_errors(frames: Callable[[np.ndarray, bool], Frames], goal_points_mm: np.ndarray,
                goal_rotations: np.ndarray, poses: np.ndarray, derivatives: bool = True
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Position errors [mm] and rotation errors log(R^g^T R) [deg] of poses (..., dof).

    Returns:
        (e_point (..., 3), e_rot (..., 3), J_point (..., 3, dof) [mm / pose unit] or None,
        J_rot (..., 3, dof) [deg / pose unit] or None).
    """
    shape = poses.shape[:-1]
    dof = poses.shape[-1]
    point, rotation, j_point, j_angular = frames(poses.reshape(-1, dof), derivatives)
    if derivatives:
        assert j_point is not None and j_angular is not None  # asked for
        j_point, j_angular = j_point.reshape(*shape, 3, dof), j_angular.reshape(*shape, 3, dof)
    return errors_from_frames(point.reshape(*shape, 3), rotation.reshape(*shape, 3, 3),
                              j_point, j_angular, goal_points_mm, goal_rotations)


def errors_from_frames(point_m: np.ndarray, rotation: np.ndarray, j_point: np.ndarray | None,
                       j_angular: np.ndarray | None, goal_points_mm: np.ndarray,
                       goal_rotations: np.ndarray, exact: bool = True
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """:func:`pose_errors` from evaluated frames: point_m (..., 3), rotation (..., 3, 3) and
    their Jacobians (..., 3, dof) [m, rad per pose unit] or None. ``exact=False`` leaves out
    Jr^-1 (= I + O(angle)), a cheaper Jacobian for small rotation errors."""
    phi = so3_log(goal_rotations.swapaxes(-1, -2) @ rotation)               # rad
    e_point, e_rot = point_m * MM_PER_M - goal_points_mm, phi * DEG_PER_RAD
    if j_point is None:
        return e_point, e_rot, None, None
    j_rot = rotation.swapaxes(-1, -2) @ j_angular * DEG_PER_RAD             # end frame axes
    if exact:
        j_rot = right_jacobian_inverse(phi) @ j_rot
    return e_point, e_rot, j_point * MM_PER_M, j_rot


def evaluate_frames(kinematics: object, problem: FrameProblem, poses: np.ndarray,
                    derivatives: bool = True) -> Evaluation:
    """Loss, terms, gradient and Gauss-Newton blocks at poses (B, N, dof) (``kinematics`` is
    unused: the problem carries its frame kinematics); see :class:`.problem.Evaluation`."""
    b, n_poses, dof = poses.shape
    e_point, e_rot, j_point, j_rot = pose_errors(problem.frames, problem.goal_points_mm,
                                                 problem.goal_rotations, poses, derivatives)
    steps = np.diff(poses, axis=1)
    terms = np.zeros((b, len(TERMS)))
    terms[:, 0] = np.mean(e_point**2, axis=(1, 2))
    terms[:, 1] = np.mean(e_rot**2, axis=(1, 2))
    terms[:, 6] = np.mean(steps**2, axis=(1, 2))
    loss = np.sum(terms * problem.weights, axis=1)
    if not derivatives:
        return Evaluation(loss, terms)
    a0, a1, a6 = problem.residual_weights()
    assert j_point is not None and j_rot is not None  # asked for
    diagonal, gradient = gauss_newton_blocks((a0[:, None], j_point, e_point),
                                             (a1[:, None], j_rot, e_rot), a6, steps)
    return Evaluation(loss, terms, gradient, diagonal, a6)
