"""The numba backend of ours-lm: the whole LM loop compiled, one trajectory per thread task.

The numpy solver (:mod:`.solver`) stays the reference; this is the same method step for step
on the paper's objective (:mod:`.problem`): the vectorised chain's FK and analytic Jacobians
(:mod:`ikbench.core.kinematics.chain`, the same formulas written per pose), the residuals and
the block-tridiagonal Gauss-Newton blocks, the active set on the joint limits, the Marquardt
damping diag(J^T J) with Nielsen's update, a banded Cholesky of the damped normal equations
(the algorithm of LAPACK ``dpbtrf``/``dpbtrs`` that the numpy solver calls, written out), step
clipping, the gain test and the stopping rule. The numpy solver iterates on all running
trajectories at once; every trajectory's iteration only reads its own data, so running each
trajectory's loop to its end on its own is the same algorithm. Results equal the numpy
solver's up to rounding (final losses within ~1e-14 relative measured; tested to 1e-6).

Speed (one LM iteration of one trajectory of 51 poses, 7 joints: ~35 us of one core, against
~370 us in the numpy solver at a batch of 1 000): the loops over the joints have the joint
count as a compile-time constant (the length of the tuple ``kt``: one compiled version per
chain length), the rotation is kept in scalars, sine and cosine come from fdlibm's kernels
without branches (:func:`.compiled_chain.sin_cos`, within 1 ulp; libm's calls were most of
the chain's time), and only accepted steps build the Gauss-Newton blocks. The chain's
constants (:class:`.compiled_chain.Chain`) and the sine are shared with the single-pose IK.

Threads: the trajectories are dealt round-robin to numba threads (``prange``): at most
``threads``, one per :data:`PER_THREAD` trajectories (:func:`thread_count`); a batch that
gets one thread runs in the calling thread. The kernels release the GIL. numba is an optional
dependency (the ``[fast]`` extra); :mod:`.solver` imports this module only when the backend
runs. The first use compiles the kernels (~20-25 s per chain length on a 2-core EPYC); numba
caches them (``__pycache__``), so later processes load them in about a second.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numba
import numpy as np
from numba import njit, prange

from ikbench.core.losses import PAPER_WEIGHTS
from ikbench.core.task import Goal, Requirements, Task
from ikbench.methods.ours_lm.compiled_chain import Chain, joint_step, sin_cos
from ikbench.methods.ours_lm.compiling import say_if_compiling
from ikbench.methods.ours_lm.problem import CM_PER_M, Problem, Weights
from ikbench.methods.ours_lm.settings import (
    BOUND_EPS_DEG,
    MAX_DAMPING,
    MIN_GAIN_RATIO,
    BatchResult,
    initial_poses_batched,
)

if TYPE_CHECKING:
    import numpy.typing as npt

    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.methods.ours_lm.settings import LMSettings

#: A batch gets a second (third, ...) thread for every this many trajectories.
PER_THREAD = 16
#: The chain's sine and cosine (:func:`.compiled_chain.sin_cos`), by its older name here.
_sin_cos = sin_cos


def solve_batch(robot: Robot, tasks: Sequence[Task], settings: LMSettings, weights: Weights,
                initial: npt.ArrayLike | None = None) -> BatchResult:
    """:func:`.solver.solve_batch` of the paper's objective, compiled (same arguments)."""
    start = time.perf_counter()
    problem = Problem.from_tasks(robot, tasks, weights)
    poses = (initial_poses_batched(robot, tasks) if initial is None
             else np.array(initial, dtype=float))
    result = solve(robot, problem, poses, settings)
    result.duration_s = time.perf_counter() - start
    return result


def solve(robot: Robot, problem: Problem, poses: npt.ArrayLike, settings: LMSettings
          ) -> BatchResult:
    """:func:`solve_problem` with the solver settings (``poses`` are clipped to the box)."""
    start = time.perf_counter()
    poses = np.ascontiguousarray(np.clip(poses, problem.lower_deg, problem.upper_deg),
                                 dtype=float)
    poses, loss, terms, iterations, converged = solve_problem(
        Chain(robot), problem, poses, settings.max_iterations, settings.tolerance,
        settings.damping, settings.threads)
    return BatchResult(poses, loss, terms, iterations, converged,
                       time.perf_counter() - start)


def max_threads() -> int:
    """The most threads numba runs (``NUMBA_NUM_THREADS``, by default the cores)."""
    return int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]


