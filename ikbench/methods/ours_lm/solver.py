"""Projected Levenberg-Marquardt on the paper's objective, batched over trajectories.

Joint limits are box constraints: projected LM with an active set (a variable at a bound whose
gradient points outwards is held), steps clipped to the box, Marquardt damping diag(J^T J)
with Nielsen's update. Initial poses: the joint interpolation from start to touch pose, or,
for a task that pins neither (a letter, polyline or spline), every pose at the task's reference
pose. Many trajectories are solved at once, vectorised over trajectories and poses.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.core.kinematics.chain import pinocchio_kinematics
from ikbench.core.losses import resolve_weights
from ikbench.methods.ours_lm.devices import cpu_backend
from ikbench.methods.ours_lm.linalg import block_matvec, solve_normal_equations
from ikbench.methods.ours_lm.problem import Evaluation, Problem, Weights, evaluate
from ikbench.methods.ours_lm.settings import (  # noqa: F401  (moved; re-exported)
    BOUND_EPS_DEG,
    KINEMATICS,
    LINEAR_SOLVERS,
    MAX_DAMPING,
    MIN_GAIN_RATIO,
    BatchResult,
    LMProgress,
    LMSettings,
    initial_poses,
    initial_poses_batched,
)

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.methods.ours_lm.frames import FrameProblem












def torch_module() -> ModuleType:
    """ours-lm's torch backend (:mod:`.torch_backend`), imported here on first use (torch
    loads in seconds; the numpy and numba solvers never need it)."""
    return importlib.import_module("ikbench.methods.ours_lm.torch_backend")

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
        return torch_module().solve_batch(robot, tasks, settings, weights, initial, progress)
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
        return torch_module().solve_problem(robot, problem, initial, settings, progress)
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
    nu, iterations, converged, active = batch_bookkeeping(b)
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
        compiled = importlib.import_module("ikbench.methods.ours_lm.compiled")
    except ImportError as error:
        if settings.backend == "numba":
            raise InputError(f"--lm-backend numba: numba does not import ({error}); "
                             "use --lm-backend numpy") from None
        return None
    return compiled


def batch_bookkeeping(b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What a damped loop over a batch of ``b`` trajectories starts from: Nielsen's nu (b,)
    = 2 (:func:`nielsen_update`), the iterations (b,) = 0, converged (b,) False, and the
    indices of the trajectories still running: all."""
    return np.full(b, 2.0), np.zeros(b, dtype=int), np.zeros(b, dtype=bool), np.arange(b)


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
