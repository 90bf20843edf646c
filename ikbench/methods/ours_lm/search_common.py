"""What the two implementations of ours-lm's start search share: the numpy reference
(:mod:`.start_search`) and the compiled one (:mod:`.path_search`): the settings, the search's
constants and result, the seeding IK of a waypoint, the stitch's costs and the removal of
duplicate solutions.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.validity import (
    MAX_JOINT_CHANGE_DEG,
    MAX_JOINT_CHANGE_MM,
)
from ikbench.methods.options import check_positive, check_seed, option
from ikbench.methods.ours_lm.frames import errors_from_frames
from ikbench.methods.ours_lm.solver import LMSettings

if TYPE_CHECKING:
    from ikbench.core.kinematics.chain import Frames
    from ikbench.core.robot import Robot

#: Carrying: iterations per waypoint at most, and the error [mm or deg] before a step above
#: which another one follows.
CARRY_ITERATIONS = 3
CARRY_RETRY = 1.0
#: A candidate whose error before a waypoint's first step exceeds this [mm or deg] is not
#: carried further.
DROP_MM_DEG = 50.0
#: The refinement stops once a candidate's position and rotation errors are below this
#: fraction of CppFlow's thresholds (and its other criteria hold): a valid result with room
#: to spare, e.g. for an evaluation in float32.
SEARCH_MARGIN = 0.9
#: Damping of the carrying steps [mm] (damped least squares, J^T (J J^T + d^2 I)^-1 e).
CARRY_DAMPING = 1e-2
#: Gain of the joint-limit avoidance in the null space while carrying (per waypoint).
AVOIDANCE_GAIN = 0.005
#: The cost of a step above it, per pose unit above it: the path jumps only where no carried
#: path continues, as little as it can (the LM refinement may then smooth the jump).
STITCH_JUMP_COST = 1e6
#: A carried pose further than this [mm or deg] from its goal is not a node of the stitch.
STITCH_REACHED = 1.0
#: First-waypoint IK: iterations, and the tolerance on the errors [mm, deg].
IK_ITERATIONS = 100
IK_TOLERANCE = 1e-6
#: A seed whose damping grew above this made no progress for many iterations (stuck).
IK_STALLED = 1e6
#: Largest joint step [pose units] of one first-waypoint IK iteration.
IK_MAX_STEP = 20.0
#: Seeds closer than this [pose units, max over joints] after IK count as one.
DUPLICATE_DEG = 1.0
STITCH_MAX_STEP = 6.5
STITCH_STEP_SHARE = STITCH_MAX_STEP / MAX_JOINT_CHANGE_DEG


def lm_seed_option() -> Any:
    """The settings field ``seed`` as ``--lm-seed``: ours-lm's and, for the start search of
    its initial trajectory, ours-exact's."""
    return option(0, flag="lm-seed",
                  help="6-D pose paths: seed of the start search's random IK seeds, in [0, 2^63)")


@dataclass
class OursLMSettings(LMSettings):
    """:class:`LMSettings` plus the start search of 6-D pose paths.

    Attributes:
        seed: seed of the random IK seeds, in [0, 2^63).
        ik_seeds: IK seeds for the first waypoint (the home pose and random ones).
        refine: carried candidates refined by LM at once.
    """

    seed: int = lm_seed_option()
    ik_seeds: int = option(16, flag="lm-ik-seeds",
                           help="6-D pose paths: IK seeds for the first waypoint (the home "
                           "pose and random ones)")
    refine: int = option(2, flag="lm-refine",
                         help="6-D pose paths: carried candidates refined by LM together")
    clearance_mm: float = option(0.5, flag="lm-clearance-mm", unit="mm",
                                 help="pose paths with obstacles: the clearance the collision "
                                 "penalty asks for (validity needs >= 0)")
    collision_weight: float = option(10.0, flag="lm-collision-weight",
                                     help="pose paths with obstacles: weight of the collision "
                                     "penalty (per mm^2 of missing clearance, per waypoint)")

    def __post_init__(self):
        super().__post_init__()
        check_seed(self)
        check_positive(self, "ik_seeds", "refine", integer=True)
        check_positive(self, "clearance_mm", "collision_weight")
        self.ik_seeds, self.refine = int(self.ik_seeds), int(self.refine)