def solve_problem(chain: Chain, problem: Problem, poses: np.ndarray, max_iterations: int,
                  tolerance: float, damping: float, threads: int | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(poses (B, N, k), loss (B,), terms (B, 7), iterations (B,), converged (B,)) from
    initial ``poses`` (B, N, k) within the limits, on ``threads`` threads (None: all)."""
    b = poses.shape[0]
    f64 = np.ascontiguousarray
    loss = np.empty(b)
    terms = np.empty((b, 7))
    iterations = np.zeros(b, dtype=np.int64)
    converged = np.zeros(b, dtype=np.bool_)
    count = thread_count(b, threads)
    args = (f64(problem.goal_points_cm, dtype=float), f64(problem.goal_directions, dtype=float),
            f64(problem.start_pose, dtype=float), f64(problem.end_pose, dtype=float),
            f64(problem.weights, dtype=float), f64(problem.lower_deg, dtype=float),
            f64(problem.upper_deg, dtype=float), chain.arrays(), poses, loss, terms,
            iterations, converged, int(max_iterations), float(tolerance), float(damping))
    kt = (0,) * poses.shape[2]
    if count == 1:  # in this thread: no hand-off to numba's workers
        _solve_serial(*args, kt)  # type: ignore[call-arg]
        return poses, loss, terms, iterations, converged
    previous = numba.get_num_threads()
    numba.set_num_threads(count)
    try:
        _solve_all(*args, count, kt)  # type: ignore[call-arg]
    finally:
        numba.set_num_threads(previous)
    return poses, loss, terms, iterations, converged


def thread_count(batch: int, threads: int | None = None) -> int:
    """Threads a batch is solved on: at most ``threads`` (None: all), and one more only per
    :data:`PER_THREAD` trajectories (below that, waking a second thread on a busy machine
    cost more than it saved: the paper's seven took a median 2.4 ms on one thread and 9.7 ms
    on two, under a load of 4 on 2 cores)."""
    limit = min(threads or max_threads(), max_threads())
    return max(1, min(limit, batch // PER_THREAD))


def forward(robot: Robot, poses: npt.ArrayLike, threads: int | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
    """End points [m] (M, 3) and pointing directions (M, 3) of poses (M, dof) [pose units]:
    the chain's FK compiled (as :class:`ikbench.core.kinematics.chain.ChainKinematics`)."""
    poses = np.ascontiguousarray(poses, dtype=float).reshape(-1, robot.dof)
    point_cm, direction = np.empty((len(poses), 3)), np.empty((len(poses), 3))
    count = max(1, min(threads or max_threads(), max_threads()))
    previous = numba.get_num_threads()
    numba.set_num_threads(count)
    try:
        _forward_all(poses, Chain(robot).arrays(), point_cm, direction, count,
                     (0,) * robot.dof)  # type: ignore[call-arg]
    finally:
        numba.set_num_threads(previous)
    return point_cm / CM_PER_M, direction


def warm_up(robot: Robot) -> None:
    """Compile (or load from numba's cache) the kernels outside any timed region."""
    say_if_compiling(sys.modules[__name__])
    k = robot.dof
    pose = np.clip(np.zeros(k), robot.lower, robot.upper)
    goal = np.zeros((3, 3))
    direction = np.tile([1.0, 0.0, 0.0], (3, 1))
    task = Task("warm-up", Goal(goal, direction), Requirements(pose, pose))
    chain, b = Chain(robot), 2 * PER_THREAD
    problem = Problem.from_tasks(robot, [task] * b, dict(PAPER_WEIGHTS))
    for threads in (1, 2):  # the serial and the parallel kernel
        solve_problem(chain, problem, np.tile(pose, (b, 3, 1)).astype(float), 1, 1e-9, 1e-3,
                      threads)
    forward(robot, pose[None])


@njit(cache=True, parallel=True, nogil=True)
def _solve_all(goal, gdir, start, end, weights, lower, upper, chain, poses, loss, terms,
               iterations, converged, max_iterations, tolerance, damping, threads, kt):
    b, n = poses.shape[0], poses.shape[1]
    k = len(kt)
    for t in prange(threads):
        ws = _Workspace(n, k)
        for m in range(t, b, threads):
            loss[m], iterations[m], converged[m] = _solve_one(
                goal[m], gdir[m], start[m], end[m], weights[m], lower, upper, chain, poses[m],
                terms[m], max_iterations, tolerance, damping, ws, kt)


@njit(cache=True, nogil=True)
def _solve_serial(goal, gdir, start, end, weights, lower, upper, chain, poses, loss, terms,
                  iterations, converged, max_iterations, tolerance, damping, kt):
    ws = _Workspace(poses.shape[1], len(kt))
    for m in range(poses.shape[0]):
        loss[m], iterations[m], converged[m] = _solve_one(
            goal[m], gdir[m], start[m], end[m], weights[m], lower, upper, chain, poses[m],
            terms[m], max_iterations, tolerance, damping, ws, kt)


@njit(cache=True, parallel=True, nogil=True)
def _forward_all(poses, chain, point, direc, threads, kt):
    m = poses.shape[0]
    k = len(kt)
    size = (m + threads - 1) // threads
    for t in prange(threads):
        lo, hi = t * size, min(m, (t + 1) * size)
        if lo < hi:
            none = np.empty((0, 3, k))
            _kinematics(poses[lo:hi], chain, point[lo:hi], direc[lo:hi], none, none,
                        np.empty((k, 3)), np.empty((k, 3)), kt, False)


@njit(cache=True)
def _Workspace(n, k):
    """Scratch arrays of one thread (a tuple, reused for its trajectories)."""
    return (np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3, k)), np.empty((n, 3, k)),
            np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3, k)), np.empty((n, 3, k)),
            np.empty((n, k)), np.empty((n, k, k)), np.empty((n, k)), np.empty((n, k)),
            np.empty((n * k, k + 1)), np.empty(n * k), np.empty(7), np.empty((k, 3)),
            np.empty((k, 3)), np.empty((n, k)))


