"""The least-squares form of the paper's objective, for B trajectories at once.

``L = |r|^2`` with residuals (N = n+1 poses, P in cm, v unit directions, d goal directions):

- L0: sqrt(c0 / (3N)) (P_i - P^g_i)             - L1: sqrt(c1 / (2N)) (v_i - d_i)
- L2: sqrt(c2) (p_0 - p^s)                      - L3: sqrt(c3) (p_n - p^e)
- L4: sqrt(c4) (P_0 - P^g_0)                    - L5: sqrt(c5) (P_n - P^g_n)
- L6: sqrt(c6 / (n dof)) (p_{i+1} - p_i)

(for unit vectors 1 - v.d = |v - d|^2 / 2, so the L1 residual is exact). Only L6 couples
neighbouring poses, with a multiple of the identity, so J^T J is block-tridiagonal.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeAlias, cast

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.losses import MM_PER_CM, TERMS

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: The loss weights: one dict (term -> weight) for every task, or one dict per task.
Weights: TypeAlias = "dict[str, float] | Sequence[dict[str, float]]"
#: Trajectories picked from a batch: indices (or a mask) into its first axis.
Index: TypeAlias = "np.ndarray | Sequence[int] | slice | int"
#: FK with Jacobians: ``kinematics(poses (M, dof), jacobian)`` -> (points [m] (M, 3),
#: directions (M, 3), their Jacobians (M, 3, dof) per pose unit, or None without them).
Kinematics: TypeAlias = "Callable[[np.ndarray, bool], tuple[Any, Any, Any, Any]]"

CM_PER_M = 100.0


@dataclass
class Problem:
    """B trajectories of N poses in the loss units, with per-trajectory weights.

    Attributes:
        goal_points_cm: (B, N, 3).  goal_directions: (B, N, 3).
        start_pose / end_pose: (B, dof) (zeros where a task fixes none).
        weights: (B, 7) c0..c6 per trajectory (c2/c3 set to 0 where a pose is not fixed).
        lower_deg / upper_deg: (dof,) motor ranges.
    """

    goal_points_cm: np.ndarray
    goal_directions: np.ndarray
    start_pose: np.ndarray
    end_pose: np.ndarray
    weights: np.ndarray
    lower_deg: np.ndarray
    upper_deg: np.ndarray

    @classmethod
    def from_tasks(cls, robot: Robot, tasks: Sequence[Task], weights: Weights) -> Problem:
        """Stack tasks of equal length; ``weights`` is one dict or one dict per task."""
        sizes = {t.goal.steps for t in tasks}
        if len(sizes) != 1:
            raise InputError(f"ours-lm batches tasks of one length; got n = {sorted(sizes)}")
        per_task = cast("Sequence[dict[str, float]]", weights if isinstance(weights, (list, tuple))
                        else [weights] * len(tasks))  # a list or tuple: one dict per task
        w = np.array([[float(ws.get(k, 0.0)) for k in TERMS] for ws in per_task])
        zero = np.zeros(robot.dof)
        start = np.stack([zero if t.required.start_pose is None else t.required.start_pose
                          for t in tasks])
        end = np.stack([zero if t.required.end_pose is None else t.required.end_pose
                        for t in tasks])
        w[:, 2] *= [t.required.start_pose is not None for t in tasks]
        w[:, 3] *= [t.required.end_pose is not None for t in tasks]
        return cls(np.stack([t.goal.points_mm for t in tasks]) / MM_PER_CM,
                   np.stack([t.goal.directions for t in tasks]), start, end, w,
                   robot.lower, robot.upper)

    def take(self, index: Index) -> Problem:
        """The sub-problem of trajectories ``index``."""
        return Problem(self.goal_points_cm[index], self.goal_directions[index],
                       self.start_pose[index], self.end_pose[index],
                       self.weights[index], self.lower_deg, self.upper_deg)

    def residual_weights(self) -> tuple[np.ndarray, ...]:
        """Squared residual scales (B,) each: a0^2 .. a6^2 (see the module docstring)."""
        n_poses = self.goal_points_cm.shape[1]
        dof = len(self.lower_deg)
        c = self.weights.T
        return (c[0] / (3 * n_poses), c[1] / (2 * n_poses), c[2], c[3], c[4], c[5],
                c[6] / ((n_poses - 1) * dof))


@dataclass
class Evaluation:
    """Loss, gradient and Gauss-Newton blocks of B trajectories at poses (B, N, dof).

    ``loss`` (B,) equals :func:`ikbench.core.losses.objective`; ``terms`` (B, 7) the L_k;
    ``gradient`` (B, N, dof) = J^T r (half the loss gradient); ``diagonal`` (B, N, dof, dof)
    and ``coupling`` (B,) the blocks of J^T J (off-diagonal blocks = -coupling * I).
    """

    loss: np.ndarray
    terms: np.ndarray
    gradient: Any = None        # np.ndarray when derivatives were asked for
    diagonal: Any = None
    coupling: Any = None


def evaluate(kinematics: Kinematics, problem: Problem, poses: np.ndarray,
             derivatives: bool = True) -> Evaluation:
    """Residuals of ``problem`` at ``poses`` (B, N, dof) [motor deg]; see :class:`Evaluation`."""
    b, n_poses, dof = poses.shape
    point, direction, j_point, j_dir = kinematics(poses.reshape(-1, dof), derivatives)
    point = point * CM_PER_M  # the loss is in cm
    if derivatives:
        j_point = j_point * CM_PER_M
    point = point.reshape(b, n_poses, 3)
    direction = direction.reshape(b, n_poses, 3)
    e_point = point - problem.goal_points_cm
    e_dir = direction - problem.goal_directions
    e_start = poses[:, 0] - problem.start_pose
    e_end = poses[:, -1] - problem.end_pose
    steps = np.diff(poses, axis=1)
    terms = np.stack([
        np.mean(e_point**2, axis=(1, 2)),
        np.mean(1.0 - np.sum(direction * problem.goal_directions, axis=-1), axis=1),
        np.sum(e_start**2, axis=1), np.sum(e_end**2, axis=1),
        np.sum(e_point[:, 0] ** 2, axis=1), np.sum(e_point[:, -1] ** 2, axis=1),
        np.mean(steps**2, axis=(1, 2)),
    ], axis=1)
    loss = np.sum(terms * problem.weights, axis=1)
    if not derivatives:
        return Evaluation(loss, terms)
    a0, a1, a2, a3, a4, a5, a6 = problem.residual_weights()
    w_point = np.repeat(a0[:, None], n_poses, axis=1)
    w_point[:, 0] += a4
    w_point[:, -1] += a5
    diagonal, gradient = gauss_newton_blocks(
        (w_point, j_point.reshape(b, n_poses, 3, dof), e_point),
        (a1[:, None], j_dir.reshape(b, n_poses, 3, dof), e_dir), a6, steps,
        (a2, e_start, a3, e_end))
    return Evaluation(loss, terms, gradient, diagonal, a6)


def gauss_newton_blocks(first: tuple[Any, Any, Any], second: tuple[Any, Any, Any], a6: Any,
                        steps: Any, ends: tuple[Any, Any, Any, Any] | None = None
                        ) -> tuple[Any, Any]:
    """The diagonal blocks (B, N, dof, dof) of J^T J and J^T r (B, N, dof) of a path's
    residuals: two per-pose residuals, each ``(w, J, e)`` (its squared scale w (B, N) or
    (B, 1), Jacobian J (B, N, 3, dof) and value e (B, N, 3): sqrt(w) e), the steps
    sqrt(a6) (p_{i+1} - p_i) (a6 (B,), ``steps`` (B, N - 1, dof); off-diagonal blocks
    -a6 I) and, with ``ends`` = (a2, e_start, a3, e_end) ((B,), (B, dof) each), the fixed
    poses sqrt(a2) e_start on the first pose and sqrt(a3) e_end on the last. Numpy arrays or
    torch tensors (:mod:`.torch_backend` computes the same blocks on a device)."""
    (w_p, j_p, e_p), (w_q, j_q, e_q) = first, second
    j_p_t, j_q_t = j_p.swapaxes(-1, -2), j_q.swapaxes(-1, -2)
    diagonal = w_p[..., None, None] * (j_p_t @ j_p) + w_q[..., None, None] * (j_q_t @ j_q)
    gradient = (w_p[..., None] * (j_p_t @ e_p[..., None])[..., 0]
                + w_q[..., None] * (j_q_t @ e_q[..., None])[..., 0])
    if ends is not None:
        gradient[:, 0] += ends[0][:, None] * ends[1]
        gradient[:, -1] += ends[2][:, None] * ends[3]
    gradient[:, :-1] -= a6[:, None, None] * steps
    gradient[:, 1:] += a6[:, None, None] * steps
    if isinstance(steps, np.ndarray):  # the diagonals as writable views (B, N, dof)
        degree, diag = np.full(steps.shape[1] + 1, 2.0), np.einsum("...ii->...i", diagonal)
    else:
        degree, diag = (steps.new_full((steps.shape[1] + 1,), 2.0),
                        diagonal.diagonal(dim1=-2, dim2=-1))
    degree[[0, -1]] = 1.0  # neighbours of each pose
    diag += a6[:, None, None] * degree[None, :, None]
    if ends is not None:
        diag[:, 0] += ends[0][:, None]
        diag[:, -1] += ends[2][:, None]
    return diagonal, gradient


