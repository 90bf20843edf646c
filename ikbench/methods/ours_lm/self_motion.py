"""Sweeps of a pose's self-motion manifold, compiled (numba), and the repair of a stitched
path's too-large steps by the shortest path through them.

A 7-joint arm reaches a 6-D pose along a curve of joint vectors (its self-motion manifold: the
elbow's swing); the stitch (:mod:`.path_search`) only sees the poses its carried tracks happen to
take on it. Where a carried track cannot continue (an obstacle closes in on the arm's links, or
the path swings the arm quickly past a singular pose) the stitch jumps between tracks. Two uses:

- :func:`sweep_manifolds`: from each start pose, the curve's samples both ways (the null
  vector of the 6 x k Jacobian, by the generalised cross product of its rows, a step of
  ``h`` pose units along it, then damped least-squares corrections back onto the pose; a step
  that bends too far is halved), to a joint limit, once round, or ``steps`` samples each way;
- :func:`repair_steps`: for a stitched path whose steps exceed the step limit somewhere, the
  window of waypoints around them is sampled densely (the sweeps from the path's poses and from
  the two tracks it switches between), and the window is replaced by the shortest path
  (weighted joint path length, :func:`.compiled_paths.stitch_choice`) through the samples that
  collide with nothing, from the path's pose at the window's first waypoint to its pose at
  the last, with the steps held below the limit where it can be.

:func:`sweep_reference` is the numpy reference of a sweep (``tests/test_ours_lm_paths.py``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numba
import numpy as np
from numba import njit, prange

from ikbench.methods.ours_lm.compiled_paths import (
    PathSpec,
    _pose_error,
    _pose_frames,
    _redundant_step,
    _workspace,
    stitch_choice,
    track_nodes,
)
from ikbench.methods.ours_lm.frames import errors_from_frames

if TYPE_CHECKING:
    from ikbench.core.kinematics.chain import Frames

#: A sweep: the largest step along the manifold [pose units, max over joints], damped
#: least-squares corrections after each step at most, the error a sample keeps below [mm and
#: deg], the correction (as a share of the step) above which a step is halved, the smallest
#: step (as a share of the largest) before the sweep ends, and the damping [mm].
SWEEP_STEP = 1.5
SWEEP_CORRECTIONS = 3
SWEEP_TOLERANCE = 1e-3
SWEEP_BEND = 0.3
SWEEP_SMALLEST = 1.0 / 16.0
SWEEP_DAMPING = 1e-3


def sweep_settings(step: float = SWEEP_STEP) -> np.ndarray:
    """The kernels' sweep settings: (step [pose units], corrections, tolerance [mm and deg],
    bend share, smallest share, damping [mm])."""
    return np.array([step, SWEEP_CORRECTIONS, SWEEP_TOLERANCE, SWEEP_BEND, SWEEP_SMALLEST,
                     SWEEP_DAMPING])


# ----- the null vector --------------------------------------------------------------------------
@njit(cache=True)
def _det6(M):
    """Determinant of M (6, 6) by Gaussian elimination with partial pivoting (M destroyed)."""
    n = M.shape[0]
    det = 1.0
    for c in range(n):
        pivot, best = c, abs(M[c, c])
        for r in range(c + 1, n):
            if abs(M[r, c]) > best:
                pivot, best = r, abs(M[r, c])
        if best == 0.0:
            return 0.0
        if pivot != c:
            for j in range(n):
                M[c, j], M[pivot, j] = M[pivot, j], M[c, j]
            det = -det
        det *= M[c, c]
        for r in range(c + 1, n):
            f = M[r, c] / M[c, c]
            for j in range(c, n):
                M[r, j] -= f * M[c, j]
    return det


@njit(cache=True)
def _null_vector(J, out):
    """out (k,) = the generalised cross product of J's six rows (k = 7): (-1)^j det(J without
    column j), a null vector of J (zero where J loses rank), scaled to a largest entry of 1.
    Returns False where it vanishes (or k != 7)."""
    k = J.shape[1]
    if k != 7:
        return False
    M = np.empty((6, 6))
    size = 0.0
    for j in range(k):
        for r in range(6):
            c2 = 0
            for c in range(k):
                if c != j:
                    M[r, c2] = J[r, c]
                    c2 += 1
        out[j] = (1.0 if j % 2 == 0 else -1.0) * _det6(M)
        size = max(size, abs(out[j]))
    if not size > 0.0:
        return False
    for j in range(k):
        out[j] /= size
    return True


# ----- a sweep ----------------------------------------------------------------------------------
@njit(cache=True)
def _error_size(chain, tip_rot, q, goal_p, goal_R, ws, derivatives):
    """The largest error component [mm or deg] at q; fills ws's e (and J)."""
    rots, origins, axes, point, rot, e, J = ws[0], ws[1], ws[2], ws[3], ws[4], ws[5], ws[6]
    _pose_frames(q, chain, tip_rot, rots, origins, axes, point, rot)
    _pose_error(chain, point, rot, axes, origins, goal_p, goal_R, False, derivatives, e, J)
    size = 0.0
    for r in range(6):
        size = max(size, abs(e[r]))
    return size