@njit(cache=True)
def _solve_one(goal, gdir, start, end, c, lower, upper, chain, x, terms, max_iterations,
               tolerance, lam, ws, kt):
    """The LM loop of one trajectory (poses ``x`` (N, k) updated in place; ``terms`` (7,)
    written); returns (loss, iterations, converged)."""
    (point, direc, jp, jd, tpoint, tdirec, tjp, tjd, grad, diag, trial, step, band, rhs,
     tterms, w_axes, origins, free) = ws
    n = x.shape[0]
    k = len(kt)
    a = _residual_weights(c, n, k)
    _kinematics(x, chain, point, direc, jp, jd, w_axes, origins, kt)
    loss = _loss(x, point, direc, goal, gdir, start, end, c, terms, kt)
    _blocks(x, point, direc, jp, jd, goal, gdir, start, end, a, grad, diag, kt)
    nu = 2.0
    iterations = 0
    converged = False
    while True:
        ok, largest, predicted = _damped_trial(x, grad, diag, a[6], lower, upper, free, lam,
                                               band, rhs, step, trial, kt)
        _kinematics(trial, chain, tpoint, tdirec, tjp, tjd, w_axes, origins, kt)
        new_loss = _loss(trial, tpoint, tdirec, goal, gdir, start, end, c, tterms, kt)
        iterations += 1
        lam, nu, accept, small, stuck, converged = _damping_update(
            ok, predicted, loss, new_loss, largest, tolerance, lam, nu, grad, free, kt)
        if accept:
            x[:, :] = trial
            point, tpoint = tpoint, point
            direc, tdirec = tdirec, direc
            jp, tjp = tjp, jp
            jd, tjd = tjd, jd
            terms[:] = tterms
            loss = new_loss
            _blocks(x, point, direc, jp, jd, goal, gdir, start, end, a, grad, diag, kt)
        if small or stuck or iterations >= max_iterations:
            return loss, iterations, converged


@njit(cache=True)
def _residual_weights(c, n, k):
    """a0^2 .. a6^2 of :meth:`.problem.Problem.residual_weights`."""
    return np.array([c[0] / (3 * n), c[1] / (2 * n), c[2], c[3], c[4], c[5],
                     c[6] / ((n - 1) * k)])


