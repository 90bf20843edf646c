"""Torch backend of ``ours-lm``: the same projected Levenberg-Marquardt, batched on a device.

The numpy solver (:mod:`.problem`, :mod:`.linalg`, :mod:`.solver`) step for step in torch, on
``cpu``, ``cuda`` or ``cuda:N``, in float64 or float32: the same residuals and analytic
Jacobians (from :class:`~ikbench.core.kinematics.chain_torch.TorchChainKinematics`), the
same block-tridiagonal Gauss-Newton system solved on the device (batched block cyclic
reduction for a few trajectories, block Cholesky-Thomas elimination for many), the same
active set, step clipping, Marquardt damping with Nielsen's update, gain test and stopping
rule. Trajectories are independent: each one's result does not depend on what else is in
the batch (up to rounding where the solve method switches with the number still running).

Host synchronisation: one per iteration (the number of trajectories still running).

float32: a relative loss decrease of 1e-9 is below float32's resolution (about 1.2e-7), so
the stopping tolerance is raised to :data:`FLOAT32_TOLERANCE` there, and a step whose
predicted decrease is below it also stops the trajectory (the loss cannot resolve more); the
final loss and terms are always recomputed in float64 from the final poses, so ``loss`` is
the objective of the poses returned, whatever the working precision.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import torch

from ikbench.core.kinematics.chain_torch import torch_chain_kinematics
from ikbench.core.losses import resolve_weights
from ikbench.methods.ours_lm.devices import torch_dtype
from ikbench.methods.ours_lm.linalg import block_matvec
from ikbench.methods.ours_lm.problem import CM_PER_M, Problem, Weights, gauss_newton_blocks
from ikbench.methods.ours_lm.settings import (
    BOUND_EPS_DEG,
    MAX_DAMPING,
    MIN_GAIN_RATIO,
    BatchResult,
    LMProgress,
    LMSettings,
    initial_poses_batched,
)

if TYPE_CHECKING:
    from ikbench.core.kinematics.chain_torch import TorchChainKinematics
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: The smallest stopping tolerance used in float32 (relative loss decrease, or step in deg):
#: about 2.5 float32 ulps. 1e-6 stopped 7 of 50 000 sampled trajectories up to 1.8e-4 above
#: the float64 loss; 3e-7 keeps 3 000 of them within 7.5e-7, all converged, no slower.
FLOAT32_TOLERANCE = 3e-7
#: Up to this many running trajectories the block-tridiagonal system is solved by cyclic
#: reduction (~6 rounds of batched kernels for n = 50), above it by block Cholesky-Thomas
#: (n sequential steps, fewer flops). Measured on the CPU (crossover 16-32 trajectories,
#: 1.5x faster for the paper's seven); not tuned on a GPU, where launches cost more.
CYCLIC_MAX_BATCH = 16


@dataclass
class TorchBatchResult(BatchResult):
    """:class:`BatchResult` plus where the time went.

    Attributes:
        loop_s: wall time of the LM iterations on the device (synchronised) [s].
        device: the torch device the solve ran on.
        dtype: the working precision (``float64`` / ``float32``).
    """

    loop_s: float = 0.0
    device: str = "cpu"
    dtype: str = "float64"


@dataclass
class TorchProblem:
    """:class:`~.problem.Problem` as tensors on one device: goal_points_cm (B, N, 3),
    goal_directions (B, N, 3), start/end_pose (B, dof), weights (B, 7), lower/upper_deg
    (dof,)."""

    goal_points_cm: Any
    goal_directions: Any
    start_pose: Any
    end_pose: Any
    weights: Any
    lower_deg: Any
    upper_deg: Any

    @classmethod
    def of(cls, problem: Problem, dtype: torch.dtype, device: str | torch.device
           ) -> TorchProblem:
        return cls(*(torch.as_tensor(getattr(problem, f.name), dtype=dtype, device=device)
                     for f in fields(Problem)))

    def take(self, index: torch.Tensor | None) -> TorchProblem:
        """The sub-problem of trajectories ``index`` (a long tensor; None: all)."""
        if index is None:
            return self
        return TorchProblem(self.goal_points_cm[index], self.goal_directions[index],
                            self.start_pose[index], self.end_pose[index],
                            self.weights[index], self.lower_deg, self.upper_deg)

    def residual_weights(self) -> tuple[torch.Tensor, ...]:
        """Squared residual scales a0^2 .. a6^2, (B,) each (see :mod:`.problem`)."""
        n_poses = self.goal_points_cm.shape[1]
        dof = self.lower_deg.shape[0]
        c = self.weights.T
        return (c[0] / (3 * n_poses), c[1] / (2 * n_poses), c[2], c[3], c[4], c[5],
                c[6] / ((n_poses - 1) * dof))


@dataclass
class TorchEvaluation:
    """loss (B,), terms (B, 7), gradient (B, N, dof) = J^T r, diagonal (B, N, dof, dof) and
    coupling (B,): the blocks of J^T J (off-diagonal blocks -coupling * I)."""

    loss: Any
    terms: Any
    gradient: Any = None
    diagonal: Any = None
    coupling: Any = None

    def take(self, index: torch.Tensor | None) -> TorchEvaluation:
        if index is None:
            return self
        return TorchEvaluation(*(None if v is None else v[index] for v in self._values()))

    def _values(self):
        return (self.loss, self.terms, self.gradient, self.diagonal, self.coupling)


def evaluate(kinematics: TorchChainKinematics, problem: TorchProblem, poses: torch.Tensor,
             derivatives: bool = True) -> TorchEvaluation:
    """Residuals of ``problem`` at ``poses`` (B, N, dof) [motor deg]: a
    :class:`TorchEvaluation` (the numpy :func:`~.problem.evaluate`, in torch)."""
    b, n_poses, dof = poses.shape
    point, direction, j_point, j_dir = kinematics(poses.reshape(-1, dof), derivatives)
    point = (point * CM_PER_M).reshape(b, n_poses, 3)  # the loss is in cm
    direction = direction.reshape(b, n_poses, 3)
    e_point = point - problem.goal_points_cm
    e_dir = direction - problem.goal_directions
    e_start = poses[:, 0] - problem.start_pose
    e_end = poses[:, -1] - problem.end_pose
    steps = poses.diff(dim=1)
    terms = torch.stack([
        (e_point**2).mean(dim=(1, 2)),
        (1.0 - (direction * problem.goal_directions).sum(-1)).mean(dim=1),
        (e_start**2).sum(dim=1), (e_end**2).sum(dim=1),
        (e_point[:, 0] ** 2).sum(dim=1), (e_point[:, -1] ** 2).sum(dim=1),
        (steps**2).mean(dim=(1, 2)),
    ], dim=1)
    loss = (terms * problem.weights).sum(dim=1)
    if not derivatives:
        return TorchEvaluation(loss, terms)
    a0, a1, a2, a3, a4, a5, a6 = problem.residual_weights()
    w_point = a0[:, None].repeat(1, n_poses)
    w_point[:, 0] += a4
    w_point[:, -1] += a5
    diagonal, gradient = gauss_newton_blocks(
        (w_point, (j_point * CM_PER_M).reshape(b, n_poses, 3, dof), e_point),
        (a1[:, None], j_dir.reshape(b, n_poses, 3, dof), e_dir), a6, steps,
        (a2, e_start, a3, e_end))
    return TorchEvaluation(loss, terms, gradient, diagonal, a6)


def solve_normal_equations(diagonal: torch.Tensor, coupling: torch.Tensor, rhs: torch.Tensor,
                           free: torch.Tensor, method: str = "cyclic"
                           ) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`.linalg.solve_normal_equations` (the same system, the same masking of the
    variables that are not free), batched on the device.

    Args:
        method: ``"cyclic"`` (block cyclic reduction: log2(N) rounds, each on all blocks of
            the round at once, so few kernel launches) or ``"thomas"`` (block Cholesky-Thomas:
            N sequential steps, as the numpy fallback).

    Returns:
        (steps (B, N, k), ok (B,) bool: False where the matrix was not positive definite).
    """
    f = free.to(rhs.dtype)
    diag = diagonal * f[..., :, None] * f[..., None, :]
    diag.diagonal(dim1=-2, dim2=-1).add_(1.0 - f)
    off = coupling[:, None, None] * f[:, :-1] * f[:, 1:]          # (B, N-1, k), sign: -off
    rhs = rhs * f
    if method == "thomas":
        x, ok = _thomas(diag, off, rhs)
    else:
        lower = torch.diag_embed(-off)                            # A[i+1, i] (B, N-1, k, k)
        x, ok = _cyclic_reduction(diag, lower, rhs)
    return torch.where(ok[:, None, None], x, 0.0), ok


