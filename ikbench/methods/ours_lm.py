"""Fast second-order solver ("ours-lm"): the paper's objective by Levenberg-Marquardt.

Minimises exactly the loss of ``ours`` (:mod:`ikbench.losses`, cm and motor degrees, weights
c0..c6) over the poses p (n+1, dof) [motor deg] within the motor ranges, written as a sum of
squared residuals ``L = |r|^2`` (N = n+1 poses, P in cm, v unit directions, d goal directions):

- L0: sqrt(c0 / (3N)) (P_i - P^g_i)             - L1: sqrt(c1 / (2N)) (v_i - d_i)
- L2: sqrt(c2) (p_0 - p^s)                      - L3: sqrt(c3) (p_n - p^e)
- L4: sqrt(c4) (P_0 - P^g_0)                    - L5: sqrt(c5) (P_n - P^g_n)
- L6: sqrt(c6 / (n dof)) (p_{i+1} - p_i)

(for unit vectors 1 - v.d = |v - d|^2 / 2, so the L1 residual is exact). Jacobians are
analytic: for a revolute joint with world axis w through o, dP/dq = w x (P - o) and
dv/dq = w x v, times dq/dp = scale * pi / 180 (motor -> joint map) and 100 (m -> cm).

Only L6 couples neighbouring poses, with a multiple of the identity, so the Gauss-Newton
matrix J^T J is block-tridiagonal (dof x dof blocks): a band matrix of half-bandwidth dof,
solved by banded Cholesky (LAPACK ``pbsv`` via scipy; a numpy block-Thomas solver otherwise).
Joint limits are box constraints: projected LM with an active set (a variable at a bound whose
gradient points outwards is held), steps clipped to the box, Marquardt damping diag(J^T J)
with Nielsen's update. Initial poses: the joint interpolation from start to touch pose, or,
for a task that pins neither (a letter, polyline or spline), every pose at the task's reference
pose. Many trajectories are solved at once, vectorised over trajectories and poses.

Weights: as in ``ours``, a task may name the weights it is meant for
(``Task.default_weights``, e.g. a letter's c0=1, c1=50, c6=1, others 0); ``--weights`` changes
then apply on top of those instead of the paper's, per task in one batch.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from ikbench.errors import InputError, SolverError
from ikbench.losses import MM_PER_CM, PAPER_WEIGHTS, TERMS, parse_weights
from ikbench.methods import Method, Solution, register
from ikbench.robot import DEG2RAD

KINEMATICS = ("numpy", "pinocchio")
LINEAR_SOLVERS = ("banded", "thomas")
CM_PER_M = 100.0
#: A variable within this distance [motor deg] of a bound counts as on the bound.
BOUND_EPS_DEG = 1e-9
#: Steps whose gain ratio (actual / predicted reduction) is below this are rejected.
MIN_GAIN_RATIO = 1e-4
#: Give up on a trajectory when the damping exceeds this (no descent step exists).
MAX_DAMPING = 1e12


@dataclass
class LMSettings:
    """Settings of the Levenberg-Marquardt solver.

    Attributes:
        weights: loss weights keyed L0..L6 (default the paper's).
        max_iterations: iteration cap per trajectory.
        tolerance: stop when an accepted step lowers the loss by less than
            ``tolerance * loss`` (relative), or moves no pose by more than ``tolerance`` deg.
        damping: initial Marquardt damping factor lambda (times diag(J^T J)).
        kinematics: ``"numpy"`` (vectorised chain FK from the Pinocchio model) or
            ``"pinocchio"`` (``computeFrameJacobian`` per pose; the reference, slower).
        linear_solver: ``"banded"`` (LAPACK banded Cholesky) or ``"thomas"`` (numpy).
    """

    weights: dict = field(default_factory=lambda: dict(PAPER_WEIGHTS))
    max_iterations: int = 200
    tolerance: float = 1e-9
    damping: float = 1e-3
    kinematics: str = "numpy"
    linear_solver: str = "banded"


# ----- kinematics ----------------------------------------------------------------------------
class ChainKinematics:
    """Vectorised FK and analytic Jacobians of a serial revolute chain, in the loss units.

    Built from the robot's Pinocchio model (joint placements, axes, end frame). Call with
    poses (M, dof) [motor deg]; returns point [cm] (M, 3), direction (M, 3) and their
    Jacobians d/d(motor deg) (M, 3, dof).
    """

    def __init__(self, robot):
        import pinocchio as pin

        model = robot.pinocchio_fk().model
        self.dof = robot.dof
        self.rotations, self.translations, self.axes = [], [], []
        for j in range(1, model.njoints):
            if model.parents[j] != j - 1:
                raise SolverError(f"ours-lm needs a serial chain; joint {model.names[j]} "
                                  f"hangs off joint {model.names[model.parents[j]]}")
            self.axes.append(_revolute_axis(model.joints[j], model.names[j]))
            self.rotations.append(np.array(model.jointPlacements[j].rotation))
            self.translations.append(np.array(model.jointPlacements[j].translation))
        frame = model.frames[robot.pinocchio_fk().frame_id]
        if frame.parentJoint != model.njoints - 1:
            raise SolverError(f"end frame {robot.end_frame} is not on the last joint")
        self.tip_rotation = np.array(frame.placement.rotation)
        self.tip_translation = np.array(frame.placement.translation)
        # dq [rad] / dp [motor deg]
        self.rad_per_motor_deg = robot.scale * DEG2RAD
        self.robot = robot
        self._pin = pin

    def __call__(self, poses_deg, jacobian: bool = True):
        """FK (and Jacobians) of poses (M, dof) [motor deg].

        Returns:
            (point_cm (M, 3), direction (M, 3), J_point (M, 3, dof) [cm / motor deg] or None,
            J_direction (M, 3, dof) [1 / motor deg] or None).
        """
        q = self.robot.motor_to_joint_rad(np.asarray(poses_deg, dtype=float))
        m = len(q)
        rot = np.broadcast_to(np.eye(3), (m, 3, 3))
        pos = np.zeros((m, 3))
        axes_world, origins = [], []
        for j in range(self.dof):
            pos = pos + rot @ self.translations[j]
            rot = rot @ self.rotations[j]
            axis = self.axes[j]
            rot = rot @ _axis_rotation(axis, q[:, j])
            axes_world.append(rot @ axis)
            origins.append(pos)
        point = (pos + rot @ self.tip_translation) * CM_PER_M
        direction = rot @ self.tip_rotation[:, 2]
        if not jacobian:
            return point, direction, None, None
        w = np.stack(axes_world, axis=1)                        # (M, dof, 3)
        o = np.stack(origins, axis=1) * CM_PER_M                # (M, dof, 3)
        scale = self.rad_per_motor_deg[None, :, None]
        j_point = np.cross(w, point[:, None, :] - o) * scale    # (M, dof, 3)
        j_dir = np.cross(w, direction[:, None, :]) * scale
        return point, direction, j_point.transpose(0, 2, 1), j_dir.transpose(0, 2, 1)


def _revolute_axis(joint, name: str) -> np.ndarray:
    short = joint.shortname()
    fixed = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0),
             "JointModelRZ": (0.0, 0.0, 1.0)}
    if short in fixed:
        return np.array(fixed[short])
    if short == "JointModelRevoluteUnaligned":
        axis = np.array(joint.extract().axis, dtype=float)
        return axis / np.linalg.norm(axis)
    raise SolverError(f"ours-lm handles revolute joints only; {name} is {short}")


def _axis_rotation(axis: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """Rotations (M, 3, 3) about a unit axis by angles (M,) (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                  [-axis[1], axis[0], 0.0]])
    s, c = np.sin(angle_rad)[:, None, None], np.cos(angle_rad)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def pinocchio_kinematics(robot, poses_deg, jacobian: bool = True):
    """The reference of :class:`ChainKinematics`: Pinocchio per pose (LOCAL_WORLD_ALIGNED)."""
    import pinocchio as pin

    pfk = robot.pinocchio_fk()
    model, data, fid = pfk.model, pfk.data, pfk.frame_id
    q_rad = robot.motor_to_joint_rad(np.atleast_2d(np.asarray(poses_deg, dtype=float)))
    m, dof = q_rad.shape
    point, direction = np.empty((m, 3)), np.empty((m, 3))
    j_point, j_dir = np.empty((m, 3, dof)), np.empty((m, 3, dof))
    scale = robot.scale * DEG2RAD
    for i, q in enumerate(q_rad):
        jac = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        placement = data.oMf[fid]
        point[i] = placement.translation * CM_PER_M
        direction[i] = placement.rotation[:, 2]
        j_point[i] = jac[:3] * CM_PER_M * scale
        j_dir[i] = np.cross(jac[3:].T, direction[i]).T * scale
    if not jacobian:
        return point, direction, None, None
    return point, direction, j_point, j_dir