@njit(cache=True)
def _kinematics(x, chain, point, direc, jp, jd, w_axes, origins, kt, derivatives=True):
    """End point [cm], direction and (``derivatives``) their Jacobians per pose unit for
    poses x (N, k); ``chain``: :meth:`Chain.arrays`."""
    _, _, _, _, _, prismatic, per_unit, mscale, moffset, msi, tip_t, tip_axis = chain
    n = x.shape[0]
    k = len(kt)
    sines, versines = np.empty((n, k)), np.empty((n, k))
    for i in range(n):  # all angles first (a branch-free loop)
        for j in range(k):
            sines[i, j], cosine = sin_cos((x[i, j] * mscale[j] + moffset[j]) * msi[j])
            versines[i, j] = 1.0 - cosine
    for i in range(n):  # the rotation (a..i, row-major) and position in scalars: registers
        a, b, c, d, e, f, g, h, o = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
        p0 = p1 = p2 = 0.0
        for j in range(k):
            (a, b, c, d, e, f, g, h, o, p0, p1, p2, w0, w1, w2) = joint_step(
                chain, j, (x[i, j] * mscale[j] + moffset[j]) * msi[j], sines[i, j],
                versines[i, j], a, b, c, d, e, f, g, h, o, p0, p1, p2)
            w_axes[j, 0], w_axes[j, 1], w_axes[j, 2] = w0, w1, w2
            origins[j, 0], origins[j, 1], origins[j, 2] = p0, p1, p2
        t0, t1, t2 = tip_t[0], tip_t[1], tip_t[2]
        point[i, 0] = p0 + a * t0 + b * t1 + c * t2
        point[i, 1] = p1 + d * t0 + e * t1 + f * t2
        point[i, 2] = p2 + g * t0 + h * t1 + o * t2
        t0, t1, t2 = tip_axis[0], tip_axis[1], tip_axis[2]
        direc[i, 0] = a * t0 + b * t1 + c * t2
        direc[i, 1] = d * t0 + e * t1 + f * t2
        direc[i, 2] = g * t0 + h * t1 + o * t2
        for j in range(k if derivatives else 0):
            w0, w1, w2 = w_axes[j, 0], w_axes[j, 1], w_axes[j, 2]
            s = per_unit[j]
            if prismatic[j]:
                jp[i, 0, j], jp[i, 1, j], jp[i, 2, j] = w0 * s * CM_PER_M, w1 * s * CM_PER_M, \
                    w2 * s * CM_PER_M
                jd[i, 0, j] = jd[i, 1, j] = jd[i, 2, j] = 0.0
            else:
                d0 = point[i, 0] - origins[j, 0]
                d1 = point[i, 1] - origins[j, 1]
                d2 = point[i, 2] - origins[j, 2]
                jp[i, 0, j] = (w1 * d2 - w2 * d1) * s * CM_PER_M
                jp[i, 1, j] = (w2 * d0 - w0 * d2) * s * CM_PER_M
                jp[i, 2, j] = (w0 * d1 - w1 * d0) * s * CM_PER_M
                v0, v1, v2 = direc[i, 0], direc[i, 1], direc[i, 2]
                jd[i, 0, j] = (w1 * v2 - w2 * v1) * s
                jd[i, 1, j] = (w2 * v0 - w0 * v2) * s
                jd[i, 2, j] = (w0 * v1 - w1 * v0) * s
        for r in range(3):
            point[i, r] *= CM_PER_M


@njit(cache=True)
def _loss(x, point, direc, goal, gdir, start, end, c, terms, kt):
    """The terms L0..L6 (written to ``terms``) and the weighted loss at poses x (N, k)."""
    n = x.shape[0]
    k = len(kt)
    sq_point = sq_dir = sq_steps = 0.0
    for i in range(n):
        dot = 0.0
        for r in range(3):
            e = point[i, r] - goal[i, r]
            sq_point += e * e
            dot += direc[i, r] * gdir[i, r]
        sq_dir += 1.0 - dot
    first = last = e_start = e_end = 0.0
    for r in range(3):
        first += (point[0, r] - goal[0, r]) ** 2
        last += (point[n - 1, r] - goal[n - 1, r]) ** 2
    for j in range(k):
        e_start += (x[0, j] - start[j]) ** 2
        e_end += (x[n - 1, j] - end[j]) ** 2
        for i in range(n - 1):
            sq_steps += (x[i + 1, j] - x[i, j]) ** 2
    terms[0] = sq_point / (3 * n)
    terms[1] = sq_dir / n
    terms[2] = e_start
    terms[3] = e_end
    terms[4] = first
    terms[5] = last
    terms[6] = sq_steps / ((n - 1) * k)
    total = 0.0
    for t in range(7):
        total += terms[t] * c[t]
    return total