@njit(cache=True)
def _correct(chain, tip_rot, q, goal_p, goal_R, settings, ws, free_lower, free_upper, zero,
             step):
    """Damped least-squares corrections of q (in place) back onto the goal; returns the error
    left [mm or deg]."""
    corrections, damping = int(settings[1]), settings[5]
    size = _error_size(chain, tip_rot, q, goal_p, goal_R, ws, True)
    for _ in range(corrections):
        if size < 0.1 * settings[2]:
            break
        _redundant_step(ws[5], ws[6], damping, q, free_lower, free_upper, zero, step)
        for j in range(len(q)):
            q[j] += step[j]
        size = _error_size(chain, tip_rot, q, goal_p, goal_R, ws, True)
    return size


@njit(cache=True)
def _sweep_one(chain, tip_rot, lower, upper, caps, goal_p, goal_R, start, settings, reach,
               out):
    """Sweep the self-motion manifold of one goal from ``start`` (k,): ``out`` (2S + 1, k)
    (NaN where none) holds the start, corrected onto the goal, at S, the samples one way at
    S + 1, S + 2, ... and the other way at S - 1, S - 2, ..., each way until a sample is
    further than ``reach`` [pose units, max over joints] from the start. Returns the samples
    found."""
    h, tolerance, bend, smallest = settings[0], settings[2], settings[3], settings[4]
    k = len(start)
    steps = (out.shape[0] - 1) // 2
    ws = _workspace(k, len(caps[0]), 0)
    free_lower, free_upper = np.full(k, -np.inf), np.full(k, np.inf)
    zero, step = np.zeros(k), np.empty(k)
    q, trial, d, d0 = start.copy(), np.empty(k), np.empty(k), np.empty(k)
    out[:, :] = np.nan
    if _correct(chain, tip_rot, q, goal_p, goal_R, settings, ws, free_lower, free_upper, zero,
                step) > tolerance:
        return 0
    for j in range(k):
        if not lower[j] <= q[j] <= upper[j]:
            return 0
    out[steps, :] = q
    found = 1
    _error_size(chain, tip_rot, q, goal_p, goal_R, ws, True)
    if not _null_vector(ws[6], d0):
        return found
    for sign in (1.0, -1.0):
        current = q.copy()
        for j in range(k):
            d[j] = sign * d0[j]
        size = h
        s = 0
        while s < steps:
            for j in range(k):
                trial[j] = current[j] + size * d[j]
            error = _correct(chain, tip_rot, trial, goal_p, goal_R, settings, ws, free_lower,
                             free_upper, zero, step)
            moved = 0.0
            bent = 0.0
            along = 0.0
            for j in range(k):
                moved = max(moved, abs(trial[j] - current[j]))
                bent = max(bent, abs(trial[j] - current[j] - size * d[j]))
                along += (trial[j] - current[j]) * d[j]
            if error > tolerance or bent > bend * size or not along > 0.0:
                size *= 0.5
                if size < smallest * h:
                    break
                continue
            outside = False
            for j in range(k):
                if not lower[j] <= trial[j] <= upper[j]:
                    outside = True
            if outside:
                break
            for j in range(k):
                d[j] = (trial[j] - current[j]) / moved
                current[j] = trial[j]
            s += 1
            out[steps + int(sign) * s, :] = current
            found += 1
            size = min(h, 1.5 * size)
            back = 0.0
            for j in range(k):
                back = max(back, abs(current[j] - q[j]))
            if (s > 4 and back < 0.5 * h) or back > reach:   # once round, or far enough
                break
    return found


