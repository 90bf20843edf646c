"""The paper's loss L = sum_k c_k L_k as named, individually droppable terms (torch).

Units are the paper's: points in **centimetres**, poses in **motor degrees**, so that the
loss values and the stopping rule (loss < 10) reproduce. With P_i the fingertip points,
v_i the unit pointing directions, p_i the poses, P^g_i / v^g_i the goals:

- L0 = mean over all (n+1) x 3 coordinates of (P_i - P^g_i)^2          line points
- L1 = mean over i of (1 - v_i . v^g_i)                                pointing
- L2 = sum (p_0 - p^s)^2,  L3 = sum (p_n - p^e)^2                      start/end poses
- L4 = sum (P_0 - P^s)^2,  L5 = sum (P_n - P^e)^2                      start/end points
- L6 = mean over n x dof of (p_{i+1} - p_i)^2                          smoothness
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError

# the terms' names and default weights are defined in ikbench.core.weights (the task uses
# them too) and are part of this module's names
from ikbench.core.weights import (  # noqa: F401
    FRAME_TERM_DESCRIPTIONS,
    FRAME_WEIGHTS,
    PAPER_WEIGHTS,
    PAPER_WEIGHTS_TEXT,
    TERM_DESCRIPTIONS,
    TERMS,
)

if TYPE_CHECKING:
    import torch
    from torch import Tensor

    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

MM_PER_CM = 10.0


def parse_terms(text: str) -> list[str]:
    """Parse ``"L1"`` or ``"L2,L3"`` into term names; unknown names raise InputError."""
    names = [t.strip().upper() for t in str(text).split(",") if t.strip()]
    bad = [n for n in names if n not in TERMS]
    if bad or not names:
        raise InputError(
            f"unknown loss term(s) {', '.join(map(repr, bad)) or repr(text)}; "
            f"valid: {', '.join(TERMS)}"
        )
    return list(dict.fromkeys(names))


def parse_weights(text: str | None, base: dict | None = None) -> dict[str, float]:
    """Parse ``"c0=1,c1=50"`` (or ``L0=1``) into weights on top of ``base`` (paper's)."""
    weights = dict(base or PAPER_WEIGHTS)
    if not text:
        return weights
    for item in str(text).split(","):
        key, sep, value = item.partition("=")
        key = key.strip().upper().replace("C", "L", 1) if key.strip() else key
        try:
            number = float(value)
        except ValueError:
            number = float("nan")
        if not sep or key not in TERMS or not np.isfinite(number) or number < 0:
            raise InputError(
                f"weights: {item.strip()!r} is not term=value with term in c0..c6 (or "
                "L0..L6) and a finite value >= 0"
            )
        weights[key] = number
    if not any(weights.values()):
        raise InputError(f"weights: {text!r} sets every term to 0; the loss would be empty")
    return weights


def format_weights(weights: dict) -> str:
    """``{"L0": 1.0, ...}`` -> ``"c0=1,c1=50,..."`` (the --weights syntax)."""
    return ",".join(f"c{name[1:]}={weights.get(name, 0.0):g}" for name in TERMS)


def check_weights(weights: dict[str, float] | str | None) -> None:
    """InputError when ``weights`` is neither a dict, None nor valid ``--weights`` changes."""
    if not isinstance(weights, dict):
        parse_weights(weights)


def resolve_weights(weights: dict[str, float] | str | None, task: Task) -> dict[str, float]:
    """The complete weights for ``task``: a dict as given, or changes (a ``--weights`` string;
    None for none) on top of the task's own default weights, else the paper's."""
    if isinstance(weights, dict):
        return weights
    return parse_weights(weights, task.hints.default_weights)


@dataclass
class LossGoals:
    """Goals of one task as torch tensors, in the loss units (cm, motor degrees)."""

    goal_points_cm: Any         # (n+1, 3) tensor
    goal_directions: Any        # (n+1, 3) unit
    start_pose: Any         # (dof,) or None
    end_pose: Any           # (dof,) or None

    @classmethod
    def from_task(cls, task: Task, dtype: torch.dtype, device: str | torch.device = "cpu"
                  ) -> LossGoals:
        import torch

        def tensor(x):
            return None if x is None else torch.as_tensor(x, dtype=dtype, device=device)

        return cls(tensor(task.goal.points_mm / MM_PER_CM), tensor(task.goal.directions),
                   tensor(task.required.start_pose), tensor(task.required.end_pose))


def loss_terms(points_cm: Tensor, directions: Tensor, poses_deg: Tensor,
               goals: LossGoals) -> dict[str, Tensor]:
    """The seven terms (scalar tensors) for one trajectory.

    Args:
        points_cm: (n+1, 3) fingertip points [cm].
        directions: (n+1, 3) unit pointing directions.
        poses_deg: (n+1, dof) poses [motor deg].
        goals: the task's goals. L2/L3 are 0 when the task fixes no start/end pose.
    """
    zero = poses_deg.new_zeros(())
    return {
        "L0": ((points_cm - goals.goal_points_cm) ** 2).mean(),
        "L1": (1.0 - (directions * goals.goal_directions).sum(-1)).mean(),
        "L2": zero if goals.start_pose is None
        else ((poses_deg[0] - goals.start_pose) ** 2).sum(),
        "L3": zero if goals.end_pose is None
        else ((poses_deg[-1] - goals.end_pose) ** 2).sum(),
        "L4": ((points_cm[0] - goals.goal_points_cm[0]) ** 2).sum(),
        "L5": ((points_cm[-1] - goals.goal_points_cm[-1]) ** 2).sum(),
        "L6": (poses_deg.diff(dim=0) ** 2).mean(),
    }


def weighted_loss(terms: dict[str, Tensor], weights: dict[str, float]) -> Tensor:
    """L = sum_k c_k L_k over the terms whose weight is non-zero."""
    total = None
    for name in TERMS:
        c = weights.get(name, 0.0)
        if c:
            total = terms[name] * c if total is None else total + terms[name] * c
    return total if total is not None else next(iter(terms.values())) * 0.0


def objective(robot: Robot, task: Task, poses_deg: npt.ArrayLike,
              weights: dict[str, float] | None = None) -> tuple[float, dict[str, float]]:
    """Evaluate the loss of given poses (n+1, dof) [motor deg] in float64.

    The one reference evaluation every method's final loss is compared with.

    Returns:
        (L, {term name: L_k}) as floats.
    """
    import torch

    weights = PAPER_WEIGHTS if weights is None else weights
    poses = torch.as_tensor(np.asarray(poses_deg, dtype=float), dtype=torch.float64)
    with torch.no_grad():
        point_m, direction = robot.torch_fk(torch.float64)(poses)
        terms = loss_terms(point_m * 100.0, direction, poses,
                           LossGoals.from_task(task, torch.float64))
        total = weighted_loss(terms, weights)
    return float(total), {k: float(v) for k, v in terms.items()}