@njit(cache=True)
def _blocks(x, point, direc, jp, jd, goal, gdir, start, end, a, grad, diag, kt):
    """Gradient J^T r (N, k) and the diagonal blocks of J^T J (N, k, k) at poses x."""
    n = x.shape[0]
    k = len(kt)
    for i in range(n):
        wp = a[0] + (a[4] if i == 0 else 0.0) + (a[5] if i == n - 1 else 0.0)
        e0, e1, e2 = point[i, 0] - goal[i, 0], point[i, 1] - goal[i, 1], point[i, 2] - goal[i, 2]
        f0, f1, f2 = direc[i, 0] - gdir[i, 0], direc[i, 1] - gdir[i, 1], direc[i, 2] - gdir[i, 2]
        for p in range(k):
            grad[i, p] = (wp * (jp[i, 0, p] * e0 + jp[i, 1, p] * e1 + jp[i, 2, p] * e2)
                          + a[1] * (jd[i, 0, p] * f0 + jd[i, 1, p] * f1 + jd[i, 2, p] * f2))
            for q in range(p + 1):
                v = (wp * (jp[i, 0, p] * jp[i, 0, q] + jp[i, 1, p] * jp[i, 1, q]
                           + jp[i, 2, p] * jp[i, 2, q])
                     + a[1] * (jd[i, 0, p] * jd[i, 0, q] + jd[i, 1, p] * jd[i, 1, q]
                               + jd[i, 2, p] * jd[i, 2, q]))
                diag[i, p, q] = v
                diag[i, q, p] = v
        degree = 1.0 if i == 0 or i == n - 1 else 2.0
        for p in range(k):
            diag[i, p, p] += a[6] * degree
    for p in range(k):
        grad[0, p] += a[2] * (x[0, p] - start[p])
        grad[n - 1, p] += a[3] * (x[n - 1, p] - end[p])
        diag[0, p, p] += a[2]
        diag[n - 1, p, p] += a[3]
        for i in range(n - 1):
            s = a[6] * (x[i + 1, p] - x[i, p])
            grad[i, p] -= s
            grad[i + 1, p] += s


@njit(cache=True)
def _free_variables(x, grad, lower, upper, free, kt):
    """``free`` (N, k): 0.0 for variables on a bound whose descent direction (-gradient)
    leaves the box, else 1.0."""
    n = x.shape[0]
    k = len(kt)
    for i in range(n):
        for j in range(k):
            at_lower = x[i, j] <= lower[j] + BOUND_EPS_DEG
            at_upper = x[i, j] >= upper[j] - BOUND_EPS_DEG
            held = (at_lower and grad[i, j] > 0) or (at_upper and grad[i, j] < 0)
            free[i, j] = 0.0 if held else 1.0


@njit(cache=True)
def _solve_damped(diag, coupling, grad, free, lam, band, rhs, step, kt):
    """Step (N, k) of the damped system (held variables: identity rows, step 0) by banded
    Cholesky (lower band storage ``band[r, d] = A[r + d, r]``); False if not positive
    definite (the step is then 0)."""
    n = grad.shape[0]
    k = len(kt)
    size = n * k
    for i in range(n):
        for p in range(k):
            r = i * k + p
            fp = free[i, p]
            for d in range(k - p):
                band[r, d] = diag[i, p + d, p] * fp * free[i, p + d]
            for d in range(k - p, k):
                band[r, d] = 0.0
            scale = max(diag[i, p, p], 1e-12)
            band[r, 0] += (lam * scale) * fp * fp + (1.0 - fp)
            band[r, k] = -(coupling * fp * free[i + 1, p]) if i < n - 1 else 0.0
            rhs[r] = -grad[i, p] * fp
    # A = L L^T in place, column by column as LAPACK's dpbtf2 (column j of L in band[j]);
    # the columns before the last k with the full (compile-time) bandwidth k
    full = size - k
    for j in range(size):
        ajj = band[j, 0]
        if not ajj > 0.0:
            step[:, :] = 0.0
            return False
        ajj = math.sqrt(ajj)
        band[j, 0] = ajj
        inv = 1.0 / ajj
        if j < full:
            for d in range(1, k + 1):
                band[j, d] *= inv
            for q in range(1, k + 1):  # the trailing block -= v v^T
                vq = band[j, q]
                for p in range(q, k + 1):
                    band[j + q, p - q] -= band[j, p] * vq
        else:
            kn = size - 1 - j
            for d in range(1, kn + 1):
                band[j, d] *= inv
            for q in range(1, kn + 1):
                vq = band[j, q]
                for p in range(q, kn + 1):
                    band[j + q, p - q] -= band[j, p] * vq
    for j in range(size):  # L y = b
        y = rhs[j] / band[j, 0]
        rhs[j] = y
        if j < full:
            for d in range(1, k + 1):
                rhs[j + d] -= band[j, d] * y
        else:
            for d in range(1, size - j):
                rhs[j + d] -= band[j, d] * y
    for j in range(size - 1, -1, -1):  # L^T x = y
        s = rhs[j]
        if j < full:
            for d in range(1, k + 1):
                s -= band[j, d] * rhs[j + d]
        else:
            for d in range(1, size - j):
                s -= band[j, d] * rhs[j + d]
        rhs[j] = s / band[j, 0]
    for i in range(n):
        for p in range(k):
            step[i, p] = rhs[i * k + p]
    return True