# ----- the least-squares problem -------------------------------------------------------------
@dataclass
class Problem:
    """B trajectories of N poses in the loss units, with per-trajectory weights.

    Attributes:
        goal_points_cm: (B, N, 3).  goal_directions: (B, N, 3).
        start_pose_deg / end_pose_deg: (B, dof) (zeros where a task fixes none).
        weights: (B, 7) c0..c6 per trajectory (c2/c3 set to 0 where a pose is not fixed).
        lower_deg / upper_deg: (dof,) motor ranges.
    """

    goal_points_cm: np.ndarray
    goal_directions: np.ndarray
    start_pose_deg: np.ndarray
    end_pose_deg: np.ndarray
    weights: np.ndarray
    lower_deg: np.ndarray
    upper_deg: np.ndarray

    @classmethod
    def from_tasks(cls, robot, tasks, weights) -> Problem:
        """Stack tasks of equal length; ``weights`` is one dict or one dict per task."""
        sizes = {t.steps for t in tasks}
        if len(sizes) != 1:
            raise InputError(f"ours-lm batches tasks of one length; got n = {sorted(sizes)}")
        per_task = weights if isinstance(weights, (list, tuple)) else [weights] * len(tasks)
        w = np.array([[float(ws.get(k, 0.0)) for k in TERMS] for ws in per_task])
        zero = np.zeros(robot.dof)
        start = np.stack([zero if t.start_pose_deg is None else t.start_pose_deg for t in tasks])
        end = np.stack([zero if t.end_pose_deg is None else t.end_pose_deg for t in tasks])
        w[:, 2] *= [t.start_pose_deg is not None for t in tasks]
        w[:, 3] *= [t.end_pose_deg is not None for t in tasks]
        return cls(np.stack([t.goal_points_mm for t in tasks]) / MM_PER_CM,
                   np.stack([t.goal_directions for t in tasks]), start, end, w,
                   robot.lower_motor_deg, robot.upper_motor_deg)

    def take(self, index) -> Problem:
        """The sub-problem of trajectories ``index``."""
        return Problem(self.goal_points_cm[index], self.goal_directions[index],
                       self.start_pose_deg[index], self.end_pose_deg[index],
                       self.weights[index], self.lower_deg, self.upper_deg)

    def residual_weights(self):
        """Squared residual scales (B,) each: a0^2 .. a6^2 (see the module docstring)."""
        n_poses = self.goal_points_cm.shape[1]
        dof = len(self.lower_deg)
        c = self.weights.T
        return (c[0] / (3 * n_poses), c[1] / (2 * n_poses), c[2], c[3], c[4], c[5],
                c[6] / ((n_poses - 1) * dof))


