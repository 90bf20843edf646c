"""The paper's method ("ours"): the whole trajectory optimised at once with Adam.

Variables are logits z (n+1, dof); poses p = lo + sigmoid(z) * (hi - lo) stay inside the joint
limits (motor ranges for NICO; continuous joints within +-180 deg). FK runs through
pytorch-kinematics on the URDF, batched over the n+1 poses, and the loss is
:mod:`ikbench.core.losses` in the paper's units.

Initial logits (``init``):

- ``"random"`` (default): uniform in +-1/sqrt(n+1), seeded - the initialisation of the
  authors' released code (PyTorch's default for their ``nn.Linear(n+1, 7)``). It reproduces the
  iteration counts and losses of the paper's Table 1.
- ``"interpolation"``: the joint-space linear interpolation from start to touch pose mapped
  back through the sigmoid, as the paper's text describes. It starts much closer to the goal,
  so the stopping rule fires after about 100 iterations instead of the paper's 369-12394.

Stopping rule (``stop``):

- ``"paper"`` (default; the authors' code for lines): append each step's loss to a history
  seeded with 1000; stop when loss < 10 and loss > the median of the last 10 entries. The
  result is the poses with the lowest loss seen among those below 10 (the poses at which that
  loss was evaluated); if no loss fell below 10 before the iteration cap, the lowest loss
  overall (``converged`` False).
- ``"none"`` (the authors' letter script): run exactly ``max_iterations`` iterations and keep
  the poses with the lowest loss seen.

Weights: a task may name the weights it is meant for (``Task.hints.default_weights``, e.g. a
letter's c0=1, c1=50, c6=1); ``--weights`` changes then apply on top of those instead of the
paper's.
"""

from __future__ import annotations

import math
import statistics
import time
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from ikbench.core.losses import (
    LossGoals,
    format_weights,
    loss_terms,
    resolve_weights,
    weighted_loss,
)
from ikbench.methods.base import Capabilities, Method, Progress, Solution, report_fraction
from ikbench.methods.ours_frames import optimise_frames
from ikbench.methods.ours_init import initial_logits
from ikbench.methods.ours_settings import DTYPES as DTYPES
from ikbench.methods.ours_settings import STOPS as STOPS
from ikbench.methods.ours_settings import AdamSettings
from ikbench.methods.registry import Adapter

if TYPE_CHECKING:
    from torch import Tensor

    from ikbench.core.robot import Robot
    from ikbench.core.task import Task


def optimise(robot: Robot, task: Task, settings: AdamSettings, progress: Progress | None = None,
             logits: Tensor | None = None) -> Solution:
    """Run the paper's Adam optimisation for one task; return the best poses (see module doc).

    Args:
        robot: the robot.
        task: goal points and directions, start and end poses.
        settings: optimiser settings.
        progress: optional object with ``update(task, iteration, loss)``.
        logits: optional initial logits (n+1, dof); default :func:`initial_logits`.
    """
    import torch

    weights = resolve_weights(settings.weights, task)
    settings = replace(settings, weights=weights)
    dtype = {"float32": torch.float32, "float64": torch.float64}[settings.dtype]
    fk = robot.torch_fk(dtype)
    # the sigmoid keeps poses within the limits (continuous joints: within +-180 deg)
    lo = torch.as_tensor(robot.sample_lower, dtype=dtype)
    span = torch.as_tensor(robot.sample_upper - robot.sample_lower, dtype=dtype)
    goals = LossGoals.from_task(task, dtype)
    if logits is None:
        logits = initial_logits(robot, task, dtype, settings.init, settings.seed)
    z = logits.to(dtype).clone()
    z.requires_grad_(True)
    optimiser = torch.optim.Adam([z], lr=settings.lr)

    history = [settings.history_seed]
    best_loss, best_poses, best_below = math.inf, None, False
    iterations, converged = 0, False
    start = time.perf_counter()
    while iterations < settings.max_iterations:
        optimiser.zero_grad()
        poses = lo + torch.sigmoid(z) * span
        point_m, direction = fk(poses)
        loss = weighted_loss(loss_terms(point_m * 100.0, direction, poses, goals), weights)
        loss.backward()
        optimiser.step()
        iterations += 1
        value = float(loss.detach())
        below = settings.stop == "paper" and value < settings.stop_below
        if (below and (not best_below or value < best_loss)) or (
            not best_below and value < best_loss
        ):
            best_loss, best_poses, best_below = value, poses.detach().clone(), below
        if progress and iterations % settings.progress_every == 0:
            progress.update(task, iterations, value)
            report_fraction(iterations, settings.max_iterations)
        history.append(value)
        if below and value > statistics.median(history[-settings.median_window:]):
            converged = True
            break
    duration = time.perf_counter() - start
    converged = converged or settings.stop == "none"
    assert best_poses is not None  # at least one iteration ran
    return Solution(
        poses=best_poses.to(torch.float64).numpy(),
        iterations=iterations,
        duration_s=duration,
        loss=best_loss,
        converged=converged,
        info={"iterations_per_s": iterations / duration, "hit_cap": not converged,
              "dtype": settings.dtype, "init": settings.init, "seed": settings.seed,
              "stop": settings.stop, "weights": format_weights(weights)},
    )


class Ours(Method):
    """The paper's method: sigmoid logits + Adam through differentiable FK."""

    name = "ours"
    description = "the paper's method: whole trajectory by Adam through pytorch-kinematics FK"
    library = "torch"
    Settings = AdamSettings
    bench_rounds = 3  # tens of seconds per round on the paper's seven targets
    capabilities = Capabilities(frames=True)  # 6-D pose paths: ikbench.methods.ours_frames

    def runtime(self) -> dict[str, Any]:
        """Adam on torch on the CPU, in the settings' precision, on torch's threads."""
        import torch

        return {"backend": f"torch (cpu, {self.settings.dtype})",
                "threads": torch.get_num_threads()}

    def settings_for(self, task: Task) -> AdamSettings:
        """The settings for one task, with its complete weights (see :func:`resolve_weights`)."""
        return replace(self.settings, weights=resolve_weights(self.settings.weights, task))

    def prepare(self, robot: Robot) -> None:
        import torch

        robot.torch_fk({"float32": torch.float32, "float64": torch.float64}[self.settings.dtype])
        # torch's first optimiser imports torch._dynamo (seconds): not part of any solve
        torch.optim.Adam([torch.zeros(1, requires_grad=True)])

    def solve(self, robot: Robot, task: Task, progress: Progress | None = None) -> Solution:
        if task.goal.rotations is not None:
            return optimise_frames(robot, task, self.settings_for(task), progress)
        return optimise(robot, task, self.settings_for(task), progress)


#: What ikbench brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="ikbench", requires=("torch", "pytorch_kinematics"),
                  methods=(Ours,), solvers=(), rank=10)
