"""The numba kernels of the compiled single-pose IK (:mod:`.single_pose_compiled` says what
they compute and how they are called).

``spec`` is the packed problem, (k + 2, :data:`.compiled_chain.WIDTH`): the chain and its
limits (:func:`.compiled_chain.pack`, rows 0..k) and the settings row (k + 1, columns
:data:`TOL_MM` ...). One thread's scratch is the tuple of :func:`workspace`, allocated once
per call (or per thread of a batch); nothing is allocated inside the loop.
"""

from __future__ import annotations

import math
import time
from typing import Any, TypeAlias

import numpy as np
from numba import njit, prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from ikbench.methods.ours_lm.compiled_chain import (
    LOWER,
    PRISMATIC,
    SCALE,
    SI,
    UPPER,
    frame,
    frame_jacobian,
)
from ikbench.methods.ours_lm.single_pose import STALLED

MM_PER_M = 1000.0
DEG_PER_RAD = 180.0 / math.pi
#: lambda's floor, and the eps of ``diag(J^T J) + eps I``.
MIN_DAMPING, DIAGONAL_EPS = 1e-9, 1e-9
#: Below this angle [rad] the series of the SO(3) log (as :func:`ikbench.core.rotations.so3_log`).
SMALL_ANGLE = 1e-6
#: Columns of the settings row: tolerances [mm, deg], stop, the iteration cap, restart_after,
#: position only (1.0 / 0.0), the largest step [pose units], lambda at every (re)start, and
#: the early restart: after ABANDON_AT iterations (0: never) an attempt whose |r| is still
#: above ABANDON_ABOVE restarts; the crawl check (:data:`KICK_SEED`).
TOL_MM, TOL_DEG, STOP, MAX_ITERATIONS, RESTART_AFTER, POSITION_ONLY, MAX_STEP_COLUMN, \
    DAMPING, ABANDON_AT, ABANDON_ABOVE, CRAWL_WINDOW, CRAWL_RATIO, KICK = range(13)

#: The crawl check (columns CRAWL_WINDOW, CRAWL_RATIO, KICK; window 0: off): an attempt whose
#: |r|^2 has not dropped below CRAWL_RATIO x its value CRAWL_WINDOW iterations before is
#: crawling (e.g. into the stretched-elbow saddle, where J^T J cannot see that bending helps)
#: and is kicked: every joint moved by a uniform draw in +-KICK x max_step [pose units] (into
#: the limits), lambda reset. The draws are xorshift64 from KICK_SEED at each call: the same
#: target and starts give the same kicks.
KICK_SEED = np.uint64(0x9E3779B97F4A7C15)

#: The kernels' arrays (numba reads the types from the arguments, not from annotations), and
#: one thread's scratch (:func:`workspace`).
Array: TypeAlias = np.ndarray
Workspace: TypeAlias = tuple[np.ndarray, ...]

CLOCK_MONOTONIC = getattr(time, "CLOCK_MONOTONIC", 1)
#: libc's clock_gettime, bound by symbol name when the kernel is linked: cacheable, where a
#: ctypes function pointer is a "dynamic global" that stops numba from caching the kernel.
_clock_gettime: Any = types.ExternalFunction("clock_gettime",
                                             types.int32(types.int32, types.voidptr))


@njit(cache=True)
def monotonic_s(timespec: Array) -> float:
    """CLOCK_MONOTONIC [s]; ``timespec``: int64 (2,) scratch (tv_sec, tv_nsec)."""
    _clock_gettime(CLOCK_MONOTONIC, timespec.ctypes)
    return timespec[0] + 1e-9 * timespec[1]


def _fetch_add(typingctx: Any, counter: Any, value: Any) -> Any:
    """numba's typing and code of :data:`fetch_add`."""
    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        array_type = signature.args[0]
        array = context.make_array(array_type)(context, builder, args[0])
        pointer = cgutils.get_item_pointer(context, builder, array_type, array,
                                           [context.get_constant(types.intp, 0)])
        return builder.atomic_rmw("add", pointer, args[1], "seq_cst")

    return types.int64(counter, types.int64), codegen


#: ``fetch_add(counter, value)``: ``counter[0] += value`` as one atomic step (LLVM's
#: atomicrmw), returning the old value; ``counter``: int64 (1,). numba has no atomics on the
#: CPU; this hands the targets of a batch out to the threads.
fetch_add: Any = intrinsic(_fetch_add)


