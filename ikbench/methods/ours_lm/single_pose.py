"""Single-pose IK of many targets at once on ours-lm's machinery (``ikbench ik``).

Each target is one end-frame pose (a point [mm] and a rotation) or one point; each starts
from its own initial pose. All targets are solved in one batch by a projected
Levenberg-Marquardt loop on the residual ``r = [e_point / tol_mm, e_rot / tol_deg]`` (the
errors of :func:`.frames.errors_from_frames`: mm, and the SO(3) log map in degrees, with the
exact Jacobian of the vectorised chain kinematics, ``robot.chain_kinematics().frames``),
scaled by the study's tolerances so that one unit of either counts the same. Per target and
iteration: ``(J^T J + lambda (diag(J^T J) + eps I)) dq = -J^T r``, the step moved into the
joint limits (:func:`into_limits`: a revolute joint by whole turns where that brings it
within them, the same frame, else clipped); a joint on a limit that the step pushes further
out, where the move would clip it back, is left out of the equations and the step solved
again for the others (the projection discards that joint's part, which only shrank the
others': on Tiago's arm the first descent ended against a limit after its 100 iterations on
half the targets); accepted when |r| drops (lambda / 3), else rejected (lambda * 4). A
target leaves the batch once its errors are below ``stop`` times the tolerances, or when
lambda exceeds :data:`STALLED` (stuck in a local minimum or on a limit), or after
``max_iterations``. Only the targets still in the batch are evaluated.

``restarts``: a target that is stuck (or not done ``restart_after`` iterations after its
(re)start) is restarted from a fresh uniformly random pose (a
generator seeded with ``seed``: deterministic), up to ``restarts`` times, with the iteration
budget shared - as TRAC-IK and KDL restart within their time budget.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ikbench.methods.ours_lm.frames import errors_from_frames

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

#: A target whose damping exceeds this made no progress for many iterations (stuck).
STALLED = 1e8
#: Largest joint step [pose units] of one iteration.
MAX_STEP = 30.0
#: lambda at every (re)start.
INITIAL_DAMPING = 1e-3


@dataclass
class BatchIK:
    """What :func:`solve_poses` returns (B targets).

    Attributes:
        poses: (B, dof) solutions [pose units], within the limits.
        iterations: (B,) LM iterations spent on each target (restarts included).
        converged: (B,) the errors fell below ``stop`` times the tolerances.
        restarts: (B,) restarts used.
    """

    poses: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    restarts: np.ndarray


def into_limits(robot: Robot, q: np.ndarray, lower: np.ndarray, upper: np.ndarray
                ) -> np.ndarray:
    """Poses (..., dof) [pose units] moved into the limits: each value within them as it is;
    a revolute joint's turned by the fewest whole turns (360 joint deg) that bring it within
    them (the same frame: a step that crosses a limit a joint's range exceeds by a turn goes
    on instead of stopping there); what no turn brings within is clipped."""
    turn = np.where(robot.prismatic, np.inf,
                    np.abs(360.0 / np.broadcast_to(np.asarray(robot.scale, dtype=float),
                                                   (robot.dof,))))
    with np.errstate(invalid="ignore"):
        down = q - turn * np.ceil((q - upper) / turn)
        up = q + turn * np.ceil((lower - q) / turn)
    out = np.where((q > upper) & (down >= lower), down, q)
    out = np.where((q < lower) & (up <= upper), up, out)
    return np.clip(out, lower, upper)


def _residuals(frames, q, goal_mm, goal_R, scale, position_only: bool):
    """(r (K, k), J (K, k, dof)) of poses q (K, dof) scaled by ``scale`` (tol_mm, tol_deg)."""
    point_m, rotation, j_point_m, j_angular = frames(q)
    e_point, e_rot, j_point, j_rot = errors_from_frames(point_m, rotation, j_point_m, j_angular,
                                                        goal_mm, goal_R)
    if position_only:
        return e_point / scale[0], j_point / scale[0]
    return (np.concatenate([e_point / scale[0], e_rot / scale[1]], -1),
            np.concatenate([j_point / scale[0], j_rot / scale[1]], -2))


def solve_poses(robot: Robot, goal_points_mm: npt.ArrayLike, goal_rotations: npt.ArrayLike,
                initial: npt.ArrayLike, tolerance: tuple[float, float] = (1.0, 0.5),
                position_only: bool = False, max_iterations: int = 100, stop: float = 1e-3,
                restarts: int = 0, restart_after: int = 25, seed: int = 0,
                max_step: float = MAX_STEP, initial_damping: float = INITIAL_DAMPING) -> BatchIK:
    """Solve B single-pose IK problems in one batch (see the module docstring).

    Args:
        robot: the robot (its chain kinematics and limits).
        goal_points_mm: (B, 3) goal points [mm] in the base frame.
        goal_rotations: (B, 3, 3) goal rotations of the end frame (ignored when
            ``position_only``).
        initial: (B, dof) initial poses [pose units].
        tolerance: (position [mm], rotation [deg]) the residual is scaled by.
        position_only: solve the goal points only.
        max_iterations: LM iterations per target at most (restarts included).
        stop: a target is done when both errors are below ``stop`` x the tolerances.
        restarts: random restarts per target at most.
        restart_after: a target not done after this many iterations since its (re)start
            counts as stuck.
        seed: seed of the restarts' generator.
        max_step: largest joint step of one iteration [pose units].
        initial_damping: lambda at every (re)start.
    """
    frames = robot.chain_kinematics().frames
    lower = np.where(np.isfinite(robot.lower), robot.lower, -np.inf)
    upper = np.where(np.isfinite(robot.upper), robot.upper, np.inf)
    goal_mm = np.asarray(goal_points_mm, dtype=float)
    goal_R = np.asarray(goal_rotations, dtype=float)
    q = np.clip(np.array(initial, dtype=float), lower, upper)
    b, dof = q.shape
    scale = np.asarray(tolerance, dtype=float)
    rng = np.random.default_rng(seed)
    iterations, used = np.zeros(b, dtype=int), np.zeros(b, dtype=int)
    started = np.zeros(b, dtype=int)
    converged = np.zeros(b, dtype=bool)
    damping = np.full(b, float(initial_damping))
    r, J = _residuals(frames, q, goal_mm, goal_R, scale, position_only)
    cost = np.sum(r**2, axis=1)
    active = np.arange(b)
    eye = np.eye(dof)
    while len(active):
        done = np.all(np.linalg.norm(r[active].reshape(len(active), -1, 3), axis=2) < stop,
                      axis=1)
        converged[active[done]] = True
        slow = iterations[active] - started[active] >= restart_after
        stuck = ~done & ((damping[active] > STALLED) | slow)
        again = active[stuck & (used[active] < restarts)]
        if len(again):  # restart from a random pose
            used[again] += 1
            started[again] = iterations[again]
            q[again] = rng.uniform(robot.sample_lower, robot.sample_upper, (len(again), dof))
            damping[again] = initial_damping
            r[again], J[again] = _residuals(frames, q[again], goal_mm[again], goal_R[again],
                                            scale, position_only)
            cost[again] = np.sum(r[again] ** 2, axis=1)
        stuck = ~done & (damping[active] > STALLED)
        keep = ~done & ~stuck & (iterations[active] < max_iterations)
        active = active[keep]
        if not len(active):
            break
        Ja, ra = J[active], r[active]
        JtJ = Ja.swapaxes(-1, -2) @ Ja
        diag = np.einsum("kii->ki", JtJ)[:, :, None] * eye + 1e-9 * eye
        H = JtJ + damping[active, None, None] * diag
        rhs = Ja.swapaxes(-1, -2) @ ra[..., None]
        step = _scaled(-np.linalg.solve(H, rhs)[..., 0], max_step)
        qa = q[active]
        moved = into_limits(robot, qa + step, lower, upper)
        pinned = (((qa == lower) & (step < 0.0) & (moved == lower))
                  | ((qa == upper) & (step > 0.0) & (moved == upper)))
        again = pinned.any(1)
        if again.any():  # again without the joints the projection would clip back
            free = ~pinned[again]
            H_free = np.where(free[:, :, None] & free[:, None, :], H[again], eye)
            rhs_free = np.where(free[..., None], rhs[again], 0.0)
            step[again] = _scaled(-np.linalg.solve(H_free, rhs_free)[..., 0], max_step)
        trial = into_limits(robot, q[active] + step, lower, upper)
        r_new, J_new = _residuals(frames, trial, goal_mm[active], goal_R[active], scale,
                                  position_only)
        cost_new = np.sum(r_new**2, axis=1)
        better = cost_new < cost[active]
        idx = active[better]
        q[idx], r[idx], J[idx], cost[idx] = trial[better], r_new[better], J_new[better], \
            cost_new[better]
        damping[active] = np.where(better, np.maximum(damping[active] / 3.0, 1e-9),
                                   damping[active] * 4.0)
        iterations[active] += 1
    return BatchIK(q, iterations, converged, used)


def _scaled(step: np.ndarray, max_step: float) -> np.ndarray:
    """Steps (K, dof) scaled so that none moves a joint more than ``max_step``."""
    return step * np.minimum(1.0, max_step / np.maximum(np.abs(step).max(1), 1e-300))[:, None]
