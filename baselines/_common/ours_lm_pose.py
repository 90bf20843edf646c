"""ours-lm's single-pose IK under the protocol of ``ikbench ik`` (ikbench's own method, not a
library: its adapter sits beside the interface, :mod:`ikbench.baselines._common.single_pose`).

ours-lm restarts by itself: :meth:`OursLMSolver.solve_within` takes the target's whole
sequence of initial configurations [pose units] and the budget. Today it runs on the numpy
reference, :func:`ikbench.methods.ours_lm.single_pose.solve_poses`, one target per call: an
attempt from row a stops after :data:`RESTART_AFTER` iterations without success (the last
row's after :data:`~ikbench.baselines._common.single_pose.MAX_STEPS`), and the next row starts
while the budget lasts (checked between attempts: numpy cannot stop inside one). The compiled
single-pose LM (``SinglePoseLM(robot, kind, tolerance).solve(point_mm, rotation, initials,
budget_s)``, restarts and deadline inside its loop) takes exactly these arguments and replaces
the loop here.

Batched (:meth:`OursLMSolver.solve_batch`, throughput only): every target in one numpy batch
from its first row, restarting from the reference's own seeded random poses (up to A - 1 of
them) with :data:`BATCH_MAX_ITERATIONS` iterations in all; no wall-clock budget; one thread.
"""

from __future__ import annotations

import time

import numpy as np

from ikbench.baselines._common.single_pose import MAX_STEPS, BatchOut, PoseOut, PoseSolver

#: Iterations of one attempt before the next row (as the reference's ``restart_after``).
RESTART_AFTER = 15
#: The batch: LM iterations per target in all (restarts included).
BATCH_MAX_ITERATIONS = 1500


class OursLMSolver(PoseSolver):
    """ours-lm's projected LM on ``[e_point / tol_mm, e_rot / tol_deg]`` (see the module
    docstring)."""

    name, library, modules = "ours-lm", "ikbench", ()
    restarts_itself = True
    batched = True
    pose_units = True
    iterations_are = "LM iterations (all attempts)"

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        """One descent from ``q_init`` [pose units] (:data:`MAX_STEPS` iterations at most)."""
        return self.solve_within(np.asarray(q_init, dtype=float)[None], point_m, rotation,
                                 float("inf"))

    def solve_within(self, initials: np.ndarray, point_m: np.ndarray, rotation: np.ndarray,
                     budget_s: float) -> PoseOut:
        """From the rows of ``initials`` (A, dof) [pose units] in order until success, the
        last row or the budget [s] (see the module docstring)."""
        from ikbench.methods.ours_lm.single_pose import solve_poses

        deadline = time.perf_counter() + budget_s
        point_mm = np.asarray(point_m, dtype=float)[None] * 1000.0
        goal_R = np.asarray(rotation, dtype=float)[None]
        iterations = 0
        for a in range(len(initials)):
            last = a + 1 == len(initials)
            out = solve_poses(self.robot, point_mm, goal_R, initials[a:a + 1], self.tolerance,
                              position_only=self.kind == "position",
                              max_iterations=MAX_STEPS if last else RESTART_AFTER)
            iterations += int(out.iterations[0])
            if out.converged[0] or last or time.perf_counter() >= deadline:
                break
        return PoseOut(out.poses[0], iterations, bool(out.converged[0]), a + 1)

    def solve_batch(self, initials: np.ndarray, points_m: np.ndarray, rotations: np.ndarray,
                    budget_s: float, threads: int | None = None) -> BatchOut:
        """Every target in one numpy batch (see the module docstring; ``budget_s`` and
        ``threads`` are not used by the numpy reference: no deadline, one thread)."""
        from ikbench.methods.ours_lm.single_pose import solve_poses

        rows = initials.shape[1]
        out = solve_poses(self.robot, np.asarray(points_m) * 1000.0, rotations,
                          initials[:, 0], self.tolerance,
                          position_only=self.kind == "position",
                          max_iterations=BATCH_MAX_ITERATIONS, restarts=rows - 1,
                          restart_after=RESTART_AFTER)
        return BatchOut(out.poses, out.restarts + 1, 1)