@dataclass
class Evaluation:
    """Loss, gradient and Gauss-Newton blocks of B trajectories at poses (B, N, dof).

    ``loss`` (B,) equals :func:`ikbench.losses.objective`; ``terms`` (B, 7) the L_k;
    ``gradient`` (B, N, dof) = J^T r (half the loss gradient); ``diagonal`` (B, N, dof, dof)
    and ``coupling`` (B,) the blocks of J^T J (off-diagonal blocks = -coupling * I).
    """

    loss: np.ndarray
    terms: np.ndarray
    gradient: np.ndarray | None = None
    diagonal: np.ndarray | None = None
    coupling: np.ndarray | None = None


def evaluate(kinematics, problem: Problem, poses, derivatives: bool = True) -> Evaluation:
    """Residuals of ``problem`` at ``poses`` (B, N, dof) [motor deg]; see :class:`Evaluation`."""
    b, n_poses, dof = poses.shape
    point, direction, j_point, j_dir = kinematics(poses.reshape(-1, dof), derivatives)
    point = point.reshape(b, n_poses, 3)
    direction = direction.reshape(b, n_poses, 3)
    e_point = point - problem.goal_points_cm
    e_dir = direction - problem.goal_directions
    e_start = poses[:, 0] - problem.start_pose_deg
    e_end = poses[:, -1] - problem.end_pose_deg
    steps = np.diff(poses, axis=1)
    terms = np.stack([
        np.mean(e_point**2, axis=(1, 2)),
        np.mean(1.0 - np.sum(direction * problem.goal_directions, axis=-1), axis=1),
        np.sum(e_start**2, axis=1), np.sum(e_end**2, axis=1),
        np.sum(e_point[:, 0] ** 2, axis=1), np.sum(e_point[:, -1] ** 2, axis=1),
        np.mean(steps**2, axis=(1, 2)),
    ], axis=1)
    loss = np.sum(terms * problem.weights, axis=1)
    if not derivatives:
        return Evaluation(loss, terms)
    a0, a1, a2, a3, a4, a5, a6 = problem.residual_weights()
    w_point = np.repeat(a0[:, None], n_poses, axis=1)
    w_point[:, 0] += a4
    w_point[:, -1] += a5
    j_point = j_point.reshape(b, n_poses, 3, dof)
    j_dir = j_dir.reshape(b, n_poses, 3, dof)
    j_point_t, j_dir_t = j_point.swapaxes(-1, -2), j_dir.swapaxes(-1, -2)
    diagonal = (w_point[..., None, None] * (j_point_t @ j_point)
                + a1[:, None, None, None] * (j_dir_t @ j_dir))
    gradient = (w_point[..., None] * (j_point_t @ e_point[..., None])[..., 0]
                + a1[:, None, None] * (j_dir_t @ e_dir[..., None])[..., 0])
    gradient[:, 0] += a2[:, None] * e_start
    gradient[:, -1] += a3[:, None] * e_end
    gradient[:, :-1] -= a6[:, None, None] * steps
    gradient[:, 1:] += a6[:, None, None] * steps
    degree = np.full(n_poses, 2.0)
    degree[[0, -1]] = 1.0
    idx = np.arange(dof)
    diagonal[:, :, idx, idx] += a6[:, None, None] * degree[None, :, None]
    diagonal[:, 0, idx, idx] += a2[:, None]
    diagonal[:, -1, idx, idx] += a3[:, None]
    return Evaluation(loss, terms, gradient, diagonal, a6)