@dataclass
class SearchResult:
    """The start search's outcome for one task (poses in pose units)."""

    poses: np.ndarray          # (N, dof)
    loss: float
    terms: np.ndarray              # (7,) L0..L6 of the 6-D objective
    valid: bool
    iterations: int                # IK + carrying + LM iterations
    converged: bool                # the LM stopping rule was met
    info: dict


def first_waypoint_ik(frames: Callable[..., Frames], goal_mm: np.ndarray, goal_R: np.ndarray,
                      seeds: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                      max_iterations: int = IK_ITERATIONS
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Damped least-squares IK of one pose (``goal_mm`` (3,), ``goal_R`` (3, 3), or one per
    seed, (K, 3) and (K, 3, 3)) from every seed (K, dof), with an adaptive damping; a seed
    stops once converged or stuck (the others go on).

    Returns:
        (poses (K, dof), position errors (K,) [mm], rotation errors (K,) [deg], iterations).
    """
    q = np.clip(seeds, lower, upper)
    goal_mm, goal_R = np.asarray(goal_mm, dtype=float), np.asarray(goal_R, dtype=float)
    per_seed = goal_mm.ndim == 2

    def errors(poses, rows):
        return _stack(*errors_from_frames(*frames(poses), goal_mm[rows] if per_seed else goal_mm,
                                          goal_R[rows] if per_seed else goal_R))

    e, J = errors(q, slice(None))
    damping = np.full(len(q), 1.0)
    iterations = 0
    while iterations < max_iterations:
        norm = np.linalg.norm(e, axis=1)
        active = np.flatnonzero((norm >= IK_TOLERANCE) & (damping <= IK_STALLED))
        if not active.size:                                   # every seed converged or stuck
            break
        iterations += 1
        step = _dls(e[active], J[active], damping[active])
        step *= np.minimum(1.0, IK_MAX_STEP / np.maximum(np.abs(step).max(1), 1e-300))[:, None]
        trial = np.clip(q[active] + step, lower, upper)
        e_new, J_new = errors(trial, active)
        better = np.linalg.norm(e_new, axis=1) < norm[active]
        rows = active[better]
        q[rows], e[rows], J[rows] = trial[better], e_new[better], J_new[better]
        damping[active] = np.where(better, np.maximum(damping[active] / 3.0, 1e-6),
                                   damping[active] * 4.0)
    return q, np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:], axis=1), iterations


def distinct(poses: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Indices of ``poses`` (K, dof) where ``keep``, dropping near-duplicates (first kept)."""
    chosen: list[int] = []
    for k in np.flatnonzero(keep):
        if all(np.abs(poses[k] - poses[c]).max() > DUPLICATE_DEG for c in chosen):
            chosen.append(int(k))
    return np.array(chosen, dtype=int)


def stitch_costs(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """(weights (dof,), largest step (dof,) [pose units]) of the stitch: a revolute joint's
    step counts by its size [deg], a prismatic joint's [mm] by 7/20 of it (CppFlow's step
    limits' ratio), and a step above :data:`STITCH_MAX_STEP` (prismatic:
    :data:`STITCH_STEP_SHARE` of 20 mm) is a jump."""
    prismatic = robot.chain_kinematics().prismatic
    weights = np.where(prismatic, MAX_JOINT_CHANGE_DEG / MAX_JOINT_CHANGE_MM, 1.0)
    max_step = np.where(prismatic, STITCH_STEP_SHARE * MAX_JOINT_CHANGE_MM, STITCH_MAX_STEP)
    return weights, max_step


def _stack(e_point, e_rot, j_point, j_rot):
    """(e (K, 6), J (K, 6, dof)) from position and rotation errors [mm, deg]."""
    return np.concatenate([e_point, e_rot], -1), np.concatenate([j_point, j_rot], -2)


def _dls(e, J, damping):
    """Minimum-norm damped least-squares steps (K, dof): -J^T (J J^T + d^2 I)^-1 e."""
    d2 = np.asarray(damping, dtype=float).reshape(-1, 1, 1) ** 2
    JJt = J @ J.swapaxes(-1, -2) + d2 * np.eye(J.shape[-2])
    return -(J.swapaxes(-1, -2) @ np.linalg.solve(JJt, e[..., None]))[..., 0]