def _cyclic_reduction(diag, lower, rhs):
    """Block cyclic reduction of the symmetric block-tridiagonal system with diagonal blocks
    ``diag`` (B, n, k, k), sub-diagonal blocks ``lower`` (B, n-1, k, k) (A[i+1, i]) and
    right-hand side (B, n, k): eliminate the odd blocks, solve the even ones the same way,
    substitute back. Returns (x (B, n, k), ok (B,))."""
    n, k = diag.shape[1], diag.shape[-1]
    factor, info = torch.linalg.cholesky_ex(diag[:, 1::2] if n > 1 else diag)
    ok = (info == 0).all(dim=1)
    eye = torch.eye(k, dtype=diag.dtype, device=diag.device)
    factor = torch.where(ok[:, None, None, None], factor, eye)
    if n == 1:
        return torch.cholesky_solve(rhs[..., None], factor)[..., 0], ok
    odd = factor.shape[1]
    la, lb = lower[:, 0::2], lower[:, 1::2]                       # A[2m+1, 2m], A[2m+2, 2m+1]
    nb = lb.shape[1]
    # W = D_odd^-1 applied to [La | Lb^T | b]: one solve per round
    solved = torch.cholesky_solve(torch.cat([
        la, torch.nn.functional.pad(lb.transpose(-1, -2), (0, 0, 0, 0, 0, odd - nb)),
        rhs[:, 1::2, :, None]], dim=-1), factor)
    p, r, w = solved[..., :k], solved[..., k:2 * k][:, :nb], solved[..., 2 * k]
    d_even, b_even = diag[:, 0::2].clone(), rhs[:, 0::2].clone()
    la_t = la.transpose(-1, -2)
    d_even[:, :odd] -= la_t @ p
    b_even[:, :odd] -= (la_t @ w[..., None])[..., 0]
    d_even[:, 1:nb + 1] -= lb @ r
    b_even[:, 1:nb + 1] -= (lb @ w[:, :nb, :, None])[..., 0]
    x_even, ok_even = _cyclic_reduction(d_even, -(lb @ p[:, :nb]), b_even)
    x_odd = w - (p @ x_even[:, :odd, :, None])[..., 0]
    x_odd[:, :nb] -= (r @ x_even[:, 1:nb + 1, :, None])[..., 0]
    x = torch.empty_like(rhs)
    x[:, 0::2], x[:, 1::2] = x_even, x_odd
    return x, ok & ok_even