@njit(cache=True, parallel=True, nogil=True)
def _sweep_all(chain, tip_rot, lower, upper, caps, goals_p, goals_R, waypoints, starts,
               settings, reach, out, threads):
    m = len(waypoints)
    for t in prange(threads):
        for r in range(t, m, threads):
            if math.isnan(starts[r, 0]):
                out[r, :, :] = np.nan
                continue
            _sweep_one(chain, tip_rot, lower, upper, caps, goals_p[waypoints[r]],
                       goals_R[waypoints[r]], starts[r], settings, reach[r], out[r])


def sweep_manifolds(spec: PathSpec, goals_p: np.ndarray, goals_R: np.ndarray,
                    waypoints: np.ndarray, starts: np.ndarray, steps: int,
                    settings: np.ndarray | None = None, reach: np.ndarray | None = None
                    ) -> np.ndarray:
    """Sweep the self-motion manifold of waypoint ``waypoints[r]``'s goal from ``starts[r]``
    (M, k) [pose units] (NaN: none), ``steps`` samples each way at most, within the spec's
    limits (a 7-joint chain; others get the corrected start only), each way until a sample is
    further than ``reach[r]`` [pose units, max over joints] from its start (None: no bound).

    Returns:
        (M, 2 steps + 1, k): the start (corrected onto its goal) at ``steps``, the samples
        one way after it and the other way before it, NaN where there are none.
    """
    m, k = starts.shape
    if len(waypoints) != m:
        raise ValueError(f"sweep_manifolds: {len(waypoints)} waypoints for {m} starts")
    out = np.full((m, 2 * steps + 1, k), np.nan)
    if not m:
        return out
    count = max(1, min(numba.get_num_threads(), m))
    _sweep_all(spec.chain, spec.tip_rotation, spec.lower,  # type: ignore[call-arg]
               spec.upper, spec.caps, np.ascontiguousarray(goals_p, dtype=float),
               np.ascontiguousarray(goals_R, dtype=float),
               np.asarray(waypoints, dtype=np.int64), np.ascontiguousarray(starts, dtype=float),
               sweep_settings() if settings is None else np.asarray(settings, dtype=float),
               np.full(m, np.inf) if reach is None else np.asarray(reach, dtype=float), out,
               count)
    return out