@njit(cache=True)
def workspace(k: int) -> Workspace:
    """One thread's scratch: q, trial, g, step (k,); r, r_trial (6,); phi, phi_trial,
    point (3,); jac (6, k); jtj, chol (k, k); rot (3, 3); axes, origins, trig (k, 3);
    j_point, j_angular (3, k); timespec int64 (2,)."""
    return (np.empty(k), np.empty(k), np.empty(k), np.empty(k), np.zeros(6), np.zeros(6),
            np.zeros(3), np.zeros(3), np.empty(3), np.zeros((6, k)), np.empty((k, k)),
            np.empty((k, k)), np.empty((3, 3)), np.empty((k, 3)), np.empty((k, 3)),
            np.empty((k, 3)), np.empty((3, k)), np.empty((3, k)), np.zeros(2, dtype=np.int64))


@njit(cache=True)
def check(spec: Array, goal_mm: Array, goal_r: Array, initials: Array) -> None:
    """ValueError unless the goal is (3,) and (3, 3) and ``initials`` (A >= 1, k)."""
    if goal_mm.shape[0] != 3 or goal_r.shape[0] != 3 or goal_r.shape[1] != 3:
        raise ValueError("the goal point must be (3,) [mm] and the rotation (3, 3)")
    if initials.shape[0] < 1 or initials.shape[1] != spec.shape[0] - 2:
        raise ValueError("initials must be (A, dof) with A >= 1 [pose units]")


@njit(cache=True, nogil=True)
def solve_point(spec: Array, goal_mm: Array, goal_r: Array, initials: Array, budget_s: float
                ) -> tuple[Array, bool, int, int, float, float]:
    """One target: (pose (k,), success, attempts, iterations, position_error_mm,
    rotation_error_deg)."""
    check(spec, goal_mm, goal_r, initials)
    k = spec.shape[0] - 2
    pose = np.empty(k)
    out = solve_target(spec, goal_mm, goal_r, initials, budget_s, pose, workspace(k))
    return pose, out[0], out[1], out[2], out[3], out[4]


@njit(cache=True, nogil=True)
def solve_frame(spec: Array, frame_m: Array, initials: Array, budget_s: float
                ) -> tuple[Array, bool, int, int, float, float]:
    """:func:`solve_point` of a goal frame T_base_end (4, 4) [m]."""
    if frame_m.shape[0] < 3 or frame_m.shape[1] != 4:
        raise ValueError("the goal frame must be (4, 4) [m]")
    goal_mm, goal_r = np.empty(3), np.empty((3, 3))
    for i in range(3):
        goal_mm[i] = frame_m[i, 3] * MM_PER_M
        for j in range(3):
            goal_r[i, j] = frame_m[i, j]
    return solve_point(spec, goal_mm, goal_r, initials, budget_s)


@njit(cache=True, nogil=True)
def solve_views(spec: Array, point_m: Array, rotation: Array, initials: Array, budget_s: float
                ) -> tuple[Array, int, bool, int]:
    """:func:`solve_point` of the goal as ``ikbench ik`` hands it: the point (3,) [m] and the
    rotation (3, 3), views of any layout (the target frame's columns), converted to [mm] and
    copied here, inside the call; returns (pose (k,), iterations, success, attempts) in the
    order of :class:`ikbench.schemes.single_pose.PoseOut`."""
    check(spec, point_m, rotation, initials)  # the shapes, before reading them
    goal_mm, goal_r = np.empty(3), np.empty((3, 3))
    for i in range(3):
        goal_mm[i] = point_m[i] * MM_PER_M
        for j in range(3):
            goal_r[i, j] = rotation[i, j]
    k = spec.shape[0] - 2
    pose = np.empty(k)
    out = solve_target(spec, goal_mm, goal_r, initials, budget_s, pose, workspace(k))
    return pose, out[2], out[0], out[1]


