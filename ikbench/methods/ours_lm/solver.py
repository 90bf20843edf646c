"""Projected Levenberg-Marquardt on the paper's objective, batched over trajectories.

Joint limits are box constraints: projected LM with an active set (a variable at a bound whose
gradient points outwards is held), steps clipped to the box, Marquardt damping diag(J^T J)
with Nielsen's update. Initial poses: the joint interpolation from start to touch pose, or,
for a task that pins neither (a letter, polyline or spline), every pose at the task's reference
pose. Many trajectories are solved at once, vectorised over trajectories and poses.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.core.kinematics.chain import pinocchio_kinematics
from ikbench.core.losses import PAPER_WEIGHTS_TEXT, check_weights, resolve_weights
from ikbench.methods.base import check_choice, check_positive, option
from ikbench.methods.ours_lm.devices import (
    BACKENDS,
    DTYPES,
    check_backend,
    check_device,
    cpu_backend,
)
from ikbench.methods.ours_lm.linalg import block_matvec, solve_normal_equations
from ikbench.methods.ours_lm.problem import Evaluation, Problem, Weights, evaluate

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.methods.ours_lm.frames import FrameProblem

#: ``progress(iteration, n_active, losses)``: called every iteration of a batched solve.
LMProgress = Callable[[int, int, np.ndarray], object]

KINEMATICS = ("numpy", "pinocchio")
LINEAR_SOLVERS = ("banded", "thomas")
#: A variable within this distance [motor deg] of a bound counts as on the bound.
BOUND_EPS_DEG = 1e-9
#: Steps whose gain ratio (actual / predicted reduction) is below this are rejected.
MIN_GAIN_RATIO = 1e-4
#: Give up on a trajectory when the damping exceeds this (no descent step exists).
MAX_DAMPING = 1e12


@dataclass
class LMSettings:
    """Settings of the Levenberg-Marquardt solver (CLI options from the ``option`` fields).

    Attributes:
        weights: loss weights: a complete dict keyed L0..L6, or changes such as ``"c0=100"``
            on top of each task's (else the paper's) weights; None: none.
        max_iterations: iteration cap per trajectory.
        tolerance: stop when an accepted step lowers the loss by less than
            ``tolerance * loss`` (relative), or moves no pose by more than ``tolerance`` deg.
        damping: initial Marquardt damping factor lambda (times diag(J^T J)).
        kinematics: ``"numpy"`` (vectorised chain FK from the Pinocchio model) or
            ``"pinocchio"`` (``computeFrameJacobian`` per pose; the reference, slower).
        linear_solver: ``"banded"`` (LAPACK banded Cholesky) or ``"thomas"`` (numpy).
        device: None for the CPU solvers (numpy or numba, ``backend``); ``"cpu"``,
            ``"cuda"`` or ``"cuda:N"`` for the torch backend on that device
            (:mod:`.torch_backend`).
        dtype: the torch backend's precision, ``"float64"`` or ``"float32"``.
        backend: without ``device``: ``"numpy"`` (this module, the reference), ``"numba"``
            (the same loop compiled, :mod:`.compiled`; needs the ``[fast]`` extra) or
            ``"auto"``: numba when installed (and kinematics numpy, linear solver banded).
        threads: threads of the numba backend (None: all cores numba sees).
    """

    weights: dict | str | None = option(
        None, type=str, show_default=PAPER_WEIGHTS_TEXT,
        help="loss weights to change, e.g. c1=20,c6=5 (letters start from their own)")
    max_iterations: int = option(200, flag="lm-max-iterations",
                                 help="iteration cap per trajectory")
    tolerance: float = option(1e-9, flag="lm-tolerance",
                              help="stop when a step lowers the loss by less than this "
                              "fraction or moves no joint by more than this many degrees")
    damping: float = option(1e-3, flag="lm-damping", help="initial Marquardt damping")
    kinematics: str = option("numpy", flag="lm-kinematics", choices=KINEMATICS,
                             help="vectorised numpy chain, or Pinocchio "
                             "computeFrameJacobian per pose (reference, slower)")
    linear_solver: str = option("banded", flag="lm-linear-solver", choices=LINEAR_SOLVERS,
                                help="banded Cholesky via LAPACK, or numpy block Thomas "
                                "(the torch backend: thomas forces its block Thomas; else it "
                                "picks cyclic reduction or block Thomas by batch size)")
    device: str | None = option(None, type=str, show_default="none: the numpy solver",
                                help="cpu, cuda or cuda:N: the torch backend on that device")
    dtype: str = option("float64", choices=DTYPES,
                        help="precision of the torch backend (--device)")
    backend: str = option("auto", flag="lm-backend", choices=BACKENDS,
                          help="CPU solver without --device: numpy (the reference), numba "
                          "(the same loop compiled; pip extra [fast]) or auto (numba when "
                          "installed)")
    threads: int | None = option(None, flag="lm-threads", type=int,
                                 show_default="all cores",
                                 help="threads of the numba backend (trajectories are shared "
                                 "out among them)")

    def __post_init__(self):
        check_positive(self, "max_iterations", integer=True)
        check_positive(self, "tolerance", "damping")
        check_choice(self, "kinematics", KINEMATICS)
        check_choice(self, "linear_solver", LINEAR_SOLVERS)
        check_weights(self.weights)
        self.max_iterations = int(self.max_iterations)
        self.device = check_device(self.device)
        check_backend(self)


@dataclass
class BatchResult:
    """Result of :func:`solve_batch`: arrays over the B trajectories."""

    poses_deg: np.ndarray        # (B, N, dof)
    loss: np.ndarray             # (B,)
    terms: np.ndarray            # (B, 7) L0..L6
    iterations: np.ndarray       # (B,) LM iterations (accepted + rejected steps)
    converged: np.ndarray        # (B,) bool: the tolerance was met before the cap
    duration_s: float            # wall time of the whole batch [s]


def initial_poses(robot: Robot, tasks: Sequence[Task]) -> np.ndarray:
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


def initial_poses_batched(robot: Robot, tasks: Sequence[Task]) -> np.ndarray:
    """:func:`~.solver.initial_poses` without a loop over tasks when every task pins a start
    and a touch pose (the same operations, so the same numbers)."""
    if not all(t.start_pose_deg is not None and t.end_pose_deg is not None for t in tasks) \
            or len({t.steps for t in tasks}) != 1:
        return initial_poses(robot, tasks)
    # every task pins both (checked above)
    start = np.stack([cast(np.ndarray, t.start_pose_deg) for t in tasks])[:, None, :]
    end = np.stack([cast(np.ndarray, t.end_pose_deg) for t in tasks])[:, None, :]
    t = np.linspace(0.0, 1.0, tasks[0].steps + 1)[None, :, None]
    return np.clip(start + t * (end - start), robot.lower_motor_deg, robot.upper_motor_deg)


def _free_variables(problem: Problem | FrameProblem, poses: np.ndarray, gradient: np.ndarray
                    ) -> np.ndarray:
    """False for variables on a bound whose descent direction (-gradient) leaves the box."""
    at_lower = poses <= problem.lower_deg + BOUND_EPS_DEG
    at_upper = poses >= problem.upper_deg - BOUND_EPS_DEG
    return ~((at_lower & (gradient > 0)) | (at_upper & (gradient < 0)))


def solve_batch(robot: Robot, tasks: Sequence[Task], settings: LMSettings | None = None,
                weights: Weights | None = None, initial: npt.ArrayLike | None = None,
                progress: LMProgress | None = None,
                problem: Problem | FrameProblem | None = None,
                evaluator: Callable[..., Evaluation] = evaluate,
                until: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
                ) -> BatchResult:
    """Minimise the paper's objective for many tasks at once.

    Args:
        robot: the robot.
        tasks: tasks of equal length n.
        settings: solver settings (default :class:`LMSettings`).
        weights: one weights dict for all tasks or one per task (default ``settings.weights``).
        initial: initial poses (B, N, dof) [motor deg] (default :func:`initial_poses`).
        progress: optional callable ``(iteration, n_active, losses)`` called every iteration.
        problem: the least-squares problem (default: the paper's objective,
            :meth:`Problem.from_tasks`); e.g. a :class:`.frames.FrameProblem`.
        evaluator: ``evaluator(kinematics, problem, poses, derivatives)`` -> Evaluation of
            ``problem`` (default :func:`.problem.evaluate`). The numba backend
            (``settings.backend``) runs the default problem and evaluator without ``until``;
            anything else runs here in numpy. Its ``progress`` is called once, at the end.
        until: optional ``until(poses (A, N, dof), indices (A,)) -> (A,) bool`` called after
            every iteration with the active trajectories' poses; those it marks stop, counted
            as converged (e.g. once a pose path meets its validity criteria).

    Returns:
        A :class:`BatchResult`; every pose lies within the motor ranges.
    """
    settings = settings or LMSettings()
    if settings.device is not None:  # the same algorithm in torch on a device
        from ikbench.methods.ours_lm import torch_backend

        return torch_backend.solve_batch(robot, tasks, settings, weights, initial, progress)
    compiled = (_compiled(settings) if problem is None and evaluator is evaluate
                and until is None else None)
    if compiled is not None:  # the same loop compiled
        if weights is None:
            weights = [resolve_weights(settings.weights, task) for task in tasks]
        result = compiled.solve_batch(robot, tasks, settings, weights, initial)
        if progress:
            progress(int(result.iterations.max(initial=0)), 0, result.loss)
        return result
    start = time.perf_counter()
    if weights is None:
        weights = [resolve_weights(settings.weights, task) for task in tasks]
    if problem is None:
        problem = Problem.from_tasks(robot, tasks, weights)
    poses = initial_poses(robot, tasks) if initial is None else np.array(initial, dtype=float)
    return _solve_numpy(robot, problem, poses, settings, progress, evaluator, until, start)


def solve_problem(robot: Robot, problem: Problem, initial: npt.ArrayLike,
                  settings: LMSettings | None = None,
                  progress: LMProgress | None = None) -> BatchResult:
    """:func:`solve_batch` of a ready :class:`.problem.Problem` (the paper's objective) from
    ``initial`` poses (B, N, dof), by the solver ``settings`` choose (numpy, numba, torch on
    a device); no Task objects (e.g. the lines of a dataset's shard)."""
    settings = settings or LMSettings()
    if settings.device is not None:
        from ikbench.methods.ours_lm import torch_backend

        return torch_backend.solve_problem(robot, problem, initial, settings, progress)
    start = time.perf_counter()
    poses = np.array(initial, dtype=float)
    compiled = _compiled(settings)
    if compiled is None:
        return _solve_numpy(robot, problem, poses, settings, progress, evaluate, None, start)
    result = compiled.solve(robot, problem, poses, settings)
    if progress:
        progress(int(result.iterations.max(initial=0)), 0, result.loss)
    result.duration_s = time.perf_counter() - start
    return result


def _solve_numpy(robot: Robot, problem: Problem | FrameProblem, poses: np.ndarray,
                 settings: LMSettings, progress: LMProgress | None,
                 evaluator: Callable[..., Evaluation],
                 until: Callable[[np.ndarray, np.ndarray], np.ndarray] | None,
                 start: float) -> BatchResult:
    """The numpy loop of :func:`solve_batch` from initial poses (B, N, dof): per iteration,
    a damped step of the trajectories still running (:func:`_damped_step`), the gain test,
    Nielsen's damping update and the stopping rule (:func:`_stopping_rule`); ``start``: the
    :func:`time.perf_counter` the duration counts from."""
    kin = _kinematics(robot, settings.kinematics)
    poses = np.clip(poses, problem.lower_deg, problem.upper_deg)
    b = len(poses)
    current = evaluator(kin, problem, poses)
    damping = np.full(b, settings.damping)
    nu = np.full(b, 2.0)
    iterations = np.zeros(b, dtype=int)
    converged = np.zeros(b, dtype=bool)
    active = np.arange(b)
    while active.size:
        sub = problem.take(active)
        ev = _take(current, active)
        x = poses[active]
        trial, step, ok, predicted = _damped_step(ev, sub, x, damping[active],
                                                  settings.linear_solver)
        new = evaluator(kin, sub, trial)
        gain = (ev.loss - new.loss) / np.where(predicted > 0, predicted, np.inf)
        accept = ok & (predicted > 0) & (gain > MIN_GAIN_RATIO)
        iterations[active] += 1

        acc = active[accept]
        poses[acc] = trial[accept]
        _put(current, acc, _take(new, np.flatnonzero(accept)))
        nielsen_update(damping, nu, active, accept, gain)

        done = _stopping_rule(ev, new, x, sub, step, accept, active, damping, iterations,
                              converged, settings)
        if until is not None:
            reached = np.asarray(until(poses[active], active), dtype=bool)
            converged[active[reached]] = True
            done |= reached
        if progress:
            progress(int(iterations.max()), int(active.size), current.loss)
        active = active[~done]
    return BatchResult(poses, current.loss, current.terms, iterations, converged,
                       time.perf_counter() - start)


def _damped_step(ev: Evaluation, problem: Problem | FrameProblem, poses: np.ndarray,
                 damping: np.ndarray, linear_solver: str
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One projected Levenberg-Marquardt step of the active trajectories.

    Solves (J^T J + lambda diag(J^T J)) s = -J^T r over the free variables (those on a bound
    whose descent leaves the box are held), then clips ``poses + s`` to the box.

    Args:
        ev: the evaluation at ``poses`` (A trajectories).
        problem: their sub-problem (bounds).
        poses: (A, N, dof) [motor deg].
        damping: (A,) Marquardt damping factors lambda.
        linear_solver: ``banded`` or ``thomas`` (:func:`.linalg.solve_normal_equations`).

    Returns:
        (trial poses (A, N, dof), the step taken after clipping (A, N, dof), ok (A,): the
        damped system was solved, predicted loss decrease (A,) of the Gauss-Newton model).
    """
    free = _free_variables(problem, poses, ev.gradient)
    scale = np.maximum(np.diagonal(ev.diagonal, axis1=-2, axis2=-1), 1e-12)
    damped = ev.diagonal.copy()
    idx = np.arange(poses.shape[-1])
    damped[..., idx, idx] += damping[:, None, None] * scale
    step, ok = solve_normal_equations(damped, ev.coupling, -ev.gradient, free, linear_solver)
    trial = np.clip(poses + step, problem.lower_deg, problem.upper_deg)
    step = trial - poses
    predicted = -(2.0 * np.sum(ev.gradient * step, axis=(1, 2))
                  + np.sum(step * block_matvec(ev, step), axis=(1, 2)))
    return trial, step, ok, predicted


def _stopping_rule(ev: Evaluation, new: Evaluation, poses: np.ndarray,
                   problem: Problem | FrameProblem,
                   step: np.ndarray, accept: np.ndarray, active: np.ndarray,
                   damping: np.ndarray, iterations: np.ndarray, converged: np.ndarray,
                   settings: LMSettings) -> np.ndarray:
    """Which active trajectories stop after this iteration, (A,) bool; ``converged`` (B,) is
    marked in place.

    An accepted step that lowers the loss by at most ``tolerance * loss`` or moves no pose
    by more than ``tolerance`` deg converges; a damping above :data:`MAX_DAMPING` (no descent
    step found) stops, converged when the projected gradient is negligible; the iteration
    cap stops, not converged. ``ev``, ``poses``, ``problem``, ``step``, ``accept``: the
    iteration's (per active trajectory); ``damping``, ``iterations``: per trajectory (B,).
    """
    decrease = ev.loss - new.loss
    small = accept & ((decrease <= settings.tolerance * new.loss)
                      | (np.max(np.abs(step), axis=(1, 2)) <= settings.tolerance))
    converged[active[small]] = True
    stuck = damping[active] > MAX_DAMPING
    converged[active[stuck & ~small]] = _stationary(ev, poses, problem)[stuck & ~small]
    return small | stuck | (iterations[active] >= settings.max_iterations)


def _compiled(settings: LMSettings):
    """The numba backend's module when ``settings`` choose it, else None. With ``auto``, a
    numba that is installed but fails to import falls back to numpy; asked for by name, it
    is an InputError."""
    if cpu_backend(settings) != "numba":
        return None
    try:
        from ikbench.methods.ours_lm import compiled
    except ImportError as error:
        if settings.backend == "numba":
            raise InputError(f"--lm-backend numba: numba does not import ({error}); "
                             "use --lm-backend numpy") from None
        return None
    return compiled


def nielsen_update(damping: np.ndarray, nu: np.ndarray, active: np.ndarray, accept: np.ndarray,
                   gain: np.ndarray) -> None:
    """Nielsen's damping update, in place: an accepted step (gain ratio g) scales the damping
    by max(1/3, 1 - (2g - 1)^3) and resets nu to 2; a rejected one multiplies the damping by
    nu and doubles nu (H. B. Nielsen, Damping parameter in Marquardt's method, 1999).
    ``active``: the trajectories' indices; ``accept``, ``gain``: per active trajectory."""
    acc, rej = active[accept], active[~accept]
    damping[acc] *= np.maximum(1.0 / 3.0, 1.0 - (2.0 * gain[accept] - 1.0) ** 3)
    nu[acc] = 2.0
    damping[rej] *= nu[rej]
    nu[rej] *= 2.0


def _stationary(ev: Evaluation, poses: np.ndarray, problem: Problem | FrameProblem,
                rtol: float = 1e-6) -> np.ndarray:
    """True where the projected gradient is negligible (no descent direction is left)."""
    g = np.where(_free_variables(problem, poses, ev.gradient), ev.gradient, 0.0)
    return np.max(np.abs(g), axis=(1, 2)) <= rtol * np.maximum(ev.loss, 1.0)


def _take(ev: Evaluation, index) -> Evaluation:
    def take(v):
        return None if v is None else v[index]

    return Evaluation(ev.loss[index], ev.terms[index], take(ev.gradient), take(ev.diagonal),
                      take(ev.coupling))


def _put(ev: Evaluation, index, new: Evaluation) -> None:
    for name in ("loss", "terms", "gradient", "diagonal", "coupling"):
        getattr(ev, name)[index] = getattr(new, name)


def _kinematics(robot, name: str):
    """The FK + Jacobian function of ``settings.kinematics`` (point in m, per pose unit)."""
    if name == "pinocchio":
        return lambda poses, jacobian=True: pinocchio_kinematics(robot, poses, jacobian)
    return robot.chain_kinematics()