# ----- the repair of a path's steps -------------------------------------------------------------
def too_large(path: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Waypoints i (ascending) whose step to i + 1 exceeds ``limit`` (k,) in some joint."""
    return np.flatnonzero(np.any(np.abs(np.diff(path, axis=0)) > limit, axis=1))


def repair_window(spec: PathSpec, goals_p: np.ndarray, goals_R: np.ndarray, path: np.ndarray,
                  first: int, last: int, steps: int, weights: np.ndarray, limit: np.ndarray,
                  jump_cost: float, period: np.ndarray, reached: float) -> np.ndarray | None:
    """The path (N, k)'s waypoints ``first..last`` replaced by the shortest path through the
    collision-free samples of sweeps (``steps`` samples each way) from its poses there, from
    ``path[first]`` to ``path[last]`` (kept); ``weights`` (k,) weigh the joints' steps, a
    step above ``limit`` (k,) [pose units] costs ``jump_cost`` per pose unit, ``period`` (k,)
    as :func:`.compiled_paths.stitch_choice`'s, a sample is a node within ``reached`` [mm and
    deg] of its goal. None when some waypoint has no sample."""
    window = np.arange(first, last + 1)
    w = len(window)
    # a sample further from the path's pose than the path may travel from either end of
    # the window (``limit`` per step) and back is out of reach
    top = limit.max()
    reach = np.minimum(
        top * (window - first) + np.abs(path[window] - path[first]).max(axis=1),
        top * (last - window) + np.abs(path[window] - path[last]).max(axis=1))
    sweeps = sweep_manifolds(spec, goals_p, goals_R, window, path[window], steps,
                             reach=reach)
    samples = np.concatenate([path[None, window], sweeps.transpose(1, 0, 2)])  # (M, W, k)
    nodes = track_nodes(spec, goals_p[window], goals_R[window], samples, reached)
    nodes[:, 0] = nodes[:, -1] = False
    nodes[0, 0] = nodes[0, -1] = True   # the ends stay where they are
    choice = stitch_choice(np.nan_to_num(samples), nodes, weights, limit, jump_cost, period)
    if choice is None:
        return None
    out = path.copy()
    out[window] = samples[choice, np.arange(w)]
    return out


# ----- the numpy reference ----------------------------------------------------------------------
def sweep_reference(frames: Callable[..., Frames], goal_p: np.ndarray, goal_R: np.ndarray,
                    start: np.ndarray, lower: np.ndarray, upper: np.ndarray, steps: int,
                    settings: np.ndarray | None = None) -> np.ndarray:
    """:func:`_sweep_one` in numpy (the reference; the null vector by the cofactors of
    ``numpy.linalg.det``, the corrections by damped least squares), one goal: (2 steps + 1, k)."""
    h, corrections, tolerance, bend, smallest, damping = (
        sweep_settings() if settings is None else settings)
    k = len(start)
    out = np.full((2 * steps + 1, k), np.nan)

    def errors(q):
        e_p, e_r, j_p, j_r = errors_from_frames(*frames(q[None]), goal_p, goal_R, exact=False)
        return np.concatenate([e_p, e_r], -1)[0], np.concatenate([j_p, j_r], -2)[0]

    def correct(q):
        e, J = errors(q)
        for _ in range(int(corrections)):
            if np.abs(e).max() < 0.1 * tolerance:
                break
            q = q - J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(6), e)
            e, J = errors(q)
        return q, np.abs(e).max(), J

    q, error, J = correct(np.array(start, dtype=float))
    if error > tolerance or np.any((q < lower) | (q > upper)):
        return out
    out[steps] = q
    if k != 7:
        return out
    d0 = np.array([(-1.0) ** j * np.linalg.det(np.delete(J, j, axis=1)) for j in range(k)])
    if not np.abs(d0).max() > 0:
        return out
    d0 /= np.abs(d0).max()
    for sign in (1.0, -1.0):
        current, d, size, s = q.copy(), sign * d0, h, 0
        while s < steps:
            trial, error, _ = correct(current + size * d)
            moved = np.abs(trial - current).max()
            if (error > tolerance or np.abs(trial - current - size * d).max() > bend * size
                    or not (trial - current) @ d > 0):
                size *= 0.5
                if size < smallest * h:
                    break
                continue
            if np.any((trial < lower) | (trial > upper)):
                break
            d, current = (trial - current) / moved, trial
            s += 1
            out[steps + int(sign) * s] = current
            size = min(h, 1.5 * size)
            if s > 4 and np.abs(current - q).max() < 0.5 * h:
                break
    return out