# ----- block-tridiagonal linear algebra ------------------------------------------------------
def solve_normal_equations(diagonal, coupling, rhs, free, solver: str = "banded"):
    """Solve the block-tridiagonal system for the free variables.

    The matrix has diagonal blocks ``diagonal`` (B, N, k, k) and off-diagonal blocks
    ``-coupling (B,) * I``; rows and columns of variables with ``free`` (B, N, k) False are
    replaced by the identity (their step is 0).

    Returns:
        (steps (B, N, k), ok (B,) bool: False where the matrix was not positive definite).
    """
    b, n_poses, k = rhs.shape
    f = free.astype(float)
    diag = diagonal * f[..., :, None] * f[..., None, :]
    idx = np.arange(k)
    diag[..., idx, idx] += 1.0 - f
    off = coupling[:, None, None] * f[:, :-1] * f[:, 1:]          # (B, N-1, k), sign: -off
    rhs = rhs * f
    if solver == "banded":
        try:
            return _solve_banded(diag, off, rhs)
        except ImportError:
            pass
    return _solve_thomas(diag, off, rhs)


def _solve_banded(diag, off, rhs):
    from scipy.linalg.lapack import dpbsv

    b, n_poses, k = rhs.shape
    band = np.zeros((b, n_poses, k, k + 1))                      # [.., a, d] = A[ia+d, ia]
    for d in range(k):
        band[:, :, : k - d, d] = np.diagonal(diag, offset=-d, axis1=2, axis2=3)
    band[:, :-1, :, k] = -off
    band = band.reshape(b, n_poses * k, k + 1)
    out = np.empty((b, n_poses * k))
    ok = np.ones(b, dtype=bool)
    flat = rhs.reshape(b, -1)
    for t in range(b):
        _, x, info = dpbsv(band[t].T, flat[t], lower=1)
        ok[t] = info == 0
        out[t] = x if info == 0 else 0.0
    return out.reshape(b, n_poses, k), ok