@njit(cache=True, parallel=True, nogil=True)
def solve_many(spec: Array, goal_mm: Array, goal_r: Array, initials: Array, budget_s: float,
               poses: Array, success: Array, attempts: Array, iterations: Array,
               position_error_mm: Array, rotation_error_deg: Array, threads: int) -> None:
    """B targets on ``threads`` threads, each taking the next target when it is done with
    one (a shared atomic counter: a thread slowed by other work on its core takes fewer);
    results written per target."""
    b = goal_mm.shape[0]
    check(spec, goal_mm[0], goal_r[0], initials[0])
    counter = np.zeros(1, dtype=np.int64)
    for _ in prange(threads):
        ws = workspace(spec.shape[0] - 2)
        m = fetch_add(counter, 1)
        while m < b:
            out = solve_target(spec, goal_mm[m], goal_r[m], initials[m], budget_s, poses[m],
                               ws)
            success[m], attempts[m], iterations[m] = out[0], out[1], out[2]
            position_error_mm[m], rotation_error_deg[m] = out[3], out[4]
            m = fetch_add(counter, 1)


@njit(cache=True)
def solve_target(spec: Array, goal_mm: Array, goal_r: Array, initials: Array, budget_s: float,
                 pose: Array, ws: Workspace) -> tuple[bool, int, int, float, float]:
    """The LM loop with restarts of one target; writes the pose (k,) to ``pose``; returns
    (success, attempts, iterations, position_error_mm, rotation_error_deg)."""
    q, trial, g, step, r, r_trial, phi, phi_trial = ws[:8]
    jtj, chol, timespec = ws[10], ws[11], ws[18]
    k = spec.shape[0] - 2
    stop = spec[k + 1, STOP]
    max_iterations = int(spec[k + 1, MAX_ITERATIONS])
    restart_after = int(spec[k + 1, RESTART_AFTER])
    abandon_at, abandon_above = int(spec[k + 1, ABANDON_AT]), spec[k + 1, ABANDON_ABOVE]
    timed = budget_s < math.inf  # without a budget the clock is not read
    deadline = monotonic_s(timespec) + budget_s if timed else math.inf
    frozen, jtj_free, g_free = np.zeros(k), np.empty((k, k)), np.empty(k)
    attempt = iterations = started = 0
    lam, cost = restart(spec, k, initials[0], goal_mm, goal_r, ws)
    success = False
    # the crawl check: |r|^2 when the window began, its iteration, the kicks' random state
    mark_cost, mark_at, state = cost, 0, KICK_SEED
    crawl_window = int(spec[k + 1, CRAWL_WINDOW])
    while True:
        if done(spec, k, r, stop):
            success = True
            break
        if timed and monotonic_s(timespec) >= deadline:
            break
        since = iterations - started
        if since == 0:
            mark_cost, mark_at = cost, iterations
        elif iterations - mark_at >= crawl_window > 0:
            if cost > spec[k + 1, CRAWL_RATIO] * mark_cost:  # crawling: kick the pose
                state = kick(spec, k, q, state)
                cost = residual(spec, k, q, goal_mm, goal_r, r, phi, ws)
                linearise(spec, k, r, phi, ws)
                lam = spec[k + 1, DAMPING]
            mark_cost, mark_at = cost, iterations
        slow = since >= restart_after or (since == abandon_at > 0
                                          and cost > abandon_above * abandon_above)
        if (lam > STALLED or slow) and attempt + 1 < initials.shape[0]:
            attempt += 1
            started = iterations
            lam, cost = restart(spec, k, initials[attempt], goal_mm, goal_r, ws)
        if lam > STALLED or iterations >= max_iterations:
            break
        ok = damped_step(jtj, g, lam, chol, step, k, spec[k + 1, MAX_STEP_COLUMN])
        if ok and pinned(spec, k, q, step, frozen):  # again without the pinned joints
            without(jtj, g, frozen, k, jtj_free, g_free)
            ok = damped_step(jtj_free, g_free, lam, chol, step, k, spec[k + 1, MAX_STEP_COLUMN])
        for j in range(k):
            trial[j] = into_limits(spec, j, q[j] + step[j])
        new_cost = residual(spec, k, trial, goal_mm, goal_r, r_trial, phi_trial, ws)
        if ok and new_cost < cost:
            cost = new_cost
            q[:] = trial
            r[:] = r_trial
            phi[:] = phi_trial
            if done(spec, k, r, stop):  # solved: no Jacobian needed at the answer
                iterations += 1
                success = True
                break
            linearise(spec, k, r, phi, ws)
            lam = max(lam / 3.0, MIN_DAMPING)
        else:
            lam *= 4.0
        iterations += 1
    pose[:] = q
    position = math.sqrt(r[0] ** 2 + r[1] ** 2 + r[2] ** 2) * spec[k + 1, TOL_MM]
    rotation = (math.nan if spec[k + 1, POSITION_ONLY] != 0.0
                else math.sqrt(r[3] ** 2 + r[4] ** 2 + r[5] ** 2) * spec[k + 1, TOL_DEG])
    return success, attempt + 1, iterations, position, rotation


