"""The equality-constrained trajectory problem of ``ours-exact``, for B trajectories at once.

Variables: the poses x (B, N, k) [pose units: motor deg for NICO], N = n + 1.

Constraints (hard, per pose i where ``constrained``):

- point:  P(x_i) - P^g_i = 0  [mm]  (3 rows);
- frame:  additionally log(R^g_i^T R(x_i)) = 0  [deg]  (3 more rows, 6-D pose paths);
- fixed poses (the start and touch poses) are held exactly: their variables never move;
- the joint limits are bounds (held by the active set of :mod:`.sqp`).

Objective (soft), in the paper's units and with its names:

- L6 smoothness: c6 * mean over segments and joints of (x_{i+1} - x_i)^2 [deg^2];
- L1 pointing: c1 * mean over the judged poses of (1 - v_i . d_i) (= |v_i - d_i|^2 / 2), the
  pointing axis v against the goal direction d, only where pointing is judged;
- jerk (optional): cj * mean of the third differences (x_{i+3} - 3 x_{i+2} + 3 x_{i+1} -
  x_i)^2 [deg^2];
- a speed bound: cs * sum of max(0, |x_{i+1, j} - x_{i, j}| - s_j)^2, a penalty that keeps
  every joint step within s_j (pose units per segment) once cs is large.

Every term is a sum of squared residuals, so :func:`evaluate` returns the Gauss-Newton model
(gradient J^T r, blocks of J^T J) whose coupling is banded, as :mod:`.kkt` needs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np

from ikbench.methods.ours_lm.frames import errors_from_frames

if TYPE_CHECKING:
    from ikbench.core.kinematics.chain import ChainKinematics

#: Trajectories picked from a batch: indices (or a mask) into its first axis.
Index: TypeAlias = "np.ndarray | Sequence[int] | slice | int"
#: :func:`kinematics_at`'s (c (B, N, m), A (B, N, m, k), directions (B, N, 3), their Jacobian
#: (B, N, 3, k)): the Jacobians are arrays, or None without derivatives.
KinematicsAt: TypeAlias = "tuple[np.ndarray, Any, np.ndarray, Any]"

MM_PER_M = 1000.0
#: The objective's terms, in the order of ``Model.terms``.
TERMS = ("pointing", "smoothness", "jerk", "step_excess")
#: The step penalty's curvature enters the model from this share below the step limit on: its
#: kink at the limit is then inside the model, and a step cannot jump across it unseen.
NEAR_LIMIT = 0.1
#: Coefficients of the third difference (jerk per step^3).
JERK_STENCIL = np.array([-1.0, 3.0, -3.0, 1.0])


@dataclass
class ExactProblem:
    """B trajectories of N poses of k joints (see the module docstring).

    Attributes:
        goal_points_mm: (B, N, 3).  goal_directions: (B, N, 3) unit.
        goal_rotations: (B, N, 3, 3) for 6-D pose paths, else None.
        pointing: (B, N) squared residual scale of the pointing residual v_i - d_i.
        smooth: (B,) squared residual scale of the joint steps (c6 / (n k)).
        jerk: (B,) squared residual scale of the third differences.
        step_limit: (B, k) largest joint step per segment before the penalty [pose units].
        step_penalty: (B,) squared residual scale of the step excess.
        fixed: (B, N) poses held at their initial values.
        constrained: (B, N) poses whose point (and frame) are equality constraints.
        lower / upper: (k,) joint bounds [pose units].
    """

    goal_points_mm: np.ndarray
    goal_directions: np.ndarray
    goal_rotations: np.ndarray | None
    pointing: np.ndarray
    smooth: np.ndarray
    jerk: np.ndarray
    step_limit: np.ndarray
    step_penalty: np.ndarray
    fixed: np.ndarray
    constrained: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @property
    def rows(self) -> int:
        """Constraint rows per pose: 3 (point) or 6 (point and frame)."""
        return 3 if self.goal_rotations is None else 6

    def take(self, index: Index) -> ExactProblem:
        """The sub-problem of trajectories ``index``."""
        rotations = None if self.goal_rotations is None else self.goal_rotations[index]
        return ExactProblem(
            self.goal_points_mm[index], self.goal_directions[index], rotations,
            self.pointing[index], self.smooth[index], self.jerk[index],
            self.step_limit[index], self.step_penalty[index], self.fixed[index],
            self.constrained[index], self.lower, self.upper)


@dataclass
class Model:
    """Objective, constraints and their Gauss-Newton model at poses (B, N, k).

    ``objective`` (B,); ``terms`` (B, 4) the summands of :data:`TERMS` (weighted);
    ``residual`` (B, N, m) the constraints c [mm, deg] (0 where not constrained);
    ``gradient`` (B, N, k) J^T r (half the objective's gradient); ``diagonal``
    (B, N, k, k) and ``bands`` {d: (B, N - d, k)} the blocks of J^T J; ``jacobian``
    (B, N, m, k) the constraints' Jacobian A.
    """

    objective: np.ndarray
    terms: np.ndarray
    residual: np.ndarray
    gradient: Any = None        # np.ndarray when derivatives were asked for
    diagonal: Any = None
    bands: dict = field(default_factory=dict)
    jacobian: Any = None

    def take(self, index: Index) -> Model:
        """The model of trajectories ``index``."""
        def pick(v):
            return None if v is None else v[index]

        return Model(self.objective[index], self.terms[index], self.residual[index],
                     pick(self.gradient), pick(self.diagonal),
                     {d: v[index] for d, v in self.bands.items()}, pick(self.jacobian))

    def put(self, index: Index, other: Model) -> None:
        """Overwrite trajectories ``index`` with ``other``."""
        for name in ("objective", "terms", "residual", "gradient", "diagonal", "jacobian"):
            getattr(self, name)[index] = getattr(other, name)
        for d, values in other.bands.items():
            self.bands[d][index] = values

    def hessian_times(self, step: np.ndarray) -> np.ndarray:
        """(J^T J) step for step (B, N, k)."""
        out = (self.diagonal @ step[..., None])[..., 0]
        for d, values in self.bands.items():
            out[:, :-d] += values * step[:, d:]
            out[:, d:] += values * step[:, :-d]
        return out

    def violation(self) -> np.ndarray:
        """(B,) the largest constraint violation [mm or deg]."""
        return np.max(np.abs(self.residual), axis=(1, 2), initial=0.0)


def evaluate(kinematics: ChainKinematics, problem: ExactProblem, poses: np.ndarray,
             derivatives: bool = True, at: KinematicsAt | None = None) -> Model:
    """The :class:`Model` of ``problem`` at ``poses`` (B, N, k); ``at``: the poses'
    :func:`kinematics_at` when already computed."""
    b, n_poses, k = poses.shape
    if at is None:
        at = kinematics_at(kinematics, problem, poses, derivatives)
    residual, jacobian, direction, j_dir = at
    e_dir = direction - problem.goal_directions
    steps = np.diff(poses, axis=1)
    excess = np.maximum(np.abs(steps) - problem.step_limit[:, None, :], 0.0)
    third = _third_differences(poses)
    terms = np.stack([
        np.sum(problem.pointing * np.sum(e_dir**2, axis=-1), axis=1),
        problem.smooth * np.sum(steps**2, axis=(1, 2)),
        problem.jerk * np.sum(third**2, axis=(1, 2)),
        problem.step_penalty * np.sum(excess**2, axis=(1, 2)),
    ], axis=1)
    model = Model(terms.sum(axis=1), terms, residual)
    if not derivatives:
        return model
    a1 = problem.pointing[..., None, None]
    j_dir_t = j_dir.swapaxes(-1, -2)
    model.diagonal = a1 * (j_dir_t @ j_dir)
    model.gradient = problem.pointing[..., None] * (j_dir_t @ e_dir[..., None])[..., 0]
    near = np.abs(steps) > (1.0 - NEAR_LIMIT) * problem.step_limit[:, None, :]
    segment = (problem.smooth[:, None, None]
               + problem.step_penalty[:, None, None] * near)               # (B, N - 1, k)
    slope = problem.smooth[:, None, None] * steps + (
        problem.step_penalty[:, None, None] * excess * np.sign(steps))
    model.gradient[:, :-1] -= slope
    model.gradient[:, 1:] += slope
    along = np.zeros((b, n_poses, k))
    along[:, :-1] += segment
    along[:, 1:] += segment
    model.bands = {1: -segment}
    if np.any(problem.jerk > 0):
        _add_jerk(model, problem.jerk, third, along)
    idx = np.arange(k)
    model.diagonal[..., idx, idx] += along
    model.jacobian = jacobian
    return model


def kinematics_at(kinematics: ChainKinematics, problem: ExactProblem, poses: np.ndarray,
                  derivatives: bool = True) -> KinematicsAt:
    """Constraints c (B, N, m) [mm, deg], their Jacobian A (B, N, m, k), the pointing
    directions (B, N, 3) and their Jacobian (B, N, 3, k) at poses (B, N, k) (Jacobians None
    without ``derivatives``); c and A are zero where a pose is not constrained."""
    b, n_poses, k = poses.shape
    shape = (b, n_poses)
    point_m, rotation, j_point, j_angular = kinematics.frames(poses.reshape(-1, k), derivatives)
    point_m, rotation = point_m.reshape(*shape, 3), rotation.reshape(*shape, 3, 3)
    if derivatives:
        assert j_point is not None and j_angular is not None  # asked for
        j_point, j_angular = j_point.reshape(*shape, 3, k), j_angular.reshape(*shape, 3, k)
    direction = rotation @ kinematics.robot.pointing_axis
    if problem.goal_rotations is None:
        residual = point_m * MM_PER_M - problem.goal_points_mm
        jacobian = None if j_point is None else j_point * MM_PER_M
    else:
        e_point, e_rot, jp, jr = errors_from_frames(point_m, rotation, j_point, j_angular,
                                                    problem.goal_points_mm,
                                                    problem.goal_rotations)
        residual = np.concatenate([e_point, e_rot], axis=-1)
        jacobian = None if jp is None else np.concatenate([jp, jr], axis=-2)
    mask = problem.constrained[..., None]
    residual = residual * mask
    j_dir = None
    if derivatives:
        jacobian = jacobian * mask[..., None]
        assert j_angular is not None  # asked for
        j_dir = np.cross(j_angular, direction[..., None, :], axisa=-2, axisb=-1, axisc=-2)
    return residual, jacobian, direction, j_dir


def _third_differences(poses):
    """(B, N - 3, k) x_{i+3} - 3 x_{i+2} + 3 x_{i+1} - x_i (empty when N < 4)."""
    return np.diff(poses, n=3, axis=1)


def _add_jerk(model: Model, weight, third, along) -> None:
    """Add the jerk term's gradient, diagonal (into ``along``) and bands 1..3."""
    w = weight[:, None, None]
    count = third.shape[1]
    for p, cp in enumerate(JERK_STENCIL):
        model.gradient[:, p:p + count] += w * cp * third
        along[:, p:p + count] += w * cp * cp
        for q in range(p + 1, len(JERK_STENCIL)):
            d = q - p
            value = w * cp * JERK_STENCIL[q]
            band = model.bands.setdefault(d, np.zeros((third.shape[0], along.shape[1] - d,
                                                       along.shape[2])))
            band[:, p:p + count] += value