def _solve_thomas(diag, off, rhs):
    """Block Thomas elimination, vectorised over the batch (numpy only)."""
    b, n_poses, k = rhs.shape
    inverses = np.empty_like(diag)
    y = np.empty_like(rhs)
    ok = np.ones(b, dtype=bool)
    schur, y_prev = diag[:, 0], rhs[:, 0]
    for i in range(n_poses):
        if i:
            c = off[:, i - 1]                                    # C = -diag(c)
            schur = diag[:, i] - c[:, :, None] * inverses[:, i - 1] * c[:, None, :]
            y_prev = rhs[:, i] + c * (inverses[:, i - 1] @ y[:, i - 1, :, None])[..., 0]
        ok &= np.all(np.linalg.eigvalsh(schur) > 0, axis=-1)
        inverses[:, i] = np.linalg.inv(np.where(ok[:, None, None], schur, np.eye(k)))
        y[:, i] = y_prev
    x = np.empty_like(rhs)
    x[:, -1] = (inverses[:, -1] @ y[:, -1, :, None])[..., 0]
    for i in range(n_poses - 2, -1, -1):
        x[:, i] = (inverses[:, i] @ (y[:, i] + off[:, i] * x[:, i + 1])[..., None])[..., 0]
    x[~ok] = 0.0
    return x, ok


def block_matvec(evaluation: Evaluation, x):
    """(J^T J) x for x (B, N, dof)."""
    out = (evaluation.diagonal @ x[..., None])[..., 0]
    c = evaluation.coupling[:, None, None]
    out[:, 1:] -= c * x[:, :-1]
    out[:, :-1] -= c * x[:, 1:]
    return out


# ----- Levenberg-Marquardt -------------------------------------------------------------------
@dataclass
class BatchResult:
    """Result of :func:`solve_batch`: arrays over the B trajectories."""

    poses_deg: np.ndarray        # (B, N, dof)
    loss: np.ndarray             # (B,)
    terms: np.ndarray            # (B, 7) L0..L6
    iterations: np.ndarray       # (B,) LM iterations (accepted + rejected steps)
    converged: np.ndarray        # (B,) bool: the tolerance was met before the cap
    duration_s: float            # wall time of the whole batch [s]


def initial_poses(robot, tasks) -> np.ndarray:
    """Initial poses (B, N, dof) [motor deg], clipped to the motor ranges.

    The joint interpolation from start to touch pose; a task that pins neither (a letter,
    polyline or spline) starts with every pose at its reference pose.

    Raises:
        InputError: a task has neither a start and an end pose nor a reference pose.
    """
    out = []
    for task in tasks:
        t = np.linspace(0.0, 1.0, task.steps + 1)[:, None]
        if task.start_pose_deg is not None and task.end_pose_deg is not None:
            out.append(task.start_pose_deg + t * (task.end_pose_deg - task.start_pose_deg))
        elif task.reference_pose_deg is not None:
            out.append(np.asarray(task.reference_pose_deg, dtype=float) + 0.0 * t)
        else:
            raise InputError(f"trajectory {task.name!r}: ours-lm needs a start and an end pose "
                             "or a reference pose to start from")
    return np.clip(np.stack(out), robot.lower_motor_deg, robot.upper_motor_deg)


def _free_variables(problem: Problem, poses, gradient):
    """False for variables on a bound whose descent direction (-gradient) leaves the box."""
    at_lower = poses <= problem.lower_deg + BOUND_EPS_DEG
    at_upper = poses >= problem.upper_deg - BOUND_EPS_DEG
    return ~((at_lower & (gradient > 0)) | (at_upper & (gradient < 0)))


