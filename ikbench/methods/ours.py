"""The paper's method ("ours"): the whole trajectory optimised at once with Adam.

Variables are logits z (n+1, dof); poses p = lo + sigmoid(z) * (hi - lo) stay inside the motor
ranges. FK runs through pytorch-kinematics on the URDF, batched over the n+1 poses, and the
loss is :mod:`ikbench.losses` in the paper's units.

Initial logits (``init``):

- ``"random"`` (default): uniform in +-1/sqrt(n+1), seeded - the initialisation of the
  authors' released code (PyTorch's default for their ``nn.Linear(n+1, 7)``). It reproduces the
  iteration counts and losses of the paper's Table 1.
- ``"interpolation"``: the joint-space linear interpolation from start to touch pose mapped
  back through the sigmoid, as the paper's text describes. It starts much closer to the goal,
  so the stopping rule fires after about 100 iterations instead of the paper's 369-12394.

Stopping rule (the authors' code): append each step's loss to a history seeded with 1000;
stop when loss < 10 and loss > the median of the last 10 entries. The result is the poses with the
lowest loss seen among those below 10 (the poses at which that loss was evaluated); if no
loss fell below 10 before the iteration cap, the lowest loss overall (``converged`` False).
"""

from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass, field

import numpy as np

from ikbench.errors import InputError
from ikbench.losses import PAPER_WEIGHTS, LossGoals, loss_terms, parse_weights, weighted_loss
from ikbench.methods import Method, Solution, register

DTYPES = ("float32", "float64")
#: Logit clamp used when mapping the initial poses back through the sigmoid.
LOGIT_EPS = 1e-6


@dataclass
class AdamSettings:
    """Settings of the paper's optimiser.

    Attributes:
        lr: Adam learning rate.
        max_iterations: iteration cap.
        dtype: ``"float32"`` (paper) or ``"float64"``.
        weights: loss weights c0..c6 keyed L0..L6.
        stop_below: the stopping rule's loss threshold.
        median_window: the stopping rule's number of previous losses.
        history_seed: the loss history's initial value.
        progress_every: report progress every this many iterations.
    """

    lr: float = 0.1
    max_iterations: int = 15000
    dtype: str = "float32"
    weights: dict = field(default_factory=lambda: dict(PAPER_WEIGHTS))
    stop_below: float = 10.0
    median_window: int = 10
    history_seed: float = 1000.0
    progress_every: int = 250
    init: str = "random"
    seed: int = 0


INITS = ("random", "interpolation")


def initial_logits(robot, task, dtype, init: str = "random", seed: int = 0):
    """Initial logits (n+1, dof): seeded uniform +-1/sqrt(n+1), or the joint interpolation."""
    import torch

    if init == "random":
        generator = torch.Generator().manual_seed(seed)
        bound = 1.0 / math.sqrt(task.steps + 1)
        unit = torch.rand(task.steps + 1, robot.dof, generator=generator, dtype=torch.float64)
        return ((unit * 2.0 - 1.0) * bound).to(dtype)

    if init != "interpolation":
        raise InputError(f"--init: {init!r} is not one of {', '.join(INITS)}")
    lo, hi = robot.lower_motor_deg, robot.upper_motor_deg
    if task.start_pose_deg is None or task.end_pose_deg is None:
        raise InputError(f"trajectory {task.name!r}: ours needs a start and an end pose")
    t = np.linspace(0.0, 1.0, task.steps + 1)[:, None]
    poses = task.start_pose_deg + t * (task.end_pose_deg - task.start_pose_deg)
    unit = np.clip((poses - lo) / (hi - lo), LOGIT_EPS, 1.0 - LOGIT_EPS)
    return torch.tensor(np.log(unit / (1.0 - unit)), dtype=dtype)