def _thomas(diag, off, rhs):
    """Block Cholesky-Thomas elimination: one sweep down the N blocks, one back."""
    b, n_poses, k = rhs.shape
    eye = torch.eye(k, dtype=rhs.dtype, device=rhs.device)
    inverses = torch.empty_like(diag)
    y = torch.empty_like(rhs)
    ok = torch.ones(b, dtype=torch.bool, device=rhs.device)
    schur, y_i = diag[:, 0], rhs[:, 0]
    for i in range(n_poses):
        if i:
            c = off[:, i - 1]                                        # C = -diag(c)
            previous = inverses[:, i - 1]
            schur = diag[:, i] - c[:, :, None] * previous * c[:, None, :]
            y_i = rhs[:, i] + c * (previous @ y[:, i - 1, :, None])[..., 0]
        factor, info = torch.linalg.cholesky_ex(schur)
        ok &= info == 0
        inverses[:, i] = torch.cholesky_inverse(torch.where(ok[:, None, None], factor, eye))
        y[:, i] = y_i
    x = torch.empty_like(rhs)
    x[:, -1] = (inverses[:, -1] @ y[:, -1, :, None])[..., 0]
    for i in range(n_poses - 2, -1, -1):
        x[:, i] = (inverses[:, i] @ (y[:, i] + off[:, i] * x[:, i + 1])[..., None])[..., 0]
    return x, ok