def solve_batch(robot, tasks, settings: LMSettings | None = None, weights=None,
                initial=None, progress=None) -> BatchResult:
    """Minimise the paper's objective for many tasks at once.

    Args:
        robot: the robot.
        tasks: tasks of equal length n.
        settings: solver settings (default :class:`LMSettings`).
        weights: one weights dict for all tasks or one per task (default ``settings.weights``).
        initial: initial poses (B, N, dof) [motor deg] (default :func:`initial_poses`).
        progress: optional callable ``(iteration, n_active, losses)`` called every iteration.

    Returns:
        A :class:`BatchResult`; every pose lies within the motor ranges.
    """
    settings = settings or LMSettings()
    start = time.perf_counter()
    kin = _kinematics(robot, settings.kinematics)
    problem = Problem.from_tasks(robot, tasks, settings.weights if weights is None else weights)
    poses = initial_poses(robot, tasks) if initial is None else np.array(initial, dtype=float)
    poses = np.clip(poses, problem.lower_deg, problem.upper_deg)
    b = len(tasks)
    current = evaluate(kin, problem, poses)
    damping = np.full(b, settings.damping)
    nu = np.full(b, 2.0)
    iterations = np.zeros(b, dtype=int)
    converged = np.zeros(b, dtype=bool)
    active = np.arange(b)
    while active.size:
        sub = problem.take(active)
        ev = _take(current, active)
        x = poses[active]
        free = _free_variables(sub, x, ev.gradient)
        scale = np.maximum(np.diagonal(ev.diagonal, axis1=-2, axis2=-1), 1e-12)
        damped = ev.diagonal.copy()
        idx = np.arange(x.shape[-1])
        damped[..., idx, idx] += damping[active, None, None] * scale
        step, ok = solve_normal_equations(damped, ev.coupling, -ev.gradient, free,
                                          settings.linear_solver)
        trial = np.clip(x + step, sub.lower_deg, sub.upper_deg)
        step = trial - x
        predicted = -(2.0 * np.sum(ev.gradient * step, axis=(1, 2))
                      + np.sum(step * block_matvec(ev, step), axis=(1, 2)))
        new = evaluate(kin, sub, trial)
        gain = (ev.loss - new.loss) / np.where(predicted > 0, predicted, np.inf)
        accept = ok & (predicted > 0) & (gain > MIN_GAIN_RATIO)
        iterations[active] += 1

        acc = active[accept]
        poses[acc] = trial[accept]
        _put(current, acc, _take(new, np.flatnonzero(accept)))
        g = gain[accept]
        damping[acc] *= np.maximum(1.0 / 3.0, 1.0 - (2.0 * g - 1.0) ** 3)
        nu[acc] = 2.0
        rej = active[~accept]
        damping[rej] *= nu[rej]
        nu[rej] *= 2.0

        decrease = ev.loss - new.loss
        small = accept & ((decrease <= settings.tolerance * new.loss)
                          | (np.max(np.abs(step), axis=(1, 2)) <= settings.tolerance))
        converged[active[small]] = True
        stuck = damping[active] > MAX_DAMPING
        converged[active[stuck & ~small]] = _stationary(ev, x, sub)[stuck & ~small]
        done = small | stuck | (iterations[active] >= settings.max_iterations)
        if progress:
            progress(int(iterations.max()), int(active.size), current.loss)
        active = active[~done]
    return BatchResult(poses, current.loss, current.terms, iterations, converged,
                       time.perf_counter() - start)


def _stationary(ev: Evaluation, poses, problem: Problem, rtol: float = 1e-6):
    """True where the projected gradient is negligible (no descent direction is left)."""
    g = np.where(_free_variables(problem, poses, ev.gradient), ev.gradient, 0.0)
    return np.max(np.abs(g), axis=(1, 2)) <= rtol * np.maximum(ev.loss, 1.0)


def _take(ev: Evaluation, index) -> Evaluation:
    return Evaluation(*(None if v is None else v[index] for v in
                        (ev.loss, ev.terms, ev.gradient, ev.diagonal, ev.coupling)))


def _put(ev: Evaluation, index, new: Evaluation) -> None:
    for name in ("loss", "terms", "gradient", "diagonal", "coupling"):
        getattr(ev, name)[index] = getattr(new, name)


def _kinematics(robot, name: str):
    if name == "pinocchio":
        return lambda poses, jacobian=True: pinocchio_kinematics(robot, poses, jacobian)
    key = "ours_lm_chain"
    if key not in robot._cache:
        robot._cache[key] = ChainKinematics(robot)
    return robot._cache[key]