@njit(cache=True)
def _dot(a, b, kt):
    n = a.shape[0]
    k = len(kt)
    total = 0.0
    for i in range(n):
        for j in range(k):
            total += a[i, j] * b[i, j]
    return total


@njit(cache=True)
def _quadratic(diag, coupling, s, kt):
    """s^T (J^T J) s with the undamped blocks."""
    n = s.shape[0]
    k = len(kt)
    total = 0.0
    for i in range(n):
        for p in range(k):
            row = 0.0
            for q in range(k):
                row += diag[i, p, q] * s[i, q]
            if i > 0:
                row -= coupling * s[i - 1, p]
            if i < n - 1:
                row -= coupling * s[i + 1, p]
            total += s[i, p] * row
    return total


@njit(cache=True)
def _stationary(grad, free, loss, kt):
    """True where the projected gradient is negligible (no descent direction is left)."""
    n = grad.shape[0]
    k = len(kt)
    largest = 0.0
    for i in range(n):
        for j in range(k):
            if free[i, j] > 0.0:
                largest = max(largest, abs(grad[i, j]))
    return largest <= 1e-6 * max(loss, 1.0)


@njit(cache=True)
def _damped_trial(x, grad, diag, coupling, lower, upper, free, lam, band, rhs, step, trial, kt):
    """One damped LM step from poses x (N, k), clipped into the joint limits: ``trial`` gets
    the poses, ``step`` the clipped step; returns (the damped system solved, largest |step|,
    the decrease of the loss the step predicts). Shared by :func:`_solve_one` and the path
    solver in :mod:`.compiled_paths`."""
    n = x.shape[0]
    k = len(kt)
    _free_variables(x, grad, lower, upper, free, kt)
    ok = _solve_damped(diag, coupling, grad, free, lam, band, rhs, step, kt)
    largest = 0.0
    for i in range(n):
        for j in range(k):
            v = min(max(x[i, j] + step[i, j], lower[j]), upper[j])
            trial[i, j] = v
            step[i, j] = v - x[i, j]
            largest = max(largest, abs(step[i, j]))
    predicted = -(2.0 * _dot(grad, step, kt) + _quadratic(diag, coupling, step, kt))
    return ok, largest, predicted


@njit(cache=True)
def _damping_update(ok, predicted, loss, new_loss, largest, tolerance, lam, nu, grad, free,
                    kt):
    """The gain test of one trial step, Nielsen's damping update and the stop test: (lam, nu,
    accept, small, stuck, converged); ``small``: an accepted step that barely changed the loss
    or the poses, ``stuck``: the damping above MAX_DAMPING (converged where no descent is
    left). Shared by :func:`_solve_one` and the path solver in :mod:`.compiled_paths`."""
    gain = (loss - new_loss) / predicted if predicted > 0 else 0.0
    accept = ok and predicted > 0 and gain > MIN_GAIN_RATIO
    if accept:
        lam *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
        nu = 2.0
    else:
        lam *= nu
        nu *= 2.0
    decrease = loss - new_loss
    small = accept and (decrease <= tolerance * new_loss or largest <= tolerance)
    stuck = lam > MAX_DAMPING
    converged = small
    if not small and stuck:
        converged = _stationary(grad, free, loss, kt)
    return lam, nu, accept, small, stuck, converged