@njit(cache=True, inline="always")
def restart(spec: Array, k: int, start: Array, goal_mm: Array, goal_r: Array, ws: Workspace
            ) -> tuple[float, float]:
    """Start from ``start`` clipped into the limits (q, r, phi, the Jacobian and normal
    equations of ``ws`` written); returns (lambda, cost)."""
    q, r, phi = ws[0], ws[4], ws[6]
    for j in range(k):
        q[j] = min(max(start[j], spec[j, LOWER]), spec[j, UPPER])
    cost = residual(spec, k, q, goal_mm, goal_r, r, phi, ws)
    linearise(spec, k, r, phi, ws)
    return spec[k + 1, DAMPING], cost


@njit(cache=True, inline="always")
def kick(spec: Array, k: int, q: Array, state: np.uint64) -> np.uint64:
    """Move every joint of ``q`` by a uniform draw in +-KICK x max_step [pose units], into
    its limits (:func:`into_limits`); returns the xorshift64 state after the k draws."""
    reach = spec[k + 1, KICK] * spec[k + 1, MAX_STEP_COLUMN]
    for j in range(k):
        state ^= state << np.uint64(13)
        state ^= state >> np.uint64(7)
        state ^= state << np.uint64(17)
        u = (state >> np.uint64(11)) * (1.0 / 9007199254740992.0)  # [0, 1), 53 bits
        q[j] = into_limits(spec, j, q[j] + (2.0 * u - 1.0) * reach)
    return state


@njit(cache=True, inline="always")
def into_limits(spec: Array, j: int, value: float) -> float:
    """Joint ``j``'s ``value`` [pose units] moved into its limits: as it is when within them;
    a revolute joint's turned by the fewest whole turns that bring it within them (the same
    frame: the descent goes on where clipping would stop the joint on a limit that its range
    exceeds by a turn); else clipped (:func:`.single_pose.into_limits`, vectorised)."""
    lower, upper = spec[j, LOWER], spec[j, UPPER]
    if lower <= value <= upper:
        return value
    if spec[j, PRISMATIC] == 0.0:
        turn = 2.0 * math.pi / abs(spec[j, SCALE] * spec[j, SI])
        if value > upper:
            shifted = value - turn * math.ceil((value - upper) / turn)
            if shifted >= lower:
                return shifted
        else:
            shifted = value + turn * math.ceil((lower - value) / turn)
            if shifted <= upper:
                return shifted
    return min(max(value, lower), upper)


@njit(cache=True, inline="always")
def pinned(spec: Array, k: int, q: Array, step: Array, frozen: Array) -> bool:
    """Marks in ``frozen`` (1.0, else 0.0) each joint on a limit that ``step`` pushes further
    out and :func:`into_limits` would clip back onto it (a step the projection discards: left
    in the normal equations it only shrinks the other joints' steps); True when there is one."""
    any_pinned = False
    for j in range(k):
        frozen[j] = 0.0
        lower, upper = spec[j, LOWER], spec[j, UPPER]
        if (q[j] == lower and step[j] < 0.0 and into_limits(spec, j, q[j] + step[j]) == lower) \
                or (q[j] == upper and step[j] > 0.0
                    and into_limits(spec, j, q[j] + step[j]) == upper):
            frozen[j] = 1.0
            any_pinned = True
    return any_pinned


@njit(cache=True, inline="always")
def without(jtj: Array, g: Array, frozen: Array, k: int, jtj_free: Array, g_free: Array
            ) -> None:
    """J^T J and J^T r without the ``frozen`` joints: their rows and columns 0, a 1 on the
    diagonal and 0 in g (their step is then 0, the others' that of the system without them)."""
    for a in range(k):
        g_free[a] = 0.0 if frozen[a] != 0.0 else g[a]
        for b in range(k):
            if frozen[a] != 0.0 or frozen[b] != 0.0:
                jtj_free[a, b] = 1.0 if a == b else 0.0
            else:
                jtj_free[a, b] = jtj[a, b]


