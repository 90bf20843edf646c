"""The tracking scheme: differential IK from the recorded start pose, landing on the touch pose.

This is how the IK libraries solve the paper's task (both poses fixed), the way pink and mink
are meant to be used: start at the start pose and track the goal points one after the other,
each solve warm-started at the pose before, with a posture term that resolves the arm's
redundancy and brings it onto the touch pose at the end.

Per step i = 1 .. n-1 the library is asked for (URDF units, base frame):

- **position**: the goal point P_i (the hard part: every adapter converges it to its
  tolerance);
- **pointing** (when the task's contract asks for it): the pointing axis along a scheduled
  direction ``directions[i]``: from the start pose's own pointing direction it turns to the
  goal direction by the first judged step (``contract.judged_from(n)``, spherical
  interpolation), follows the goal direction, and over the last :data:`LANDING_FRACTION` of
  the steps turns to the touch pose's own pointing direction, so the arm arrives at the touch
  pose without a jump. The roll about the axis stays free;
- **posture**: the pose ``posture[i]`` = q_start + (i / n) (q_touch - q_start) with a small
  weight (each adapter's ``posture_cost``), which only picks among the poses that meet the two
  goals above; at step n it is the touch pose itself, which meets them exactly.

Row 0 is the start pose and row n the touch pose, exactly as given; the study judges whether
the steps next to them stay within the speed limits. Tasks without a start pose (letters,
pose paths) cannot be tracked this way; they are refused before any solve.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ikbench.core.contract import DEFAULT_POINTING_FROM
from ikbench.core.errors import InputError
from ikbench.methods.base import report_fraction
from ikbench.schemes.chain import Chain, Goals
from ikbench.schemes.walk import PointResult, Walk

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: The last part of the steps over which the pointing turns to the touch pose's own.
LANDING_FRACTION = 0.2
#: The schemes a sequential library method offers (its ``scheme`` setting).
SCHEMES = ("track", "walk")
SCHEME_HELP = ("track (from the start pose along the goal points onto the touch pose: the "
               "paper's task) or walk (the authors' walk back from the touch pose: the start "
               "pose is free)")


@dataclass(frozen=True)
class TrackPlan:
    """What the tracking scheme asks at each step (URDF units, base frame).

    Attributes:
        points_m: (N, 3) goal points [m] (N = n + 1).
        directions: (N, 3) unit scheduled pointing directions, or None when the task does not
            ask for pointing.
        posture: (N, dof) posture targets [rad, m]: start to touch pose, linearly.
        q_start: (dof,) the start pose [rad, m] (row 0).
        q_touch: (dof,) the touch pose [rad, m] (row n).
        judged_from: the first step whose pointing the contract judges.
    """

    points_m: np.ndarray
    directions: np.ndarray | None
    posture: np.ndarray
    q_start: np.ndarray
    q_touch: np.ndarray
    judged_from: int

    def __len__(self) -> int:
        return len(self.points_m)


def slerp(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    """The unit vector a fraction ``t`` of the way from unit ``a`` to unit ``b`` (great
    circle); for opposite vectors it turns about any axis orthogonal to ``a``."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    angle = float(np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b))
    if angle < 1e-12:
        return a.copy()
    axis = np.cross(a, b)
    if np.linalg.norm(axis) < 1e-12:  # opposite: any orthogonal axis
        axis = np.cross(a, np.eye(3)[np.argmin(np.abs(a))])
    axis /= np.linalg.norm(axis)
    phi = t * angle
    return (a * np.cos(phi) + np.cross(axis, a) * np.sin(phi)
            + axis * (axis @ a) * (1 - np.cos(phi)))


def require_start_and_touch(task: Task, method: str) -> None:
    """InputError unless the task fixes both poses (the scheme starts and lands on them)."""
    if task.required.start_pose is None or task.required.end_pose is None:
        missing = "no start pose" if task.required.start_pose is None else "no touch pose"
        raise InputError(f"trajectory {task.name!r}: --method {method} (scheme track) starts at "
                         f"the start pose and lands on the touch pose; the task has {missing} "
                         "(for letters, polylines and splines use --method ours or --method "
                         "ours-lm)")


def plan_track(robot: Robot, task: Task, goals: Goals) -> TrackPlan:
    """The per-step targets of the tracking scheme for ``task`` (see the module doc)."""
    contract = task.required.contract
    pointing = True if contract is None else bool(contract.pointing)
    n = len(goals) - 1
    judged_from = (contract.judged_from(n) if contract is not None
                   else int(np.ceil(DEFAULT_POINTING_FROM * n)))
    q_start, q_touch = goals.q_start, goals.q_touch
    assert q_start is not None and q_touch is not None  # a tracked line pins both poses
    s = np.linspace(0.0, 1.0, n + 1)[:, None]
    posture = q_start + s * (q_touch - q_start)
    directions = None
    if pointing:
        assert task.required.start_pose is not None and task.required.end_pose is not None  # as q_*
        fk = robot.fk(np.stack([task.required.start_pose, task.required.end_pose]))
        d_start, d_touch = fk.direction
        goal = goals.directions
        landing = max(1, int(round(LANDING_FRACTION * n)))
        directions = goal.copy()
        for i in range(n + 1):
            if i < judged_from:
                directions[i] = slerp(d_start, goal[i], i / judged_from)
            elif i > n - landing:
                directions[i] = slerp(goal[i], d_touch, (i - (n - landing)) / landing)
        directions[0], directions[n] = d_start, d_touch
    return TrackPlan(goals.points_m, directions, posture, q_start, q_touch, judged_from)


def speed_box(q_previous: np.ndarray, q_touch: np.ndarray, steps_left: int,
              step: np.ndarray, lower: np.ndarray, upper: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) (dof,) [rad, m]: the joint box of a tracking step under a speed limit:
    within the limits, within ``step`` of the previous pose and within ``steps_left`` steps
    of the touch pose (so it stays reachable). Where these do not meet, low > high: the
    caller decides which wins."""
    low = np.maximum.reduce([lower, q_previous - step, q_touch - steps_left * step])
    high = np.minimum.reduce([upper, q_previous + step, q_touch + steps_left * step])
    return low, high


def track(solve_point: Callable[[int, np.ndarray], PointResult], chain: Chain,
          plan: TrackPlan) -> Walk:
    """Solve steps 1 .. n-1 forward from the start pose, each from the previous solution.

    Args:
        solve_point: ``solve_point(i, q_warm) -> PointResult``: step i's goals
            (``plan.points_m[i]``, ``plan.directions[i]``, ``plan.posture[i]``) from q_warm.
        chain: the chain (its limits clip what a library leaves outside them).
        plan: the targets (:func:`plan_track`).

    Returns:
        A :class:`ikbench.schemes.walk.Walk`; row 0 the start pose, row n the touch pose.
    """
    n_points = len(plan)
    q = np.empty((n_points, chain.dof))
    q[0], q[-1] = plan.q_start, plan.q_touch
    walk = Walk(q, 0)
    for i in range(1, n_points - 1):
        warm = np.array(q[i - 1], dtype=float)
        walk.record(i, solve_point(i, warm.copy()), chain, warm)
        report_fraction(i, n_points - 2)
    return walk