def _free_variables(problem: TorchProblem, poses, gradient):
    """False for variables on a bound whose descent direction (-gradient) leaves the box."""
    at_lower = poses <= problem.lower_deg + BOUND_EPS_DEG
    at_upper = poses >= problem.upper_deg - BOUND_EPS_DEG
    return ~((at_lower & (gradient > 0)) | (at_upper & (gradient < 0)))


def _stationary(ev: TorchEvaluation, poses, problem: TorchProblem, rtol: float = 1e-6):
    """True where the projected gradient is negligible (no descent direction is left)."""
    g = torch.where(_free_variables(problem, poses, ev.gradient), ev.gradient, 0.0)
    return g.abs().amax(dim=(1, 2)) <= rtol * ev.loss.clamp_min(1.0)


def stopping_tolerance(settings: LMSettings) -> float:
    """The tolerance of the stopping rule in the working precision (module docstring)."""
    if settings.dtype == "float32":
        return max(settings.tolerance, FLOAT32_TOLERANCE)
    return settings.tolerance


def solve_batch(robot: Robot, tasks: Sequence[Task], settings: LMSettings,
                weights: Weights | None = None, initial: npt.ArrayLike | None = None,
                progress: LMProgress | None = None) -> TorchBatchResult:
    """:func:`~.solver.solve_batch` on ``settings.device`` in ``settings.dtype``.

    Args:
        robot: the robot.
        tasks: tasks of equal length n.
        settings: solver settings; ``device`` names the torch device.
        weights: one weights dict for all tasks or one per task (default ``settings.weights``).
        initial: initial poses (B, N, dof) [motor deg] (default: the joint interpolation).
        progress: optional callable ``(iteration, n_active, losses)`` called every iteration.

    Returns:
        A :class:`TorchBatchResult` (numpy arrays, float64 losses of the returned poses).
    """
    start = time.perf_counter()
    if weights is None:
        weights = [resolve_weights(settings.weights, task) for task in tasks]
    problem = Problem.from_tasks(robot, tasks, weights)
    poses = initial_poses_batched(robot, tasks) if initial is None else initial
    result = solve_problem(robot, problem, poses, settings, progress)
    result.duration_s = time.perf_counter() - start
    return result


def solve_problem(robot: Robot, problem: Problem, initial: npt.ArrayLike, settings: LMSettings,
                  progress: LMProgress | None = None) -> TorchBatchResult:
    """Minimise ``problem`` from ``initial`` (B, N, dof) [motor deg] on ``settings.device``.

    Returns:
        A :class:`TorchBatchResult`; every pose lies within the motor ranges.
    """
    start = time.perf_counter()
    device, dtype = torch.device(settings.device or "cpu"), torch_dtype(settings.dtype)
    kin = torch_chain_kinematics(robot, dtype, device)
    tp = TorchProblem.of(problem, dtype, device)
    poses = torch.as_tensor(np.asarray(initial, dtype=float), device=device).to(dtype)
    poses = poses.clamp(tp.lower_deg, tp.upper_deg)
    with torch.no_grad():
        loop_start = time.perf_counter()
        poses, iterations, converged, final = _iterate(kin, tp, poses, settings, progress)
        if dtype != torch.float64:
            final = _float64_evaluation(robot, tp, poses)
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        loop_s = time.perf_counter() - loop_start
        out = (poses.to(torch.float64).cpu().numpy(), final.loss.cpu().numpy(),
               final.terms.cpu().numpy(), iterations.cpu().numpy(), converged.cpu().numpy())
    return TorchBatchResult(*out, duration_s=time.perf_counter() - start, loop_s=loop_s,
                            device=str(device), dtype=settings.dtype)


