"""The differential-IK scheme pink and mink share (one QP per step, per goal point).

Per goal point, from the warm start, repeat until the position error is below ``tolerance``
[m] and the pointing error below ``tolerance`` [rad], or ``max_steps`` steps:

1. measure the pointing frame P (the end frame turned so that its z-axis is the pointing
   axis, :func:`baselines._geometry.frame_with_z_on`) and the errors;
2. set the frame task's target: the goal point, and the rotation nearest P's whose z-axis is
   the goal direction (so the roll error is 0 and the orientation cost ``[w, w, 0]`` on P's
   body twist frees the roll); for 6-D goals the goal rotation itself, cost ``[w, w, w]``;
3. one QP: ``v = solve_ik(configuration, tasks, dt, damping, limits)``, q <- q + v dt.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from baselines._chain import Goals
from baselines._geometry import angle_between_rad, closest_rotation_with_axis, rotation_angle_rad

Z = np.array([0.0, 0.0, 1.0])


def target_rotation(goals: Goals, i: int, R_P: np.ndarray, R_EP: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) the frame task asks of P for goal ``i`` (see the module doc)."""
    if goals.rotations is not None:
        return goals.rotations[i] @ R_EP
    return closest_rotation_with_axis(R_P, Z, goals.directions[i])


def errors(goals: Goals, i: int, p_P, R_P, R_EP) -> tuple[float, float]:
    """(position error [m], orientation error [rad]) of P at (p_P (3,), R_P (3, 3)): the angle
    between its z-axis and the goal direction, or to the goal rotation for 6-D goals."""
    position = float(np.linalg.norm(np.asarray(p_P) - goals.points_m[i]))
    if goals.rotations is not None:
        return position, rotation_angle_rad(R_P, goals.rotations[i] @ R_EP)
    return position, angle_between_rad(np.asarray(R_P) @ Z, goals.directions[i])


def orientation_costs(goals: Goals, cost: float) -> list[float]:
    """Per-axis orientation cost of P's frame task: the roll (z) free unless 6-D goals."""
    return [cost, cost, cost if goals.rotations is not None else 0.0]


def converge(measure: Callable[[], tuple[float, float]], step: Callable[[], None],
             tolerance: float, max_steps: int) -> tuple[int, bool]:
    """Take ``step()`` until both errors of ``measure()`` are below ``tolerance`` or
    ``max_steps`` steps; return (steps taken, converged)."""
    steps = 0
    while True:
        position, angle = measure()
        if position < tolerance and angle < tolerance:
            return steps, True
        if steps >= max_steps:
            return steps, False
        step()
        steps += 1
