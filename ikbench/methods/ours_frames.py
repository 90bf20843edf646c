"""The paper's optimiser (Adam through pytorch-kinematics) on 6-D pose paths.

A task with goal frames (e.g. a CppFlow problem) is optimised like the paper's trajectories,
the whole path at once, on the 6-D objective of :data:`ikbench.core.losses.FRAME_WEIGHTS`:

- L0: mean squared position error [mm^2];
- L1: mean squared rotation error [deg^2] per component, here through the chordal distance
  |R - R^g|_F^2 = 4 (1 - cos theta) = 2 theta^2 + O(theta^4), i.e. L1 = (180/pi)^2
  |R - R^g|_F^2 / 6, the log map's value to second order and smooth everywhere (the log map's
  gradient is undefined at zero error, where Adam ends up);
- L6: mean squared joint step [deg^2, mm^2 for prismatic joints].

Poses stay within the task's limits through the sigmoid of :mod:`ikbench.methods.ours`. The
paper's stopping rule (loss < 10 in its own units) means nothing here; Adam stops at the first
iterate that meets CppFlow's validity criteria (:mod:`ikbench.core.validity`, checked in the
optimiser's dtype on the poses whose loss it has just computed) and returns it, or after
``max_iterations`` with the lowest-loss poses (``converged`` False).
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, cast

import numpy as np

from ikbench.core.losses import format_weights, resolve_weights
from ikbench.core.validity import (
    MAX_JOINT_CHANGE_DEG,
    MAX_JOINT_CHANGE_MM,
    MAX_POSITION_ERROR_MM,
    MAX_ROTATION_ERROR_DEG,
)
from ikbench.methods.base import Progress, Solution, report_fraction
from ikbench.methods.ours_init import initial_logits

if TYPE_CHECKING:
    from torch import Tensor

    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.methods.ours_settings import AdamSettings

DEG_PER_RAD = 180.0 / math.pi


def frame_loss(T_base_tip: Tensor, poses: Tensor, goal_mm: Tensor, goal_R: Tensor,
               weights: dict[str, float], prismatic: Tensor
               ) -> tuple[Tensor, dict[str, Tensor], dict[str, float]]:
    """(loss, terms {L0, L1, L6}, figures {position_mm, rotation_deg, step_deg, step_mm}) of
    end-frame transforms (N, 4, 4) [m] at poses (N, dof), as torch tensors."""
    import torch

    e_point = T_base_tip[:, :3, 3] * 1000.0 - goal_mm
    chord = ((T_base_tip[:, :3, :3] - goal_R) ** 2).sum(dim=(1, 2))          # 4 (1 - cos)
    steps = poses.diff(dim=0)
    terms = {"L0": (e_point**2).mean(), "L1": chord.mean() * DEG_PER_RAD**2 / 6.0,
             "L6": (steps**2).mean()}
    # a tensor (the integer 0 only when no weight names L0, L1 or L6)
    loss = cast("Tensor", sum(weights.get(k, 0.0) * v for k, v in terms.items()))
    with torch.no_grad():
        angle = 2.0 * torch.asin(torch.clamp(chord.sqrt() / (2.0 * math.sqrt(2.0)), max=1.0))
        revolute = steps[:, ~prismatic]
        revolute = torch.remainder(revolute + 180.0, 360.0) - 180.0
        figures = {"position_mm": float(e_point.norm(dim=1).max()),
                   "rotation_deg": float(angle.max()) * DEG_PER_RAD,
                   "step_deg": float(revolute.abs().max()) if revolute.numel() else 0.0,
                   "step_mm": float(steps[:, prismatic].abs().max()) if prismatic.any()
                   else 0.0}
    return loss, terms, figures


def is_valid(figures: dict) -> bool:
    """CppFlow's criteria on :func:`frame_loss`'s figures (the limits hold by construction)."""
    return (figures["position_mm"] < MAX_POSITION_ERROR_MM
            and figures["rotation_deg"] < MAX_ROTATION_ERROR_DEG
            and figures["step_deg"] < MAX_JOINT_CHANGE_DEG
            and figures["step_mm"] < MAX_JOINT_CHANGE_MM)


def optimise_frames(robot: Robot, task: Task, settings: AdamSettings,
                    progress: Progress | None = None) -> Solution:
    """Adam on a 6-D pose path (see the module docstring); ``settings``: ``AdamSettings``."""
    import torch

    weights = resolve_weights(settings.weights, task)
    dtype = {"float32": torch.float32, "float64": torch.float64}[settings.dtype]
    fk = robot.torch_fk(dtype)
    lower, upper = task.limits(robot)
    lower = np.where(np.isfinite(lower), lower, robot.sample_lower)
    upper = np.where(np.isfinite(upper), upper, robot.sample_upper)
    lo = torch.as_tensor(lower, dtype=dtype)
    span = torch.as_tensor(upper - lower, dtype=dtype)
    goal_mm = torch.as_tensor(task.goal.points_mm, dtype=dtype)
    goal_R = torch.as_tensor(task.goal.rotations, dtype=dtype)
    prismatic = torch.as_tensor(robot.prismatic)
    z = initial_logits(robot, task, dtype, settings.init, settings.seed).clone()
    z.requires_grad_(True)
    optimiser = torch.optim.Adam([z], lr=settings.lr)
    best_loss, best_poses, valid, iterations = math.inf, None, False, 0
    start = time.perf_counter()
    while iterations < settings.max_iterations:
        optimiser.zero_grad()
        poses = lo + torch.sigmoid(z) * span
        loss, _, figures = frame_loss(fk.transform(poses), poses, goal_mm, goal_R, weights,
                                      prismatic)
        value = float(loss.detach())
        if is_valid(figures):
            best_loss, best_poses, valid = value, poses.detach().clone(), True
            break
        if value < best_loss:
            best_loss, best_poses = value, poses.detach().clone()
        loss.backward()
        optimiser.step()
        iterations += 1
        if progress and iterations % settings.progress_every == 0:
            progress.update(task, iterations, value)
            report_fraction(iterations, settings.max_iterations)
    duration = time.perf_counter() - start
    assert best_poses is not None
    return Solution(
        poses=best_poses.to(torch.float64).numpy(), iterations=iterations,
        duration_s=duration, loss=best_loss, converged=valid,
        info={"iterations_per_s": iterations / max(duration, 1e-12), "valid_by_search": valid,
              "dtype": settings.dtype, "init": settings.init, "seed": settings.seed,
              "weights": format_weights(weights)})
