"""Sequential quadratic programming with a Gauss-Newton model, batched over trajectories.

Each iteration linearises the constraints and takes the Gauss-Newton (J^T J, Marquardt
damped) model of the objective of :mod:`.problem`, and solves the equality-constrained QP
exactly by the banded KKT solve of :mod:`.kkt` (a full Newton step on the constraints,
whatever the damping). Steps are judged on the l1 merit function
``phi = f + rho |c|_1`` (Nocedal & Wright, Numerical Optimization, 2nd ed., Sec. 18.3 and
18.5), with ``rho`` kept above twice the largest multiplier: a step is accepted when the merit
falls by a fair share of what the model predicts, otherwise the damping grows and the step
shortens (Nielsen's update, as in ours-lm). The joint limits are bounds held by an active set:
a joint at a bound whose Lagrangian gradient points out of the box is held for the step, and
every trial is clipped to the box.

A trajectory stops when its constraints hold to ``feasibility_tolerance`` and the last accepted
step changed the merit by less than ``tolerance`` (relative) or moved no joint by more than
``tolerance`` [pose units]; or at the iteration cap; or when no step lowers the merit any more
(then it is feasible or reported infeasible with its largest violation).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np

from ikbench.methods.base import report_fraction
from ikbench.methods.ours_exact.kkt import solve_kkt
from ikbench.methods.ours_exact.problem import (
    ExactProblem,
    KinematicsAt,
    Model,
    evaluate,
    kinematics_at,
)
from ikbench.methods.ours_lm.solver import batch_bookkeeping, nielsen_update

if TYPE_CHECKING:
    from ikbench.core.kinematics.chain import ChainKinematics

#: A joint within this distance [pose units] of a bound counts as on the bound.
BOUND_EPS = 1e-9
#: Steps whose gain ratio (actual / predicted merit decrease) is below this are rejected.
MIN_GAIN_RATIO = 1e-4
#: The stopping rule trusts a small change only from a step damped less than this.
UNDAMPED = 1.0
#: Give up on a trajectory when the damping exceeds this.
MAX_DAMPING = 1e10
#: Second-order corrections of a trial (minimum-norm steps back onto the constraints, pose by
#: pose), against the constraints' curvature (the Maratos effect of l1 merit functions).
CORRECTIONS = 1
#: A correction may move a pose as far as the step did, plus this [pose units].
CORRECTION_SLACK = 1e-3
#: Polishing steps of the constraints after the loop.
POLISH = 5
#: Minimum-norm restoration steps of the initial trajectory.
RESTORATIONS = 20
#: The merit weight rho is kept at least this multiple of the largest multiplier.
RHO_MARGIN = 2.0


@dataclass
class SQPResult:
    """Arrays over the B trajectories.

    Attributes:
        poses: (B, N, k) [pose units], within the bounds.
        objective: (B,) the objective f.  terms: (B, 4) its summands (``problem.TERMS``).
        violation: (B,) the largest constraint violation [mm or deg].
        worst: (B, 2) the pose index and constraint row of the largest violation.
        iterations: (B,) SQP iterations.  converged: (B,) the stopping rule was met.
        duration_s: wall time [s].
    """

    poses: np.ndarray
    objective: np.ndarray
    terms: np.ndarray
    violation: np.ndarray
    worst: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    duration_s: float


def solve(kinematics: ChainKinematics, problem: ExactProblem, initial: np.ndarray, *,
          max_iterations: int = 100, tolerance: float = 1e-4,
          feasibility_tolerance: float = 1e-6, damping: float = 1e-3,
          restorations: int = RESTORATIONS,
          trace: Callable[..., object] | None = None) -> SQPResult:
    """Solve ``problem`` from ``initial`` poses (B, N, k); fixed poses keep their values.
    The initial poses are first moved onto the constraints pose by pose
    (:func:`restore_feasibility`, at most ``restorations`` steps; 0: start from them as they
    are, e.g. from an initial trajectory that is already smooth and close)."""
    started = time.perf_counter()
    x, at = restore_feasibility(kinematics, problem, initial, restorations,
                                feasibility_tolerance)
    b = len(x)
    current = evaluate(kinematics, problem, x, at=at)
    multipliers = np.zeros_like(current.residual)
    rho = np.zeros(b)
    mu = np.full(b, damping)
    nu, iterations, converged, active = batch_bookkeeping(b)
    while active.size:
        sub = problem.take(active)
        model = current.take(active)
        xa = x[active]
        free = _free(sub, xa, model, multipliers[active])
        damped = model.diagonal.copy()
        idx = np.arange(xa.shape[-1])
        damped[..., idx, idx] += mu[active, None, None] * np.maximum(
            model.diagonal[..., idx, idx], 1e-12)
        largest = np.max(np.abs(multipliers[active]) * sub.constrained[..., None],
                         axis=(1, 2), initial=0.0)
        rho[active] = np.maximum(rho[active], RHO_MARGIN * 2.0 * largest)
        r = rho[active]
        step, lam, ok, full = _bounded_step(sub, model, damped, xa, free, r)
        largest = np.max(np.abs(lam) * sub.constrained[..., None], axis=(1, 2), initial=0.0)
        rho[active] = r = np.maximum(r, RHO_MARGIN * 2.0 * largest)
        predicted = predicted_decrease(model, step, r)
        before = model.objective + r * _l1(model.residual)
        trial = xa + step
        at = kinematics_at(kinematics, sub, trial)
        new = evaluate(kinematics, sub, trial, at=at)
        gain = _gain(before, new, r, predicted)
        accept = ok & (predicted > 0) & (gain > MIN_GAIN_RATIO)
        retry = np.flatnonzero(ok & (predicted > 0) & ~accept)
        if retry.size:  # second-order correction of the rejected trials
            part = sub.take(retry)
            corrected, at_corrected = restore_feasibility(
                kinematics, part, trial[retry], CORRECTIONS, feasibility_tolerance,
                movable=free[retry], at=cast(KinematicsAt, tuple(v[retry] for v in at)),
                max_move=np.max(np.abs(step[retry]), axis=-1) + CORRECTION_SLACK)
            second = evaluate(kinematics, part, corrected, at=at_corrected)
            second_gain = _gain(before[retry], second, r[retry], predicted[retry])
            better = second_gain > MIN_GAIN_RATIO
            fixed = retry[better]
            trial[fixed] = corrected[better]
            new.put(fixed, second.take(np.flatnonzero(better)))
            gain[fixed] = second_gain[better]
            accept[fixed] = True
        after = new.objective + r * _l1(new.residual)
        if trace is not None:
            trace(active=active, accept=accept, gain=gain, predicted=predicted,
                  actual=before - after, damping=mu[active], step=step, model=model, new=new)
        iterations[active] += 1
        report_fraction(int(iterations.max()), max_iterations)

        acc = active[accept]
        x[acc] = trial[accept]
        current.put(acc, new.take(np.flatnonzero(accept)))
        multipliers[acc] = lam[accept]
        nielsen_update(mu, nu, active, accept, gain)

        # a nearly undamped (Gauss-Newton) step that changes little: stationary
        scale = tolerance * np.maximum(np.abs(before), 1e-12)
        small = (accept & full & (mu[active] <= UNDAMPED)
                 & (new.violation() <= feasibility_tolerance)
                 & ((np.abs(before - after) <= scale)
                    | (np.max(np.abs(step), axis=(1, 2)) <= tolerance)))
        converged[active[small]] = True
        stuck = mu[active] > MAX_DAMPING
        converged[active[stuck & ~small]] = (
            current.take(active[stuck & ~small]).violation() <= feasibility_tolerance)
        done = small | stuck | (iterations[active] >= max_iterations)
        active = active[~done]
    # polish: the constraints to the tolerance, pose by pose (a step of the order of the
    # remaining violation, where the loop stopped on the cap or on a slow objective)
    loose = np.flatnonzero(current.violation() > feasibility_tolerance)
    if loose.size:
        part = problem.take(loose)
        polished, at = restore_feasibility(kinematics, part, x[loose], POLISH,
                                           feasibility_tolerance)
        x[loose] = polished
        current.put(loose, evaluate(kinematics, part, polished, at=at))
    worst = _worst(current)
    return SQPResult(x, current.objective, current.terms, current.violation(), worst,
                     iterations, converged, time.perf_counter() - started)


def restore_feasibility(kinematics: ChainKinematics, problem: ExactProblem, poses: np.ndarray,
                        iterations: int = 20, tolerance: float = 1e-7,
                        movable: np.ndarray | None = None, max_move: np.ndarray | None = None,
                        at: KinematicsAt | None = None) -> tuple[np.ndarray, KinematicsAt]:
    """Move every constrained pose, independently, towards its goal by minimum-norm
    Gauss-Newton steps over its ``movable`` joints (default: all of the poses that are not
    fixed), clipped to the box; a correction that does not lower a pose's violation is
    dropped, and so is one that moves a pose further than ``max_move`` (B, N) [pose units]
    when given; ``at``: the poses' :func:`kinematics_at` when already computed. Used to
    start :func:`solve` on the constraints from a trajectory that leaves them (the joint
    interpolation), and as the second-order correction of a rejected trial."""
    x = _clip(problem, np.array(poses, dtype=float))
    if movable is None:
        movable = np.broadcast_to(~problem.fixed[..., None], x.shape)
    if at is None:
        at = kinematics_at(kinematics, problem, x)
    for _ in range(iterations):
        residual, jacobian = at[0], at[1]
        error = np.max(np.abs(residual), axis=-1)                          # (B, N)
        if np.all(error <= tolerance):
            break
        moving = movable
        for _ in range(3):  # joints on a bound that the step would push out stay there
            step = _min_norm_step(jacobian * moving[..., None, :], residual)
            target = x + step
            out = moving & (((target < problem.lower) & (x <= problem.lower + BOUND_EPS))
                            | ((target > problem.upper) & (x >= problem.upper - BOUND_EPS)))
            if not out.any():
                break
            moving = moving & ~out
        trial = _clip(problem, x + step)
        new = kinematics_at(kinematics, problem, trial)
        better = np.max(np.abs(new[0]), axis=-1) < error                   # (B, N)
        if max_move is not None:
            better &= np.max(np.abs(trial - x), axis=-1) <= max_move
        if not better.any():
            break
        x = np.where(better[..., None], trial, x)
        at = cast(KinematicsAt, tuple(
            np.where(better.reshape(*better.shape, *([1] * (old.ndim - 2))), value, old)
            for value, old in zip(new, at)))
    return x, at


def _clip(problem: ExactProblem, poses):
    """``poses`` (B, N, k) clipped to the box, the fixed poses as they are (a recorded pose
    may sit on a limit, which the box keeps a margin inside)."""
    return np.where(problem.fixed[..., None], poses,
                    np.clip(poses, problem.lower, problem.upper))


def _min_norm_step(a, residual):
    """-A^+ c per pose for A (..., m, k), c (..., m) (slightly damped least squares)."""
    gram = a @ a.swapaxes(-1, -2)
    trace = np.trace(gram, axis1=-2, axis2=-1)[..., None, None]
    gram += (1e-10 * trace + 1e-12) * np.eye(gram.shape[-1])
    return -(a.swapaxes(-1, -2) @ np.linalg.solve(gram, residual[..., None]))[..., 0]


def _bounded_step(problem: ExactProblem, model: Model, damped, poses, free, rho,
                  rounds: int = 3):
    """The KKT step kept in the box (a small primal active set).

    Joints that the step would push out of the box are moved exactly to their bound and held
    there, and the rest re-solved (a few rounds), so the step still satisfies the linearised
    constraints. Where that combined step does not lower the merit model, the first step is
    shortened to the first bound it reaches instead (fraction to the boundary: a descent
    step). Returns (step (B, N, k), multipliers, ok (B,), full (B,): False where the step was
    shortened)."""
    free = free.copy()
    first, lam, ok = solve_kkt(damped, model.bands, model.jacobian, model.gradient,
                               model.residual, free, problem.constrained)
    step, moved = first, np.zeros_like(poses)
    damped_model = Model(model.objective, model.terms, model.residual, model.gradient,
                         damped, model.bands, model.jacobian)
    for _ in range(rounds):
        target = poses + moved + step
        out = free & ((target < problem.lower) | (target > problem.upper))
        if not out.any():
            break
        moved = np.where(out, np.clip(target, problem.lower, problem.upper) - poses, moved)
        free &= ~out
        gradient = model.gradient + damped_model.hessian_times(moved)
        residual = model.residual + (model.jacobian @ moved[..., None])[..., 0]
        step, lam_round, ok_round = solve_kkt(damped, model.bands, model.jacobian, gradient,
                                              residual, free, problem.constrained)
        lam, ok = lam_round, ok & ok_round
    combined = _clip(problem, poses + moved + step) - poses
    descent = predicted_decrease(model, combined, rho) > 0
    if np.all(descent):
        return combined, lam, ok, descent
    room = np.where(first < 0, problem.lower - poses, problem.upper - poses)
    inside = np.abs(room) > BOUND_EPS
    first = np.where(inside, first, 0.0)            # joints already on their bound stay
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(np.abs(first) > 0, room / first, np.inf)
    alpha = np.clip(np.min(ratio, axis=(1, 2)), 0.0, 1.0)[:, None, None]
    shortened = _clip(problem, poses + alpha * first) - poses
    return np.where(descent[:, None, None], combined, shortened), lam, ok, descent


def _gain(before, new: Model, rho, predicted):
    """Actual over predicted merit decrease (-inf where nothing is predicted)."""
    after = new.objective + rho * _l1(new.residual)
    return (before - after) / np.where(predicted > 0, predicted, np.inf)


def predicted_decrease(model: Model, step: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """(B,) the merit's decrease f + rho |c|_1 that the Gauss-Newton model and the
    linearised constraints predict for ``step``."""
    linear = model.residual + (model.jacobian @ step[..., None])[..., 0]
    return (-(2.0 * np.sum(model.gradient * step, axis=(1, 2))
              + np.sum(step * model.hessian_times(step), axis=(1, 2)))
            + rho * (_l1(model.residual) - _l1(linear)))


def _free(problem: ExactProblem, poses, model: Model, multipliers):
    """(B, N, k) joints that may move: not in a fixed pose, and not at a bound whose
    Lagrangian gradient (objective plus constraints) points out of the box."""
    lagrangian = model.gradient + (model.jacobian.swapaxes(-1, -2)
                                   @ multipliers[..., None])[..., 0]
    at_lower = poses <= problem.lower + BOUND_EPS
    at_upper = poses >= problem.upper - BOUND_EPS
    held = (at_lower & (lagrangian > 0)) | (at_upper & (lagrangian < 0))
    return ~held & ~problem.fixed[..., None]


def _l1(residual):
    return np.sum(np.abs(residual), axis=(1, 2))


def _worst(model: Model) -> np.ndarray:
    """(B, 2) pose index and row of each trajectory's largest constraint violation."""
    flat = np.abs(model.residual).reshape(len(model.residual), -1)
    where = np.argmax(flat, axis=1)
    rows = model.residual.shape[-1]
    return np.stack([where // rows, where % rows], axis=1)