@njit(cache=True, inline="always")
def done(spec: Array, k: int, r: Array, stop: float) -> bool:
    """Both errors below ``stop`` x the tolerances (the residual is scaled by them)."""
    if r[0] ** 2 + r[1] ** 2 + r[2] ** 2 >= stop * stop:
        return False
    return spec[k + 1, POSITION_ONLY] != 0.0 or r[3] ** 2 + r[4] ** 2 + r[5] ** 2 < stop * stop


@njit(cache=True, inline="always")
def residual(spec: Array, k: int, q: Array, goal_mm: Array, goal_r: Array, r: Array, phi: Array,
             ws: Workspace) -> float:
    """FK of ``q`` (the frame in ``ws``) and the scaled residual ``r`` (6,) with
    phi = log(R_goal^T R) [rad] (3,) written; returns |r|^2."""
    point, rot, axes, origins, trig = ws[8], ws[12], ws[13], ws[14], ws[15]
    frame(spec, k, q, point, rot, axes, origins, trig)
    tol_mm = spec[k + 1, TOL_MM]
    for i in range(3):
        r[i] = (point[i] * MM_PER_M - goal_mm[i]) / tol_mm
    if spec[k + 1, POSITION_ONLY] != 0.0:
        return r[0] ** 2 + r[1] ** 2 + r[2] ** 2

    def entry(i, j):  # (R_goal^T R)[i, j]
        return goal_r[0, i] * rot[0, j] + goal_r[1, i] * rot[1, j] + goal_r[2, i] * rot[2, j]

    phi[0], phi[1], phi[2] = so3_log(entry(0, 0), entry(0, 1), entry(0, 2), entry(1, 0),
                                     entry(1, 1), entry(1, 2), entry(2, 0), entry(2, 1),
                                     entry(2, 2))
    tol_deg = spec[k + 1, TOL_DEG]
    for i in range(3):
        r[3 + i] = phi[i] * DEG_PER_RAD / tol_deg
    cost = 0.0
    for i in range(6):
        cost += r[i] * r[i]
    return cost


@njit(cache=True, inline="always")
def so3_log(e00: float, e01: float, e02: float, e10: float, e11: float, e12: float,
            e20: float, e21: float, e22: float) -> tuple[float, float, float]:
    """log(E) [rad] as (x, y, z), angle in [0, pi] (:func:`ikbench.core.rotations.so3_log`,
    its branches near 0 and pi)."""
    v0, v1, v2 = 0.5 * (e21 - e12), 0.5 * (e02 - e20), 0.5 * (e10 - e01)
    sin = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    theta = math.atan2(sin, 0.5 * (e00 + e11 + e22 - 1.0))
    if theta <= math.pi - 1e-3:
        factor = 1.0 + theta * theta / 6.0 if theta < SMALL_ANGLE else theta / (sin + 1e-300)
        return v0 * factor, v1 * factor, v2 * factor
    # near pi: the axis from E + E^T = 2 cos I + 2 (1 - cos) a a^T, the row of the largest
    # diagonal entry (the 1 / (1 - cos) cancels in the normalisation)
    c = math.cos(theta)
    if e00 >= e11 and e00 >= e22:
        a0, a1, a2 = e00 - c, 0.5 * (e01 + e10), 0.5 * (e02 + e20)
    elif e11 >= e22:
        a0, a1, a2 = 0.5 * (e10 + e01), e11 - c, 0.5 * (e12 + e21)
    else:
        a0, a1, a2 = 0.5 * (e20 + e02), 0.5 * (e21 + e12), e22 - c
    factor = theta / math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    if a0 * v0 + a1 * v1 + a2 * v2 < 0:
        factor = -factor
    return a0 * factor, a1 * factor, a2 * factor


