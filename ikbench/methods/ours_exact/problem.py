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
  every joint step within s_j (pose units per segment) once cs is large;
- legibility (ikbench's extension, not the paper's; only with ``--exact-legibility-weight``
  W > 0 and a goal set): sum_i w_i (1 - P_i(G*))^2, w_i = W f_i / sum f, f_i = 1 - i/n, P_i
  the pointing observer's probability of the true goal (:mod:`ikbench.core.legibility`). It
  is added to the objective, not to ``terms``; the points stay constraints, so it moves only
  the pointing, never the fingertip off its path.

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
        legibility: (B, N) weights w_i of the legibility term, or None (no term).
        legibility_goals_mm: (B, K, 3) the goal sets (rows of NaN pad shorter sets).
        true_goal: (B,) the index of each trajectory's true goal.
        sigma_deg: the pointing observer's sigma [deg].
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
    legibility: np.ndarray | None = None
    legibility_goals_mm: np.ndarray | None = None
    true_goal: np.ndarray | None = None
    sigma_deg: float = 10.0

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
            self.constrained[index], self.lower, self.upper,
            None if self.legibility is None else self.legibility[index],
            None if self.legibility_goals_mm is None else self.legibility_goals_mm[index],
            None if self.true_goal is None else self.true_goal[index], self.sigma_deg)


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
    legible = None
    if problem.legibility is not None:
        legible = _legibility(problem, poses, at, derivatives)
    model = Model(terms.sum(axis=1) if legible is None else terms.sum(axis=1) + legible[0],
                  terms, residual)
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
    if legible is not None:
        model.gradient += legible[1]
        model.diagonal += legible[2]
    model.jacobian = jacobian
    return model


def pointing_p_true(problem: ExactProblem, points_mm: np.ndarray, direction: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pointing observer's P(G*) (B, N) at fingertip points (B, N, 3) [mm] and unit
    pointing axes (B, N, 3), with its derivatives by the axis and by the point (B, N, 3) each,
    and the logits' angles theta (B, N, K) [rad] (as :mod:`ikbench.core.legibility`)."""
    assert problem.legibility_goals_mm is not None and problem.true_goal is not None
    goals = problem.legibility_goals_mm[:, None]                       # (B, 1, K, 3)
    real = np.isfinite(goals[..., 0])                                   # (B, 1, K)
    to = np.where(real[..., None], goals - points_mm[:, :, None], 1.0)  # (B, N, K, 3)
    dist = np.linalg.norm(to, axis=-1)
    u = to / dist[..., None]
    v = direction[:, :, None]
    cos = np.sum(v * u, axis=-1)
    sin = np.linalg.norm(np.cross(v, u), axis=-1)
    theta = np.arctan2(sin, cos)
    near = dist < 1.0                                                   # NEAR_GOAL_MM
    theta = np.where(near, 0.0, theta)
    ratio = np.where(sin > 1e-12, theta / np.maximum(sin, 1e-12), 1.0)
    sigma = np.radians(problem.sigma_deg)
    z = np.where(real, -theta**2 / (2.0 * sigma**2), -np.inf)
    z = z - z.max(axis=-1, keepdims=True)
    prob = np.exp(z)
    prob /= prob.sum(axis=-1, keepdims=True)                            # (B, N, K)
    # d theta^2 / dv = -2 (theta / sin)(u - cos v); d theta^2 / dp = 2 (theta / sin)(v - cos u)
    # / |G - p|; d z / d . = -(d theta^2 / d .) / (2 sigma^2)
    keep = (~near & real)[..., None]
    dz_dv = np.where(keep, ratio[..., None] * (u - cos[..., None] * v) / sigma**2, 0.0)
    dz_dp = np.where(keep, -ratio[..., None] * (v - cos[..., None] * u)
                     / dist[..., None] / sigma**2, 0.0)
    b = np.arange(len(prob))[:, None]
    true = problem.true_goal[:, None]
    n_idx = np.arange(prob.shape[1])[None]
    p_true = prob[b, n_idx, true]                                       # (B, N)
    # dP*/d. = P* (dz*/d. - sum_G P_G dz_G/d.)
    dp_dv = p_true[..., None] * (dz_dv[b, n_idx, true]
                                 - np.sum(prob[..., None] * dz_dv, axis=2))
    dp_dp = p_true[..., None] * (dz_dp[b, n_idx, true]
                                 - np.sum(prob[..., None] * dz_dp, axis=2))
    return p_true, dp_dv, dp_dp, theta


def _legibility(problem: ExactProblem, poses: np.ndarray, at: KinematicsAt,
                derivatives: bool) -> tuple[np.ndarray, Any, Any]:
    """(value (B,), its half gradient J^T r (B, N, k), its J^T J blocks (B, N, k, k)) of the
    legibility term sum_i w_i (1 - P_i)^2 (residuals sqrt(w_i) (1 - P_i))."""
    assert problem.legibility is not None
    residual, jacobian, direction, j_dir = at
    points = problem.goal_points_mm + residual[..., :3]   # the fingertip (c = P(x) - P^g)
    p_true, dp_dv, dp_dp, _ = pointing_p_true(problem, points, direction)
    w = problem.legibility
    value = np.sum(w * (1.0 - p_true) ** 2, axis=1)
    if not derivatives:
        return value, None, None
    # dP/dq (B, N, k): through the axis and through the point (its Jacobian, mm per unit;
    # zero at the fixed poses, which never move)
    dp_dq = (dp_dv[..., None, :] @ j_dir)[..., 0, :] + (
        dp_dp[..., None, :] @ jacobian[..., :3, :])[..., 0, :]
    gradient = -(w * (1.0 - p_true))[..., None] * dp_dq
    blocks = w[..., None, None] * (dp_dq[..., :, None] * dp_dq[..., None, :])
    return value, gradient, blocks


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