# ----- the method ----------------------------------------------------------------------------
@register
class OursLM(Method):
    """The paper's objective minimised by Levenberg-Marquardt (block-tridiagonal, batched)."""

    name = "ours-lm"
    description = ("the paper's objective (same L0..L6, units, weights) by batched "
                   "Levenberg-Marquardt with analytic Jacobians and joint-limit boxes")
    options = {"weights": "weights", "lm_max_iterations": "max_iterations",
               "lm_tolerance": "tolerance", "lm_damping": "damping",
               "lm_kinematics": "kinematics", "lm_linear_solver": "linear_solver"}

    def __init__(self, weights: dict | str | None = None, max_iterations: int = 200,
                 tolerance: float = 1e-9, damping: float = 1e-3, kinematics: str = "numpy",
                 linear_solver: str = "banded"):
        # As in ``ours``: changes (a --weights string) go on top of a task's own default
        # weights; a dict is the complete set and is used for every task.
        self._explicit_weights = isinstance(weights, dict)
        self._weight_changes = None if self._explicit_weights else weights
        if not self._explicit_weights:
            weights = parse_weights(weights)
        if isinstance(max_iterations, bool) or int(max_iterations) != max_iterations \
                or max_iterations < 1:
            raise InputError(f"--lm-max-iterations: {max_iterations!r} must be an integer >= 1")
        for flag, value in (("--lm-tolerance", tolerance), ("--lm-damping", damping)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InputError(f"{flag}: {value!r} must be a positive number")
        if kinematics not in KINEMATICS:
            raise InputError(f"--lm-kinematics: {kinematics!r} is not one of "
                             f"{', '.join(KINEMATICS)}")
        if linear_solver not in LINEAR_SOLVERS:
            raise InputError(f"--lm-linear-solver: {linear_solver!r} is not one of "
                             f"{', '.join(LINEAR_SOLVERS)}")
        self.settings = LMSettings(weights=weights, max_iterations=int(max_iterations),
                                   tolerance=float(tolerance), damping=float(damping),
                                   kinematics=kinematics, linear_solver=linear_solver)

    @classmethod
    def add_arguments(cls, group) -> None:
        group.add_argument("--lm-max-iterations", type=int, default=None,
                           help="ours-lm: iteration cap per trajectory (default 200); the "
                           "loss weights come from --weights")
        group.add_argument("--lm-tolerance", type=float, default=None,
                           help="ours-lm: stop when a step lowers the loss by less than this "
                           "fraction or moves no joint by more than this many degrees "
                           "(default 1e-9)")
        group.add_argument("--lm-damping", type=float, default=None,
                           help="ours-lm: initial Marquardt damping (default 1e-3)")
        group.add_argument("--lm-kinematics", choices=KINEMATICS, default=None,
                           help="ours-lm: vectorised numpy chain (default) or Pinocchio "
                           "computeFrameJacobian per pose (reference, slower)")
        group.add_argument("--lm-linear-solver", choices=LINEAR_SOLVERS, default=None,
                           help="ours-lm: banded Cholesky via LAPACK (default) or numpy "
                           "block Thomas")

    def settings_for(self, task) -> LMSettings:
        """The settings for one task: its default weights, if any, under the user's changes."""
        if task.default_weights is None or self._explicit_weights:
            return self.settings
        return replace(self.settings, weights=parse_weights(self._weight_changes,
                                                            task.default_weights))

    def solve(self, robot, task, progress=None) -> Solution:
        return self.solve_many(robot, [task])[0]

    def solve_many(self, robot, tasks, progress=None) -> list[Solution]:
        """One batched solve of every task (each with :meth:`settings_for`'s weights); each
        Solution's duration_s is its share of the batch's wall time."""
        from ikbench.methods.ours import format_weights

        weights = [self.settings_for(task).weights for task in tasks]
        if progress:
            for k, task in enumerate(tasks):
                progress.start(task, k, len(tasks))
        result = solve_batch(robot, tasks, self.settings, weights=weights)
        share = result.duration_s / len(tasks)
        solutions = []
        for k, task in enumerate(tasks):
            solutions.append(Solution(
                poses_deg=result.poses_deg[k], iterations=int(result.iterations[k]),
                duration_s=share, loss=float(result.loss[k]),
                converged=bool(result.converged[k]),
                info={"batch_size": len(tasks), "batch_wall_time_s": result.duration_s,
                      "weights": format_weights(weights[k]),
                      **{f"{t}": float(v) for t, v in zip(TERMS, result.terms[k])}}))
            if progress:
                progress.done(task, solutions[-1])
        return solutions
