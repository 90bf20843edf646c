"""Keeping clear of obstacles and of itself in ours-lm's 6-D pose-path search.

Used whenever the robot has a collision model (:mod:`ikbench.core.collision`), obstacles or
not: self-collision is always avoided (the numpy search; the compiled search
:mod:`.path_search` does the same in compiled code). Three places:

- **carrying** (:func:`avoidance_motion`): besides the joint-limit avoidance, a joint motion
  that moves every pair closer than ``activation_mm`` apart (robot-obstacle and self pairs)
  by a fraction of the missing distance along its distance gradient (the minimum-norm joint
  motion, capped); the carrying step projects it into the Jacobian's null space, so the path
  is still followed;
- **stitching** (:func:`.start_search.stitched_candidates`): only collision-free carried poses
  are nodes of the stitched path; candidates are ranked by their colliding waypoints;
- **refining** (:func:`with_collisions`): the LM objective gains one residual per close pair
  and waypoint, sqrt(w / N) max(0, clearance - d) with d the signed distance [mm] and w the
  collision weight (``--lm-collision-weight``; the clearance is ``--lm-clearance-mm`` against
  obstacles and :data:`SELF_CLEARANCE_MM` between the robot's own links); its Jacobian
  -sqrt(w / N) grad d only touches its waypoint's block, so J^T J stays block-tridiagonal.

The validity the search stops at includes "no collision" (every distance >= 0); the
clearance (``--lm-clearance-mm``) is the margin the penalty asks for beyond that.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.collision import collision_model
from ikbench.methods.ours_lm.problem import Evaluation

if TYPE_CHECKING:
    from ikbench.core.collision import CollisionModel
    from ikbench.core.obstacles import Obstacle
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: The clearance the penalty asks for between the robot's own links [mm] (at most the
#: clearance): neighbouring capsules of a conservative model often sit close together.
SELF_CLEARANCE_MM = 1.0
#: Pairs closer than this [mm] are pushed apart while carrying.
ACTIVATION_MM = 40.0
#: Fraction of the missing distance asked for per carried waypoint.
CARRY_GAIN = 0.3
#: Largest avoidance motion per carried waypoint [pose units].
CARRY_MAX_STEP = 3.0


class Avoidance:
    """A robot's collision model with a task's obstacles, for one search.

    Attributes:
        model: the :class:`ikbench.core.collision.CollisionModel`.
        obstacles: the task's obstacles.
        clearance_mm: the margin the refinement's penalty asks for [mm].
        weight: the collision weight w.
    """

    def __init__(self, model: CollisionModel, obstacles: Sequence[Obstacle], clearance_mm: float,
                 weight: float):
        self.model = model
        self.obstacles = tuple(obstacles)
        self.clearance_mm = float(clearance_mm)
        self.weight = float(weight)

    def colliding_waypoints(self, paths: np.ndarray) -> np.ndarray:
        """(K,) waypoints of paths (K, N, dof) where any pair collides."""
        k, n, dof = paths.shape
        report = self.model.check(paths.reshape(-1, dof), self.obstacles)
        return np.any(report.colliding, axis=1).reshape(k, n).sum(axis=1)

    def collision_free(self, paths: np.ndarray) -> np.ndarray:
        """(K,) True for paths (K, N, dof) without any collision."""
        return self.colliding_waypoints(paths) == 0

    def motion(self, q: np.ndarray) -> np.ndarray:
        """(K, dof) [pose units] joint motion away from close pairs (see the module doc)."""
        out = np.zeros_like(q)
        rows, _, d, g, _ = self.model.distance_jacobians(q, self.obstacles, ACTIVATION_MM)
        for row, distance, grad in zip(rows, d, g):
            norm2 = float(grad @ grad)
            if norm2 > 1e-12:
                out[row] += CARRY_GAIN * (ACTIVATION_MM - distance) * grad / norm2
        size = np.abs(out).max(axis=1, keepdims=True)
        return out * np.minimum(1.0, CARRY_MAX_STEP / np.maximum(size, 1e-300))

    def terms(self, poses: np.ndarray, derivatives: bool = True
              ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """The penalty at poses (B, N, dof): (loss (B,), gradient (B, N, dof) = J^T r,
        diagonal blocks (B, N, dof, dof) = J^T J) (None, None without derivatives)."""
        b, n, dof = poses.shape
        rows, pairs, d, g, _ = self.model.distance_jacobians(poses.reshape(-1, dof),
                                                             self.obstacles, self.clearance_mm)
        margin = np.where(self.model.scene(self.obstacles).is_env[pairs], self.clearance_mm,
                          min(self.clearance_mm, SELF_CLEARANCE_MM))
        close = d < margin
        rows, d, g, margin = rows[close], d[close], g[close], margin[close]
        scale = self.weight / n
        loss = np.zeros(b)
        violation = margin - d
        np.add.at(loss, rows // n, scale * violation**2)
        if not derivatives:
            return loss, None, None
        gradient = np.zeros((b * n, dof))
        diagonal = np.zeros((b * n, dof, dof))
        np.add.at(gradient, rows, -scale * violation[:, None] * g)
        np.add.at(diagonal, rows, scale * g[:, :, None] * g[:, None, :])
        return loss, gradient.reshape(b, n, dof), diagonal.reshape(b, n, dof, dof)

    def evaluator(self, evaluate: Callable) -> Callable:
        """``evaluate`` (an LM evaluator) with the collision penalty added."""
        def evaluate_with_collisions(kinematics, problem, poses, derivatives: bool = True):
            base = evaluate(kinematics, problem, poses, derivatives)
            loss, gradient, diagonal = self.terms(poses, derivatives)
            if not derivatives:
                return replace(base, loss=base.loss + loss)
            return Evaluation(base.loss + loss, base.terms, base.gradient + gradient,
                              base.diagonal + diagonal, base.coupling)
        return evaluate_with_collisions


def avoidance_for(robot: Robot, task: Task, clearance_mm: float, weight: float
                  ) -> Avoidance | None:
    """The :class:`Avoidance` of a task (its obstacles, if any, and the robot's own links) on
    a robot with a collision model, else None (nothing to avoid)."""

    model = collision_model(robot)
    if model is None:
        return None
    return Avoidance(model, task.required.obstacles, clearance_mm, weight)


def collision_checker(robot: Robot) -> Any:
    """The robot's collision model for checking many poses: the compiled capsules
    (:class:`ikbench.core.capsules.CapsuleModel`) when numba imports and the geometry is
    capsules, else the coal checker; None without geometry. Both have ``check(poses,
    obstacles)`` and ``distance_jacobians``."""

    model = collision_model(robot)
    if model is None:
        return None
    try:
        capsules = importlib.import_module("ikbench.core.capsules")
    except ImportError:
        return model
    return capsules.capsule_model(robot) or model


def self_colliding(checker: Any, poses: np.ndarray) -> np.ndarray:
    """(B,) waypoints of trajectories (B, N, dof) where the robot touches itself."""
    b, n, dof = poses.shape
    report = checker.check(poses.reshape(-1, dof))
    return report.self_colliding.reshape(b, n).sum(axis=1)

