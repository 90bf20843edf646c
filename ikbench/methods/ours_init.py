"""The initial values of the paper's Adam variables (the logits of the poses in their limits).

Shared by the 3-D solve (:mod:`ikbench.methods.ours`) and the 6-D one
(:mod:`ikbench.methods.ours_frames`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.errors import InputError

if TYPE_CHECKING:
    import torch
    from torch import Tensor

    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: Logit clamp used when mapping the initial poses back through the sigmoid.
LOGIT_EPS = 1e-6
#: How the poses start: seeded random logits, or the joint interpolation.
INITS = ("random", "interpolation")


def initial_logits(robot: Robot, task: Task, dtype: torch.dtype, init: str = "random",
                   seed: int = 0) -> Tensor:
    """Initial logits (n+1, dof): seeded uniform +-1/sqrt(n+1), or the joint interpolation.

    The interpolation runs from the task's start to its end pose; a task that pins neither
    (a letter) starts with every pose at its reference pose.
    """
    import torch

    if init == "random":
        generator = torch.Generator().manual_seed(seed)
        bound = 1.0 / math.sqrt(task.goal.steps + 1)
        unit = torch.rand(task.goal.steps + 1, robot.dof, generator=generator, dtype=torch.float64)
        return ((unit * 2.0 - 1.0) * bound).to(dtype)

    if init != "interpolation":
        raise InputError(f"--init: {init!r} is not one of {', '.join(INITS)}")
    lo, hi = robot.sample_lower, robot.sample_upper  # continuous joints: +-180 deg
    t = np.linspace(0.0, 1.0, task.goal.steps + 1)[:, None]
    if task.required.start_pose is not None and task.required.end_pose is not None:
        poses = task.required.start_pose + t * (task.required.end_pose - task.required.start_pose)
    elif task.hints.reference_pose is not None:
        poses = task.hints.reference_pose + 0.0 * t
    else:
        raise InputError(f"trajectory {task.name!r}: ours --init interpolation needs a start "
                         "and an end pose or a reference pose")
    unit = np.clip((poses - lo) / (hi - lo), LOGIT_EPS, 1.0 - LOGIT_EPS)
    return torch.tensor(np.log(unit / (1.0 - unit)), dtype=dtype)
