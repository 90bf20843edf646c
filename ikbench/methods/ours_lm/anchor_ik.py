"""The pose-path search's IK of single waypoints, compiled (numba).

:func:`first_waypoint_ik` is :func:`.search_common.first_waypoint_ik` (the numpy reference, step
for step) over numba threads: damped least squares, -J^T (J J^T + d^2 I)^-1 e with the exact
Jacobian of the position and SO(3)-log errors [mm, deg], the step scaled to at most
:data:`.search_common.IK_MAX_STEP` and clipped into the limits, accepted when |e| drops (d / 3,
at least 1e-6) or rejected (d * 4), each seed until |e| < :data:`.search_common.IK_TOLERANCE`,
its damping above :data:`.search_common.IK_STALLED` (stuck) or the iterations run out.
``tests/test_ours_lm_paths.py`` checks it against the reference.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from ikbench.methods.ours_lm.compiled_paths import (
    PathSpec,
    _pose_error,
    _pose_frames,
    _redundant_step,
    _workspace,
)
from ikbench.methods.ours_lm.search_common import (
    IK_ITERATIONS,
    IK_MAX_STEP,
    IK_STALLED,
    IK_TOLERANCE,
)


@njit(cache=True)
def _errors(chain, tip_rot, q, goal_p, goal_R, ws, e, J):
    """e (6,) and J (6, k) at q (exact Jacobian); returns |e|."""
    rots, origins, axes, point, rot = ws[0], ws[1], ws[2], ws[3], ws[4]
    _pose_frames(q, chain, tip_rot, rots, origins, axes, point, rot)
    _pose_error(chain, point, rot, axes, origins, goal_p, goal_R, True, True, e, J)
    s = 0.0
    for r in range(6):
        s += e[r] * e[r]
    return math.sqrt(s)


@njit(cache=True)
def _ik_one(chain, tip_rot, lower, upper, goal_p, goal_R, seed, max_iterations, q, out):
    """One seed's IK (see the module docstring): q (k,) the result, ``out`` (2,) its position
    [mm] and rotation [deg] errors. Returns the iterations it took."""
    k = len(seed)
    ws = _workspace(k, 0, 0)
    e, J = np.empty(6), np.empty((6, k))
    e_new, J_new = np.empty(6), np.empty((6, k))
    trial, step, zero = np.empty(k), np.empty(k), np.zeros(k)
    free_lower, free_upper = np.full(k, -np.inf), np.full(k, np.inf)
    for j in range(k):
        q[j] = min(max(seed[j], lower[j]), upper[j])
    norm = _errors(chain, tip_rot, q, goal_p, goal_R, ws, e, J)
    damping = 1.0
    iterations = 0
    while iterations < max_iterations:
        if not (norm >= IK_TOLERANCE and damping <= IK_STALLED):
            break
        iterations += 1
        _redundant_step(e, J, damping, q, free_lower, free_upper, zero, step)  # -J^+ e
        largest = 0.0
        for j in range(k):
            largest = max(largest, abs(step[j]))
        scale = min(1.0, IK_MAX_STEP / max(largest, 1e-300))
        for j in range(k):
            trial[j] = min(max(q[j] + step[j] * scale, lower[j]), upper[j])
        new = _errors(chain, tip_rot, trial, goal_p, goal_R, ws, e_new, J_new)
        if new < norm:
            q[:] = trial
            e[:] = e_new
            J[:, :] = J_new
            norm = new
            damping = max(damping / 3.0, 1e-6)
        else:
            damping *= 4.0
    out[0] = math.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2)
    out[1] = math.sqrt(e[3] ** 2 + e[4] ** 2 + e[5] ** 2)
    return iterations


@njit(cache=True, parallel=True, nogil=True)
def _ik_all(chain, tip_rot, lower, upper, goals_p, goals_R, seeds, max_iterations, q, out,
            iterations, threads):
    m = len(seeds)
    for t in prange(threads):
        for r in range(t, m, threads):
            iterations[r] = _ik_one(chain, tip_rot, lower, upper, goals_p[r], goals_R[r],
                                    seeds[r], max_iterations, q[r], out[r])


def first_waypoint_ik(spec: PathSpec, goal_mm: np.ndarray, goal_R: np.ndarray,
                      seeds: np.ndarray, max_iterations: int = IK_ITERATIONS
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """:func:`.search_common.first_waypoint_ik` compiled, within the spec's limits: one pose
    (``goal_mm`` (3,) [mm], ``goal_R`` (3, 3)) or one per seed ((K, 3), (K, 3, 3)) from every
    seed (K, k) [pose units].

    Returns:
        (poses (K, k), position errors (K,) [mm], rotation errors (K,) [deg], iterations (the
        most any seed took)).
    """
    # writeable C-contiguous copies, always: numba compiles one specialisation per argument
    # layout, and np.broadcast_to's read-only views (kept as they are by ascontiguousarray
    # when already contiguous) made a second one, compiled inside a timed solve
    seeds = np.array(seeds, dtype=float, order="C", copy=True)
    m, k = seeds.shape
    goals_p = np.array(np.broadcast_to(goal_mm, (m, 3)), dtype=float, order="C", copy=True)
    goals_R = np.array(np.broadcast_to(goal_R, (m, 3, 3)), dtype=float, order="C", copy=True)
    q, out = np.empty((m, k)), np.empty((m, 2))
    iterations = np.zeros(m, dtype=np.int64)
    if m:
        count = max(1, min(numba.get_num_threads(), m))
        _ik_all(spec.chain, spec.tip_rotation, spec.lower, spec.upper,  # type: ignore[call-arg]
                goals_p, goals_R, seeds, int(max_iterations), q, out, iterations, count)
    return q, out[:, 0], out[:, 1], int(iterations.max(initial=0))