def _float64_evaluation(robot, tp: TorchProblem, poses) -> TorchEvaluation:
    """Loss and terms of poses in float64 (the final ones of a float32 solve)."""
    kin64 = torch_chain_kinematics(robot, torch.float64, poses.device)
    tp64 = TorchProblem(*(getattr(tp, f.name).to(torch.float64) for f in fields(tp)))
    return evaluate(kin64, tp64, poses.to(torch.float64), derivatives=False)


def _iterate(kin, problem: TorchProblem, poses, settings: LMSettings, progress):
    """The LM loop of :func:`~.solver.solve_batch`.

    Returns:
        (poses, iterations, converged, evaluation at the poses), tensors over the batch.
    """
    b, device, dtype = poses.shape[0], poses.device, poses.dtype
    tolerance = stopping_tolerance(settings)
    low_precision = dtype != torch.float64
    current = evaluate(kin, problem, poses)
    damping = torch.full((b,), settings.damping, dtype=dtype, device=device)
    nu = torch.full((b,), 2.0, dtype=dtype, device=device)
    iterations = torch.zeros(b, dtype=torch.long, device=device)
    converged = torch.zeros(b, dtype=torch.bool, device=device)
    active = torch.arange(b, device=device)
    index = None                      # None while every trajectory is active: no gathers
    while True:
        sub, ev = problem.take(index), current.take(index)
        x = poses if index is None else poses[index]
        free = _free_variables(sub, x, ev.gradient)
        scale = ev.diagonal.diagonal(dim1=-2, dim2=-1).clamp_min(1e-12)
        damped = ev.diagonal.clone()
        damped.diagonal(dim1=-2, dim2=-1).add_(damping[active, None, None] * scale)
        method = ("cyclic" if x.shape[0] <= CYCLIC_MAX_BATCH and settings.linear_solver
                  != "thomas" else "thomas")
        step, ok = solve_normal_equations(damped, ev.coupling, -ev.gradient, free, method)
        trial = torch.clamp(x + step, sub.lower_deg, sub.upper_deg)
        step = trial - x
        predicted = -(2.0 * (ev.gradient * step).sum(dim=(1, 2))
                      + (step * block_matvec(ev, step)).sum(dim=(1, 2)))
        new = evaluate(kin, sub, trial)
        gain = (ev.loss - new.loss) / torch.where(predicted > 0, predicted, torch.inf)
        accept = ok & (predicted > 0) & (gain > MIN_GAIN_RATIO)
        decrease = ev.loss - new.loss
        small = accept & ((decrease <= tolerance * new.loss)
                          | (step.abs().amax(dim=(1, 2)) <= tolerance))
        if low_precision:  # the model predicts a change the loss cannot resolve: stop
            small |= ok & (predicted > 0) & (predicted <= tolerance * ev.loss)
        stationary = _stationary(ev, x, sub)
        # the state is written only now: while all are active, ev and x are the state itself
        iterations[active] += 1
        poses[active] = torch.where(accept[:, None, None], trial, x)
        _put(current, active, ev, new, accept)
        factor = torch.clamp_min(1.0 - (2.0 * gain - 1.0) ** 3, 1.0 / 3.0)
        damping[active] = torch.where(accept, damping[active] * factor,
                                      damping[active] * nu[active])
        nu[active] = torch.where(accept, 2.0, nu[active] * 2.0)
        stuck = damping[active] > MAX_DAMPING
        converged[active] = small | (stuck & stationary)
        done = small | stuck | (iterations[active] >= settings.max_iterations)
        if progress:
            progress(int(iterations.max()), int(active.numel()), current.loss.cpu().numpy())
        active = active[~done]        # the one host synchronisation of the iteration
        if not active.numel():
            return poses, iterations, converged, current
        index = active


def _put(current: TorchEvaluation, active, old: TorchEvaluation, new: TorchEvaluation,
         accept) -> None:
    """Store ``new`` where a step was accepted, ``old`` elsewhere, at rows ``active``."""
    for name in ("loss", "terms", "gradient", "diagonal", "coupling"):
        a, b = getattr(new, name), getattr(old, name)
        mask = accept.reshape(-1, *([1] * (a.dim() - 1)))
        getattr(current, name)[active] = torch.where(mask, a, b)
