"""The sequential walk the point-by-point library methods share.

The walk starts at the touch pose and solves the goal points n-1, ..., 0 one at a time, each
warm-started at the pose solved before it (the previous point's, the touch pose for n-1), as
the paper's authors walked their ikpy baseline. Row n *is* the touch pose, bit for bit.
Nothing ties the walk to the start pose. A pose path (a CppFlow problem) has no touch pose:
it is walked forward instead, goal 0 solved from the home pose (``goals.q_home``), each next
goal from the previous solution.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ikbench.methods.base import report_fraction
from ikbench.schemes.chain import Chain, Goals


class PointResult(NamedTuple):
    """One point's solve as a library returned it.

    Attributes:
        q: (dof,) joint values [rad, m].
        iterations: the library's iterations (or solver calls) spent on this point.
        ok: whether the library reported success (its own tolerance met).
    """

    q: np.ndarray
    iterations: int
    ok: bool


@dataclass
class Walk:
    """The walk's result in URDF units.

    Attributes:
        q: (N, dof) joint values [rad, m]; row N-1 is the touch pose.
        iterations: sum of the points' iterations.
        failed: points (ascending) whose solve the library did not report as a success, or
            that returned non-finite values (those keep their warm start).
        clipped: points whose joint values the library left outside the limits (clipped onto
            them here; empty for every library we measured).
    """

    q: np.ndarray
    iterations: int
    failed: list[int] = field(default_factory=list)
    clipped: list[int] = field(default_factory=list)

    def record(self, i: int, result: PointResult, chain: Chain, fallback: np.ndarray) -> None:
        """Keep point ``i``'s solve as row i: non-finite values keep ``fallback`` (the warm
        start) and count as failed, values outside the limits are clipped (and noted)."""
        qi = np.asarray(result.q, dtype=float).reshape(chain.dof)
        ok = bool(result.ok)
        if not np.all(np.isfinite(qi)):
            qi, ok = np.array(fallback, dtype=float), False
        clipped = chain.clip(qi)
        if not np.array_equal(clipped, qi):
            self.clipped.append(i)
        self.q[i] = clipped
        self.iterations += int(result.iterations)
        if not ok:
            self.failed.append(i)

    def info(self) -> dict:
        """Flat figures for details.csv."""
        return {"points_solved": len(self.q) - 1, "points_not_converged": len(self.failed),
                "failed_points": " ".join(map(str, self.failed)),
                "clipped_points": len(self.clipped)}


#: ``solve_point(i, q_warm) -> PointResult``: solve goal i from the warm start q_warm (dof,).
PointSolver = Callable[[int, np.ndarray], PointResult]


def walk_back(solve_point: PointSolver, chain: Chain, goals: Goals) -> Walk:
    """Walk from the touch pose back to goal 0 (see the module docstring).

    Args:
        solve_point: solves one goal from a warm start (the previous solution).
        chain: the chain (its limits clip what a library leaves outside them).
        goals: the task's goals; ``goals.q_touch`` must be set.
    """
    n_points = len(goals)
    q = np.empty((n_points, chain.dof))
    if goals.q_touch is not None:
        q[-1] = goals.q_touch
        order = [(i, i + 1) for i in range(n_points - 2, -1, -1)]
    elif goals.q_home is not None:  # a pose path: forward from the home pose
        order = [(i, i - 1) for i in range(n_points)]
    else:
        raise ValueError("the sequential walk starts at the touch pose or, for a pose path, "
                         "at the home pose; the goals have neither")
    walk = Walk(q, 0)
    for k, (i, previous) in enumerate(order, 1):
        warm = np.array(goals.q_home if previous < 0 else q[previous], dtype=float)
        walk.record(i, solve_point(i, warm.copy()), chain, warm)
        report_fraction(k, len(order))
    walk.failed.sort()
    walk.clipped.sort()
    return walk