@njit(cache=True, inline="always")
def linearise(spec: Array, k: int, r: Array, phi: Array, ws: Workspace) -> None:
    """The scaled residual's Jacobian (6, k) at the last :func:`residual`'s frame, then
    J^T J (k, k) and J^T r (k,), into ``ws``."""
    g, point, jac, jtj, rot, axes, origins, jp, ja = (ws[2], ws[8], ws[9], ws[10], ws[12],
                                                      ws[13], ws[14], ws[16], ws[17])
    frame_jacobian(spec, k, point, axes, origins, jp, ja)
    scale = MM_PER_M / spec[k + 1, TOL_MM]
    for i in range(3):
        for j in range(k):
            jac[i, j] = jp[i, j] * scale
    m = 3
    if spec[k + 1, POSITION_ONLY] == 0.0:
        m = 6
        i00, i01, i02, i10, i11, i12, i20, i21, i22 = right_jacobian_inverse(phi)
        scale = 1.0 / spec[k + 1, TOL_DEG]
        for j in range(k):  # R^T w: the rotation in the end frame [deg], then Jr^-1
            b0 = (rot[0, 0] * ja[0, j] + rot[1, 0] * ja[1, j] + rot[2, 0] * ja[2, j]) \
                * DEG_PER_RAD
            b1 = (rot[0, 1] * ja[0, j] + rot[1, 1] * ja[1, j] + rot[2, 1] * ja[2, j]) \
                * DEG_PER_RAD
            b2 = (rot[0, 2] * ja[0, j] + rot[1, 2] * ja[1, j] + rot[2, 2] * ja[2, j]) \
                * DEG_PER_RAD
            jac[3, j] = (i00 * b0 + i01 * b1 + i02 * b2) * scale
            jac[4, j] = (i10 * b0 + i11 * b1 + i12 * b2) * scale
            jac[5, j] = (i20 * b0 + i21 * b1 + i22 * b2) * scale
    for a in range(k):
        total = 0.0
        for i in range(m):
            total += jac[i, a] * r[i]
        g[a] = total
        for b in range(a + 1):
            total = 0.0
            for i in range(m):
                total += jac[i, a] * jac[i, b]
            jtj[a, b] = total
            jtj[b, a] = total


@njit(cache=True, inline="always")
def right_jacobian_inverse(phi: Array) -> tuple[float, ...]:
    """Jr^-1(phi) = I + K / 2 + c K^2 (K = [phi]_x), row-major as 9 numbers
    (:func:`ikbench.core.rotations.right_jacobian_inverse`: series below 1e-2 rad, the angle
    capped at 3 rad in the closed form)."""
    x, y, z = phi[0], phi[1], phi[2]
    t2 = x * x + y * y + z * z
    theta = math.sqrt(t2)
    if theta < 1e-2:
        c = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0
    else:
        safe = min(theta, 3.0)
        c = 1.0 / safe**2 - (1.0 + math.cos(safe)) / (2.0 * safe * math.sin(safe))
    # K^2 = phi phi^T - theta^2 I
    return (1.0 + c * (x * x - t2), -0.5 * z + c * x * y, 0.5 * y + c * x * z,
            0.5 * z + c * x * y, 1.0 + c * (y * y - t2), -0.5 * x + c * y * z,
            -0.5 * y + c * x * z, 0.5 * x + c * y * z, 1.0 + c * (z * z - t2))


@njit(cache=True, inline="always")
def damped_step(jtj: Array, g: Array, lam: float, chol: Array, step: Array, k: int,
                max_step: float) -> bool:
    """``step`` (k,) = -(J^T J + lam (diag(J^T J) + eps I))^-1 J^T r by Cholesky, then
    scaled to at most ``max_step`` [pose units]; False (step 0) when not positive definite.
    ``chol`` holds L below its diagonal and 1 / L_aa on it (one division per row, not one
    per entry: ~136 -> ~112 ns a step on the UR10)."""
    for a in range(k):
        for b in range(a + 1):
            total = jtj[a, b] + (lam * (jtj[a, a] + DIAGONAL_EPS) if a == b else 0.0)
            for c in range(b):
                total -= chol[a, c] * chol[b, c]
            if a == b:
                if not total > 0.0:
                    step[:] = 0.0
                    return False
                chol[a, a] = 1.0 / math.sqrt(total)  # the reciprocal: multiplies below
            else:
                chol[a, b] = total * chol[b, b]
    for a in range(k):  # L y = -g
        total = -g[a]
        for c in range(a):
            total -= chol[a, c] * step[c]
        step[a] = total * chol[a, a]
    for a in range(k - 1, -1, -1):  # L^T x = y
        total = step[a]
        for c in range(a + 1, k):
            total -= chol[c, a] * step[c]
        step[a] = total * chol[a, a]
    largest = 0.0
    for a in range(k):
        largest = max(largest, abs(step[a]))
    factor = min(1.0, max_step / max(largest, 1e-300))
    for a in range(k):
        step[a] *= factor
    return True