def optimise(robot, task, settings: AdamSettings, progress=None, logits=None) -> Solution:
    """Run the paper's Adam optimisation for one task; return the best poses below 10.

    Args:
        robot: the robot.
        task: goal points and directions, start and end poses.
        settings: optimiser settings.
        progress: optional object with ``update(task, iteration, loss)``.
        logits: optional initial logits (n+1, dof); default :func:`initial_logits`.
    """
    import torch

    dtype = {"float32": torch.float32, "float64": torch.float64}[settings.dtype]
    fk = robot.torch_fk(dtype)
    lo = torch.as_tensor(robot.lower_motor_deg, dtype=dtype)
    span = torch.as_tensor(robot.upper_motor_deg - robot.lower_motor_deg, dtype=dtype)
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
        loss = weighted_loss(loss_terms(point_m * 100.0, direction, poses, goals),
                             settings.weights)
        loss.backward()
        optimiser.step()
        iterations += 1
        value = float(loss.detach())
        below = value < settings.stop_below
        if (below and (not best_below or value < best_loss)) or (
            not best_below and value < best_loss
        ):
            best_loss, best_poses, best_below = value, poses.detach().clone(), below
        if progress and iterations % settings.progress_every == 0:
            progress.update(task, iterations, value)
        history.append(value)
        if below and value > statistics.median(history[-settings.median_window:]):
            converged = True
            break
    duration = time.perf_counter() - start
    return Solution(
        poses_deg=best_poses.to(torch.float64).numpy(),
        iterations=iterations,
        duration_s=duration,
        loss=best_loss,
        converged=converged,
        info={"iterations_per_s": iterations / duration, "hit_cap": not converged,
              "dtype": settings.dtype, "init": settings.init, "seed": settings.seed},
    )


@register
class Ours(Method):
    """The paper's method: sigmoid logits + Adam through differentiable FK."""

    name = "ours"
    description = "the paper's method: whole trajectory by Adam through pytorch-kinematics FK"
    options = {"dtype": "dtype", "lr": "lr", "max_iterations": "max_iterations",
               "weights": "weights", "init": "init", "seed": "seed"}

    def __init__(self, dtype: str = "float32", lr: float = 0.1, max_iterations: int = 15000,
                 weights: dict | str | None = None, init: str = "random", seed: int = 0):
        if dtype not in DTYPES:
            raise InputError(f"--dtype: {dtype!r} is not one of {', '.join(DTYPES)}")
        if init not in INITS:
            raise InputError(f"--init: {init!r} is not one of {', '.join(INITS)}")
        if not (lr > 0 and math.isfinite(lr)):
            raise InputError(f"--lr: {lr!r} must be a positive number")
        if max_iterations < 1:
            raise InputError(f"--max-iterations: {max_iterations!r} must be >= 1")
        if isinstance(weights, str) or weights is None:
            weights = parse_weights(weights)
        self.settings = AdamSettings(lr=lr, max_iterations=max_iterations, dtype=dtype,
                                     weights=weights, init=init, seed=seed)

    @classmethod
    def add_arguments(cls, group) -> None:
        group.add_argument("--dtype", choices=DTYPES, default=None,
                           help="ours: floating-point type of the optimisation (default float32)")
        group.add_argument("--lr", type=float, default=None,
                           help="ours: Adam learning rate (default 0.1)")
        group.add_argument("--max-iterations", type=int, default=None,
                           help="ours: iteration cap (default 15000)")
        group.add_argument("--weights", default=None,
                           help="loss weights to change, e.g. c1=20,c6=5 (default: the "
                           "paper's c0=1,c1=50,c2=5,c3=100,c4=10,c5=200,c6=1)")
        group.add_argument("--init", choices=INITS, default=None,
                           help="ours: initial logits - random (the authors' code, reproduces "
                           "Table 1; default) or interpolation (the paper's text)")
        group.add_argument("--seed", type=int, default=None,
                           help="ours: seed of the random initialisation (default 0)")

    def solve(self, robot, task, progress=None) -> Solution:
        return optimise(robot, task, self.settings, progress)
