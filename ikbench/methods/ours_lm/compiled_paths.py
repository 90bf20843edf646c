"""Compiled (numba) kernels of ours-lm's 6-D pose-path search: carrying, nodes, stitching, the
pose-path LM with its collision penalty, and CppFlow's validity.

Each kernel is the numpy reference's method step for step, written per pose in scalars like the
compiled 3-D solver (:mod:`.compiled`, whose sine and cosine, banded Cholesky and active set it
reuses), with the robot's capsules and the task's obstacles in compiled code
(:mod:`ikbench.core.capsules`) instead of a coal call per pose:

- :func:`carry_tracks`: :func:`.start_search.carry` for many start poses, each along its own
  run of waypoints (forward or backward from an anchor), with the joint-limit and collision
  avoidance of :func:`.start_search.redundant_step` and :meth:`.avoidance.Avoidance.motion`;
  one track per numba thread task;
- :func:`track_nodes`: :func:`.start_search.stitch_nodes` (a carried pose within reach of its
  goal that collides with nothing);
- :func:`stitch_path`: :func:`.start_search.stitch`, the dynamic programme over the nodes
  (weighted joint path length, a jump costing :data:`.start_search.STITCH_JUMP_COST`);
- :func:`solve_path`: the LM loop of :func:`.solver.solve_batch` on the 6-D objective
  (:func:`.frames.evaluate_frames`) with the clearance penalty of
  :meth:`.avoidance.Avoidance.terms` and, as ``until``, :func:`.start_search.check_paths`;
  optionally it runs on past the first valid iterate and returns the last valid one (a
  smoother, shorter path), or the last iterate when none was valid;
- :func:`check_path`: :func:`.start_search.check_paths` for one path.

``tests/test_ours_lm_paths.py`` checks each against its numpy reference (the numpy search with
:class:`ikbench.core.capsules.CapsuleScene` as its collision model computes the same
distances). numba is the ``[fast]`` extra; the kernels compile on first use (cached in
``__pycache__``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numba
import numpy as np
from numba import njit, prange

from ikbench.core.capsules import distance_gradient, pair_distances
from ikbench.methods.ours_lm.compiled import (
    Chain,
    _damped_trial,
    _damping_update,
    _sin_cos,
)
from ikbench.methods.ours_lm.compiled_chain import joint_step

if TYPE_CHECKING:
    from ikbench.core.capsules import CapsuleScene
    from ikbench.core.robot import Robot

DEG_PER_RAD = 180.0 / math.pi
MM_PER_M = 1000.0
#: so3_log's series threshold [rad] (:data:`ikbench.core.rotations.SMALL_ANGLE`).
SMALL_ANGLE = 1e-6


class PathSpec:
    """The robot's chain, a task's joint limits and its collision scene as the kernels' arrays.

    Attributes:
        chain: :meth:`.compiled.Chain.arrays`.  tip_rotation: (3, 3) end frame in the last
            joint's frame.  lower, upper: (k,) [pose units].
        caps: the capsules and the scene's pairs and obstacles: (joint (C,), a (C, 3), b (C, 3),
            radius (C,) [m], first, second, is_env (P,), kind, centre, rotation, half, radius,
            normal (the obstacles, :func:`ikbench.core.capsules.obstacle_arrays`)); no pairs
            when ``scene`` is None.
    """

    def __init__(self, robot: Robot, lower: np.ndarray, upper: np.ndarray,
                 scene: CapsuleScene | None) -> None:
        chain = Chain(robot)
        self.chain = chain.arrays()
        self.tip_rotation = np.ascontiguousarray(robot.chain_kinematics().tip_rotation,
                                                 dtype=float)
        self.lower = np.ascontiguousarray(lower, dtype=float)
        self.upper = np.ascontiguousarray(upper, dtype=float)
        self.dof = len(self.lower)
        self.caps: tuple[np.ndarray, ...]
        if scene is None:
            empty3 = np.zeros((0, 3))
            none = np.zeros(0, dtype=np.int64)
            self.caps = (none, empty3, empty3, np.zeros(0), none, none, np.zeros(0, dtype=bool),
                         none, empty3, np.zeros((0, 3, 3)), empty3, np.zeros(0), empty3)
        else:
            c = scene.capsules
            self.caps = (c.joint, np.ascontiguousarray(c.a_m), np.ascontiguousarray(c.b_m),
                         c.radius_m, scene.first, scene.second, scene.is_env, *scene.arrays)
        self.n_pairs = len(self.caps[4])

    def args(self) -> tuple:
        """(chain, tip_rotation, lower, upper, caps): the kernels' first arguments."""
        return self.chain, self.tip_rotation, self.lower, self.upper, self.caps


def set_threads(count: int | None) -> int:
    """Set numba's thread count (None: all it has); returns the previous one."""
    previous = numba.get_num_threads()
    limit = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
    numba.set_num_threads(max(1, min(count or limit, limit)))
    return previous


# ----- kinematics -------------------------------------------------------------------------------
@njit(cache=True)
def _pose_frames(q, chain, tip_rot, rots, origins, axes, point, rot):
    """Every joint frame (``rots`` (k, 3, 3), ``origins`` (k, 3) [m], world ``axes`` (k, 3))
    and the end frame (``point`` (3,) [m], ``rot`` (3, 3)) of one pose q (k,), in place."""
    _, _, _, _, _, prismatic, per_unit, mscale, moffset, msi, tip_t, tip_axis = chain
    k = len(q)
    a, b, c, d, e, f, g, h, o = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    p0 = p1 = p2 = 0.0
    for j in range(k):
        q_urdf = (q[j] * mscale[j] + moffset[j]) * msi[j]
        if prismatic[j]:
            sn = cs = 0.0
        else:
            sn, cosine = _sin_cos(q_urdf)
            cs = 1.0 - cosine
        (a, b, c, d, e, f, g, h, o, p0, p1, p2, w0, w1, w2) = joint_step(
            chain, j, q_urdf, sn, cs, a, b, c, d, e, f, g, h, o, p0, p1, p2)
        axes[j, 0], axes[j, 1], axes[j, 2] = w0, w1, w2
        origins[j, 0], origins[j, 1], origins[j, 2] = p0, p1, p2
        rots[j, 0, 0], rots[j, 0, 1], rots[j, 0, 2] = a, b, c
        rots[j, 1, 0], rots[j, 1, 1], rots[j, 1, 2] = d, e, f
        rots[j, 2, 0], rots[j, 2, 1], rots[j, 2, 2] = g, h, o
    t0, t1, t2 = tip_t[0], tip_t[1], tip_t[2]
    point[0] = p0 + a * t0 + b * t1 + c * t2
    point[1] = p1 + d * t0 + e * t1 + f * t2
    point[2] = p2 + g * t0 + h * t1 + o * t2
    for col in range(3):
        r0, r1, r2 = tip_rot[0, col], tip_rot[1, col], tip_rot[2, col]
        rot[0, col] = a * r0 + b * r1 + c * r2
        rot[1, col] = d * r0 + e * r1 + f * r2
        rot[2, col] = g * r0 + h * r1 + o * r2


@njit(cache=True)
def _segments(caps, rots, origins, segs):
    """World end centres ``segs`` (C, 2, 3) [m] of the capsules from the joint frames."""
    joint, a, b = caps[0], caps[1], caps[2]
    for c in range(len(joint)):
        j = joint[c]
        for r in range(3):
            if j < 0:
                segs[c, 0, r] = a[c, r]
                segs[c, 1, r] = b[c, r]
            else:
                segs[c, 0, r] = origins[j, r] + (rots[j, r, 0] * a[c, 0] + rots[j, r, 1] * a[c, 1]
                                                 + rots[j, r, 2] * a[c, 2])
                segs[c, 1, r] = origins[j, r] + (rots[j, r, 0] * b[c, 0] + rots[j, r, 1] * b[c, 1]
                                                 + rots[j, r, 2] * b[c, 2])


@njit(cache=True)
def _distances(caps, segs, below, d, p1, p2, nrm):
    """Every pair's signed distance [m] (pairs above ``below`` [m] hold a lower bound)."""
    pair_distances(segs, caps[3], caps[4], caps[5], caps[6], caps[7], caps[8], caps[9],
                   caps[10], caps[11], caps[12], below, d, p1, p2, nrm)


@njit(cache=True)
def _so3_log(E, out):
    """out (3,) = log(E) [rad] of a rotation matrix (as :func:`ikbench.core.rotations.so3_log`)."""
    trace = E[0, 0] + E[1, 1] + E[2, 2]
    v0 = 0.5 * (E[2, 1] - E[1, 2])
    v1 = 0.5 * (E[0, 2] - E[2, 0])
    v2 = 0.5 * (E[1, 0] - E[0, 1])
    sin = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    theta = math.atan2(sin, 0.5 * (trace - 1.0))
    if theta < SMALL_ANGLE:
        factor = 1.0 + theta * theta / 6.0
    else:
        factor = theta / (sin + 1e-300)
    out[0], out[1], out[2] = v0 * factor, v1 * factor, v2 * factor
    if theta > math.pi - 1e-3:  # the axis from the symmetric part
        c = math.cos(theta)
        best, kbest = -1e300, 0
        for kk in range(3):
            value = (E[kk, kk] - c) / (1.0 - c)
            if value > best:
                best, kbest = value, kk
        ax = np.empty(3)
        for col in range(3):
            sym = 0.5 * (E[kbest, col] + E[col, kbest]) - (c if col == kbest else 0.0)
            ax[col] = sym / (1.0 - c)
        norm = math.sqrt(ax[0] ** 2 + ax[1] ** 2 + ax[2] ** 2)
        sign = -1.0 if ax[0] * v0 + ax[1] * v1 + ax[2] * v2 < 0 else 1.0
        for col in range(3):
            out[col] = ax[col] / norm * sign * theta


@njit(cache=True)
def _pose_error(chain, point, rot, axes, origins, goal_p, goal_R, exact, derivatives, e, J):
    """Errors e (6,) [mm, deg] (position, log(R_goal^T R)) and (``derivatives``) their
    Jacobian J (6, k) per pose unit (``exact``: with Jr^-1), as
    :func:`.frames.errors_from_frames`."""
    prismatic, per_unit = chain[5], chain[6]
    k = axes.shape[0]
    E = np.empty((3, 3))
    for r in range(3):
        e[r] = point[r] * MM_PER_M - goal_p[r]
        for col in range(3):
            E[r, col] = (goal_R[0, r] * rot[0, col] + goal_R[1, r] * rot[1, col]
                         + goal_R[2, r] * rot[2, col])
    phi = np.empty(3)
    _so3_log(E, phi)
    for r in range(3):
        e[3 + r] = phi[r] * DEG_PER_RAD
    if not derivatives:
        return
    for j in range(k):
        w0, w1, w2 = axes[j, 0], axes[j, 1], axes[j, 2]
        s = per_unit[j]
        if prismatic[j]:
            J[0, j], J[1, j], J[2, j] = w0 * s * MM_PER_M, w1 * s * MM_PER_M, w2 * s * MM_PER_M
            J[3, j] = J[4, j] = J[5, j] = 0.0
            continue
        d0 = point[0] - origins[j, 0]
        d1 = point[1] - origins[j, 1]
        d2 = point[2] - origins[j, 2]
        J[0, j] = (w1 * d2 - w2 * d1) * s * MM_PER_M
        J[1, j] = (w2 * d0 - w0 * d2) * s * MM_PER_M
        J[2, j] = (w0 * d1 - w1 * d0) * s * MM_PER_M
        for r in range(3):  # R^T w: the end frame's axes
            J[3 + r, j] = (rot[0, r] * w0 + rot[1, r] * w1 + rot[2, r] * w2) * s * DEG_PER_RAD
    if exact:
        theta = math.sqrt(phi[0] ** 2 + phi[1] ** 2 + phi[2] ** 2)
        if theta < 1e-2:
            coef = 1.0 / 12.0 + theta ** 2 / 720.0 + theta ** 4 / 30240.0
        else:
            safe = min(theta, 3.0)
            coef = 1.0 / safe ** 2 - (1.0 + math.cos(safe)) / (2.0 * safe * math.sin(safe))
        K = np.zeros((3, 3))
        K[0, 1], K[0, 2], K[1, 2] = -phi[2], phi[1], -phi[0]
        K[1, 0], K[2, 0], K[2, 1] = phi[2], -phi[1], phi[0]
        M = np.empty((3, 3))
        for r in range(3):
            for col in range(3):
                kk = K[r, 0] * K[0, col] + K[r, 1] * K[1, col] + K[r, 2] * K[2, col]
                M[r, col] = (1.0 if r == col else 0.0) + 0.5 * K[r, col] + coef * kk
        for j in range(k):
            x0, x1, x2 = J[3, j], J[4, j], J[5, j]
            for r in range(3):
                J[3 + r, j] = M[r, 0] * x0 + M[r, 1] * x1 + M[r, 2] * x2


@njit(cache=True)
def _workspace(k, n_caps, n_pairs):
    """Scratch arrays of one pose's frames, errors and pair distances."""
    return (np.empty((k, 3, 3)), np.empty((k, 3)), np.empty((k, 3)), np.empty(3),
            np.empty((3, 3)), np.empty(6), np.empty((6, k)), np.empty((n_caps, 2, 3)),
            np.empty(n_pairs), np.empty((n_pairs, 3)), np.empty((n_pairs, 3)),
            np.empty((n_pairs, 3)), np.empty(k))


# ----- carrying ---------------------------------------------------------------------------------
@njit(cache=True)
def _solve6(A, rhs, out):
    """out = A^-1 rhs for a symmetric positive definite A (6, 6) (Cholesky); A is destroyed."""
    n = A.shape[0]
    for j in range(n):
        s = A[j, j]
        for m in range(j):
            s -= A[j, m] * A[j, m]
        s = math.sqrt(s)
        A[j, j] = s
        for i in range(j + 1, n):
            t = A[i, j]
            for m in range(j):
                t -= A[i, m] * A[j, m]
            A[i, j] = t / s
    for i in range(n):
        t = rhs[i]
        for m in range(i):
            t -= A[i, m] * out[m]
        out[i] = t / A[i, i]
    for i in range(n - 1, -1, -1):
        t = out[i]
        for m in range(i + 1, n):
            t -= A[m, i] * out[m]
        out[i] = t / A[i, i]


@njit(cache=True)
def _redundant_step(e, J, damping, q, lower, upper, motion, step):
    """:func:`.start_search.redundant_step` of one pose: a damped least-squares step to the
    goal plus ``motion`` (k,) projected into the Jacobian's null space; a joint that would pass
    a limit is held and the step solved again, once."""
    k = len(q)
    held = np.zeros(k, dtype=np.bool_)
    A = np.empty((6, 6))
    rhs = np.empty(6)
    x = np.empty(6)
    z = np.empty(k)
    for _ in range(2):
        for r in range(6):
            for c in range(r + 1):
                s = 0.0
                for j in range(k):
                    if not held[j]:
                        s += J[r, j] * J[c, j]
                A[r, c] = s
                A[c, r] = s
            A[r, r] += damping * damping
        for j in range(k):
            z[j] = 0.0 if held[j] else motion[j]
        for r in range(6):  # e + J_f z: both right-hand sides at once
            s = e[r]
            for j in range(k):
                if not held[j]:
                    s += J[r, j] * z[j]
            rhs[r] = s
        _solve6(A, rhs, x)
        passing = False
        for j in range(k):
            v = z[j]
            if not held[j]:
                for r in range(6):
                    v -= J[r, j] * x[r]
            step[j] = v
        for j in range(k):
            if not held[j] and (q[j] + step[j] < lower[j] or q[j] + step[j] > upper[j]):
                held[j] = True
                passing = True
        if not passing:
            break


@njit(cache=True)
def _limit_motion(q, lower, upper, gain, out):
    """:func:`.start_search.limit_avoidance`: -gain half u^3, u = (q - middle) / half."""
    for j in range(len(q)):
        half = 0.5 * (upper[j] - lower[j])
        if not math.isfinite(half):
            out[j] = 0.0
            continue
        u = (q[j] - 0.5 * (upper[j] + lower[j])) / half
        out[j] = -gain * half * u * u * u


@njit(cache=True)
def _avoid_motion(caps, chain, segs, axes, origins, activation_mm, gain, max_step, d, p1, p2, nrm,
                  grad, out):
    """:meth:`.avoidance.Avoidance.motion` of one pose (its frames given): out += a push away
    from every pair closer than ``activation_mm``, capped at ``max_step`` [pose units]."""
    k = len(out)
    motion = np.zeros(k)
    _distances(caps, segs, activation_mm / MM_PER_M, d, p1, p2, nrm)
    for p in range(len(d)):
        dist_mm = d[p] * MM_PER_M
        if not dist_mm < activation_mm:
            continue
        distance_gradient(p, p1, p2, nrm, caps[4], caps[5], caps[6], caps[0], axes, origins,
                          chain[5], chain[6], grad)
        norm2 = 0.0
        for j in range(k):
            grad[j] *= MM_PER_M
            norm2 += grad[j] * grad[j]
        if norm2 > 1e-12:
            for j in range(k):
                motion[j] += gain * (activation_mm - dist_mm) * grad[j] / norm2
    size = 0.0
    for j in range(k):
        size = max(size, abs(motion[j]))
    scale = min(1.0, max_step / max(size, 1e-300))
    for j in range(k):
        out[j] += motion[j] * scale


@njit(cache=True)
def _carry_one(chain, tip_rot, lower, upper, caps, goals_p, goals_R, anchor, direction, length,
               start, avoid, settings, track):
    """Carry ``start`` (k,) from waypoint ``anchor`` over ``length`` waypoints in
    ``direction`` (+1, -1), writing the poses into ``track`` (N, k) at those waypoints; a
    pose lost (error above the drop limit) is held for the rest. Returns the iterations."""
    (iterations_max, retry, drop, damping, limit_gain, activation_mm, carry_gain,
     carry_max) = settings
    k = len(start)
    n_pairs = len(caps[4])
    (rots, origins, axes, point, rot, e, J, segs, d, p1, p2, nrm,
     grad) = _workspace(k, len(caps[0]), n_pairs)
    motion, step, q = np.empty(k), np.empty(k), np.empty(k)
    for j in range(k):
        track[anchor, j] = start[j]
    iterations = 0
    for s in range(1, length):
        i = anchor + direction * s
        prev = i - direction
        for j in range(k):
            if s == 1:
                q[j] = track[prev, j]
            else:
                v = 2.0 * track[prev, j] - track[prev - direction, j]
                q[j] = min(max(v, lower[j]), upper[j])
        for attempt in range(int(iterations_max)):
            _pose_frames(q, chain, tip_rot, rots, origins, axes, point, rot)
            _pose_error(chain, point, rot, axes, origins, goals_p[i], goals_R[i], False, True,
                        e, J)
            size = 0.0
            for r in range(6):
                size = max(size, abs(e[r]))
            if attempt == 0 and size > drop:  # lost: held for the rest
                for rest in range(s, length):
                    at = anchor + direction * rest
                    for j in range(k):
                        track[at, j] = track[prev, j]
                return iterations
            _limit_motion(q, lower, upper, limit_gain, motion)
            if avoid and attempt == 0 and n_pairs:
                _segments(caps, rots, origins, segs)
                _avoid_motion(caps, chain, segs, axes, origins, activation_mm, carry_gain,
                              carry_max, d, p1, p2, nrm, grad, motion)
            _redundant_step(e, J, damping, q, lower, upper, motion, step)
            for j in range(k):
                q[j] = min(max(q[j] + step[j], lower[j]), upper[j])
            iterations += 1
            if size <= retry:
                break
        for j in range(k):
            track[i, j] = q[j]
    return iterations


@njit(cache=True, parallel=True, nogil=True)
def _carry_all(chain, tip_rot, lower, upper, caps, goals_p, goals_R, anchors, directions,
               lengths, starts, avoid, settings, tracks, iterations, threads):
    t_count = len(anchors)
    for t in prange(threads):
        for m in range(t, t_count, threads):
            iterations[m] = _carry_one(chain, tip_rot, lower, upper, caps, goals_p, goals_R,
                                       anchors[m], directions[m], lengths[m], starts[m], avoid,
                                       settings, tracks[m])


def carry_tracks(spec: PathSpec, goals_p: np.ndarray, goals_R: np.ndarray,
                 anchors: np.ndarray, directions: np.ndarray, lengths: np.ndarray,
                 starts: np.ndarray, avoid: bool, settings: np.ndarray,
                 threads: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Carry ``starts`` (T, k) [pose units], each from its anchor waypoint over ``lengths[t]``
    waypoints in ``directions[t]`` (+1 or -1), along the goals (N, 3) [mm] and (N, 3, 3).

    ``settings``: (iterations, retry [mm or deg], drop [mm or deg], damping [mm],
    limit-avoidance gain, activation [mm], collision gain, largest avoidance step [pose
    units]) as :mod:`.start_search` and :mod:`.avoidance` name them; ``avoid``: push away from
    close pairs of the scene.

    Returns:
        (tracks (T, N, k) with NaN where a track was not carried, iterations (T,)).
    """
    t_count, k = starts.shape
    tracks = np.full((t_count, len(goals_p), k), np.nan)
    iterations = np.zeros(t_count, dtype=np.int64)
    if not t_count:
        return tracks, iterations
    count = max(1, min(numba.get_num_threads(), t_count))
    _carry_all(*spec.args(), np.ascontiguousarray(goals_p, dtype=float),  # type: ignore[call-arg]
               np.ascontiguousarray(goals_R, dtype=float), np.asarray(anchors, dtype=np.int64),
               np.asarray(directions, dtype=np.int64), np.asarray(lengths, dtype=np.int64),
               np.ascontiguousarray(starts, dtype=float), bool(avoid),
               np.asarray(settings, dtype=float), tracks, iterations, count)
    return tracks, iterations


# ----- nodes and the stitch ---------------------------------------------------------------------
@njit(cache=True)
def _nodes_one(chain, tip_rot, caps, goals_p, goals_R, track, reached, node):
    n_pairs = len(caps[4])
    (rots, origins, axes, point, rot, e, J, segs, d, p1, p2, nrm,
     _) = _workspace(track.shape[1], len(caps[0]), n_pairs)
    for i in range(track.shape[0]):
        node[i] = False
        if math.isnan(track[i, 0]):
            continue
        _pose_frames(track[i], chain, tip_rot, rots, origins, axes, point, rot)
        _pose_error(chain, point, rot, axes, origins, goals_p[i], goals_R[i], False, False, e, J)
        size = 0.0
        for r in range(6):
            size = max(size, abs(e[r]))
        if not size < reached:
            continue
        free = True
        if n_pairs:
            _segments(caps, rots, origins, segs)
            _distances(caps, segs, 0.0, d, p1, p2, nrm)
            for p in range(n_pairs):
                if not d[p] > 0.0:
                    free = False
                    break
        node[i] = free


@njit(cache=True, parallel=True, nogil=True)
def _nodes_all(chain, tip_rot, caps, goals_p, goals_R, tracks, reached, node, threads):
    m = tracks.shape[0]
    for t in prange(threads):
        for r in range(t, m, threads):
            _nodes_one(chain, tip_rot, caps, goals_p, goals_R, tracks[r], reached, node[r])


def track_nodes(spec: PathSpec, goals_p: np.ndarray, goals_R: np.ndarray, tracks: np.ndarray,
                reached: float) -> np.ndarray:
    """(M, N) True where a carried pose of ``tracks`` (M, N, k) (NaN: not carried) is within
    ``reached`` [mm or deg] of its goal and every pair's distance is above 0."""
    node = np.zeros(tracks.shape[:2], dtype=np.bool_)
    if not len(tracks):
        return node
    count = max(1, min(numba.get_num_threads(), len(tracks)))
    _nodes_all(spec.chain, spec.tip_rotation, spec.caps, np.ascontiguousarray(goals_p),
               np.ascontiguousarray(goals_R), np.ascontiguousarray(tracks), float(reached),
               node, count)
    return node


@njit(cache=True, inline="always")
def _joint_step(a, b, period):
    """|b - a|, or for a joint that turns round (``period`` > 0 [pose units]) the shorter way."""
    step = abs(b - a)
    if period > 0.0:
        step = step % period
        step = min(step, period - step)
    return step


@njit(cache=True, inline="always")
def _edge(tracks, i, a, b, base, weights, max_step, period, jump_cost, best):
    """The cost to waypoint i's node on track b through i - 1's on track a (``base``: that
    node's cost), or a partial sum at least ``best`` once it reaches it."""
    total = 0.0
    excess = 0.0
    for j in range(tracks.shape[2]):
        step = _joint_step(tracks[a, i - 1, j], tracks[b, i, j], period[j])
        total += weights[j] * step
        excess += max(step - max_step[j], 0.0)
        if base + total + jump_cost * excess > best:
            break
    return base + total + jump_cost * excess


@njit(cache=True)
def _stitch(tracks, node, weights, max_step, period, jump_cost, choice):
    """The DP of :func:`.start_search.stitch` (weighted length plus ``jump_cost`` per pose unit
    of a step beyond ``max_step``): ``choice`` (N,) the track of each waypoint's node (-1
    everywhere when a waypoint has none); returns the path's cost. Ties go to the lower
    track index, as numpy's argmin."""
    m, n, k = tracks.shape
    # the nodes of each waypoint, in track order: ids[start[i]:start[i + 1]]
    start = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        count = 0
        for r in range(m):
            if node[r, i]:
                count += 1
        if count == 0:
            choice[:] = -1
            return np.inf
        start[i + 1] = start[i] + count
    ids = np.empty(start[n], dtype=np.int64)
    for i in range(n):
        c = start[i]
        for r in range(m):
            if node[r, i]:
                ids[c] = r
                c += 1
    cost = np.zeros(start[n])
    back = np.full(start[n], -1, dtype=np.int64)
    for i in range(1, n):
        lo, hi = start[i - 1], start[i]
        # predecessors by cost (ties by track): once one costs more than the best found, so
        # do the rest
        order = lo + np.argsort(cost[lo:hi], kind="mergesort")
        same = lo
        for c in range(start[i], start[i + 1]):
            b = ids[c]
            best, arg = np.inf, -1
            while same < hi and ids[same] < b:   # the same track first: it usually continues best
                same += 1
            if same < hi and ids[same] == b:
                best = _edge(tracks, i, b, b, cost[same], weights, max_step, period,
                             jump_cost, np.inf)
                arg = same
            for o in order:
                base = cost[o]
                if base > best:
                    break
                if o == arg:
                    continue
                value = _edge(tracks, i, ids[o], b, base, weights, max_step, period, jump_cost,
                              best)
                if value < best or (value == best and ids[o] < ids[arg]):
                    best, arg = value, o
            cost[c] = best
            back[c] = arg
    lo, hi = start[n - 1], start[n]
    arg = lo
    for c in range(lo, hi):
        if cost[c] < cost[arg]:
            arg = c
    best = cost[arg]
    for i in range(n - 1, -1, -1):
        choice[i] = ids[arg]
        if i:
            arg = back[arg]
    return best


def stitch_path(tracks: np.ndarray, node: np.ndarray, weights: np.ndarray,
                max_step: np.ndarray, jump_cost: float, period: np.ndarray | None = None
                ) -> np.ndarray | None:
    """The stitched path (N, k) through the nodes (see :func:`_stitch`), None without one;
    ``period`` (k,) [pose units]: joints that turn round (> 0) step the shorter way (the path
    is returned as the nodes are, not unwrapped)."""
    choice = stitch_choice(tracks, node, weights, max_step, jump_cost, period)
    return None if choice is None else tracks[choice, np.arange(tracks.shape[1])]


def stitch_choice(tracks: np.ndarray, node: np.ndarray, weights: np.ndarray,
                  max_step: np.ndarray, jump_cost: float, period: np.ndarray | None = None
                  ) -> np.ndarray | None:
    """:func:`stitch_path`'s track at each waypoint (N,), None without a path."""
    choice = np.empty(tracks.shape[1], dtype=np.int64)
    turn = np.zeros(tracks.shape[2]) if period is None else np.asarray(period, dtype=float)
    _stitch(np.ascontiguousarray(tracks), np.ascontiguousarray(node),
            np.asarray(weights, dtype=float), np.asarray(max_step, dtype=float), turn,
            float(jump_cost), choice)
    return None if choice[0] < 0 else choice


# ----- the pose-path LM -------------------------------------------------------------------------
@njit(cache=True)
def _evaluate(chain, tip_rot, caps, goals_p, goals_R, x, c, collision, derivatives, terms,
              grad, diag, ws):
    """The 6-D objective plus the clearance penalty at poses x (N, k) (as
    :func:`.frames.evaluate_frames` with :meth:`.avoidance.Avoidance.terms`): returns the
    loss, writes ``terms`` (7,) and (``derivatives``) the gradient J^T r (N, k) and the
    diagonal blocks (N, k, k); ``c`` = (c0, c1, c6), ``collision`` = (clearance [mm], self
    clearance [mm], weight)."""
    n, k = x.shape
    (rots, origins, axes, point, rot, e, J, segs, d, p1, p2, nrm, g) = ws
    n_pairs = len(caps[4])
    a0, a1, a6 = c[0] / (3 * n), c[1] / (3 * n), c[2] / ((n - 1) * k)
    clearance, self_clearance, weight = collision[0], collision[1], collision[2]
    scale = weight / n
    sq_p = sq_r = sq_s = 0.0
    penalty = 0.0
    for i in range(n):
        _pose_frames(x[i], chain, tip_rot, rots, origins, axes, point, rot)
        _pose_error(chain, point, rot, axes, origins, goals_p[i], goals_R[i], True, derivatives,
                    e, J)
        for r in range(3):
            sq_p += e[r] * e[r]
            sq_r += e[3 + r] * e[3 + r]
        if derivatives:
            for p in range(k):
                grad[i, p] = 0.0
                for r in range(3):
                    grad[i, p] += a0 * J[r, p] * e[r] + a1 * J[3 + r, p] * e[3 + r]
                for qq in range(p + 1):
                    v = 0.0
                    for r in range(3):
                        v += a0 * J[r, p] * J[r, qq] + a1 * J[3 + r, p] * J[3 + r, qq]
                    diag[i, p, qq] = v
                    diag[i, qq, p] = v
        if n_pairs and weight > 0.0:
            _segments(caps, rots, origins, segs)
            _distances(caps, segs, clearance / MM_PER_M, d, p1, p2, nrm)
            for p in range(n_pairs):
                margin = clearance if caps[6][p] else min(clearance, self_clearance)
                dist_mm = d[p] * MM_PER_M
                if not dist_mm < margin:
                    continue
                violation = margin - dist_mm
                penalty += scale * violation * violation
                if derivatives:
                    distance_gradient(p, p1, p2, nrm, caps[4], caps[5], caps[6], caps[0], axes,
                                      origins, chain[5], chain[6], g)
                    for a in range(k):
                        ga = g[a] * MM_PER_M
                        grad[i, a] -= scale * violation * ga
                        for b in range(k):
                            diag[i, a, b] += scale * ga * g[b] * MM_PER_M
    for j in range(k):
        for i in range(n - 1):
            step = x[i + 1, j] - x[i, j]
            sq_s += step * step
            if derivatives:
                grad[i, j] -= a6 * step
                grad[i + 1, j] += a6 * step
    if derivatives:
        for i in range(n):
            degree = 1.0 if i == 0 or i == n - 1 else 2.0
            for p in range(k):
                diag[i, p, p] += a6 * degree
    for t in range(7):
        terms[t] = 0.0
    terms[0] = sq_p / (3 * n)
    terms[1] = sq_r / (3 * n)
    terms[6] = sq_s / ((n - 1) * k)
    return c[0] * terms[0] + c[1] * terms[1] + c[2] * terms[6] + penalty


@njit(cache=True)
def _check(chain, tip_rot, lower, upper, caps, goals_p, goals_R, x, margin, limits, ws, out):
    """:func:`.start_search.check_paths` of one path x (N, k): returns valid; ``out`` (3,)
    the largest position error [mm], rotation error [deg] and revolute step [deg].
    ``limits`` = (position [mm], rotation [deg], revolute step [deg], prismatic step [mm])."""
    n, k = x.shape
    (rots, origins, axes, point, rot, e, J, segs, d, p1, p2, nrm, g) = ws
    prismatic, mscale, moffset, msi = chain[5], chain[7], chain[8], chain[9]
    n_pairs = len(caps[4])
    position = rotation = revolute = sliding = 0.0
    within = True
    for i in range(n):
        _pose_frames(x[i], chain, tip_rot, rots, origins, axes, point, rot)
        _pose_error(chain, point, rot, axes, origins, goals_p[i], goals_R[i], False, False, e, J)
        position = max(position, math.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2))
        rotation = max(rotation, math.sqrt(e[3] ** 2 + e[4] ** 2 + e[5] ** 2))
        for j in range(k):
            if x[i, j] < lower[j] - 1e-9 or x[i, j] > upper[j] + 1e-9:
                within = False
            if i:
                a = (x[i, j] * mscale[j] + moffset[j]) * msi[j]
                b = (x[i - 1, j] * mscale[j] + moffset[j]) * msi[j]
                if prismatic[j]:
                    sliding = max(sliding, abs(a - b) * MM_PER_M)
                else:
                    wrapped = abs(((a - b + math.pi) % (2.0 * math.pi)) - math.pi)
                    revolute = max(revolute, wrapped * DEG_PER_RAD)
    out[0], out[1], out[2] = position, rotation, revolute
    valid = (position < margin * limits[0] and rotation < margin * limits[1]
             and revolute < limits[2] and sliding < limits[3] and within)
    if valid and n_pairs:
        for i in range(n):
            _pose_frames(x[i], chain, tip_rot, rots, origins, axes, point, rot)
            _segments(caps, rots, origins, segs)
            _distances(caps, segs, 0.0, d, p1, p2, nrm)
            for p in range(n_pairs):
                if d[p] < 0.0:
                    return False
    return valid


def check_path(spec: PathSpec, goals_p: np.ndarray, goals_R: np.ndarray, poses: np.ndarray,
               margin: float, limits: np.ndarray) -> tuple[bool, np.ndarray]:
    """(valid, (largest position error [mm], rotation error [deg], revolute step [deg])) of
    poses (N, k); see :func:`_check`."""
    out = np.zeros(3)
    ws = _workspace(spec.dof, len(spec.caps[0]), spec.n_pairs)
    valid = _check(*spec.args(), np.ascontiguousarray(goals_p),  # type: ignore[call-arg]
                   np.ascontiguousarray(goals_R),
                   np.ascontiguousarray(poses, dtype=float), float(margin),
                   np.asarray(limits, dtype=float), ws, out)
    return bool(valid), out


@njit(cache=True, nogil=True)
def _solve_path(chain, tip_rot, lower, upper, caps, goals_p, goals_R, x, c, collision,
                max_iterations, tolerance, lam, margin, limits, mode, terms, out):
    """The LM loop of :func:`.solver.solve_batch` on one pose path x (N, k) (updated in place),
    with ``until`` = :func:`_check`. ``mode`` 0: stop at the first valid iterate (as the
    numpy search); 1: run to the stopping rule and return the last valid iterate (else the
    last one); 2: run to the stopping rule, validity not checked (valid: False). Returns
    (loss, iterations, converged, valid)."""
    n, k = x.shape
    n_caps, n_pairs = len(caps[0]), len(caps[4])
    ws = _workspace(k, n_caps, n_pairs)
    kt = np.zeros(k)
    grad, diag = np.empty((n, k)), np.empty((n, k, k))
    tgrad, tdiag = np.empty((n, k)), np.empty((n, k, k))
    trial, step, free = np.empty((n, k)), np.empty((n, k)), np.empty((n, k))
    band, rhs = np.empty((n * k, k + 1)), np.empty(n * k)
    tterms = np.empty(7)
    best = np.empty((n, k))
    best_terms = np.empty(7)
    a6 = c[2] / ((n - 1) * k)
    for i in range(n):
        for j in range(k):
            x[i, j] = min(max(x[i, j], lower[j]), upper[j])
    loss = _evaluate(chain, tip_rot, caps, goals_p, goals_R, x, c, collision, True, terms, grad,
                     diag, ws)
    best_loss = loss
    have_valid = False
    checked = False  # the current iterate's validity is known (numpy: ``until`` after a step)
    if mode == 1:
        checked = True
        if _check(chain, tip_rot, lower, upper, caps, goals_p, goals_R, x, margin, limits, ws,
                  out):
            have_valid = True
            best[:, :] = x
            best_terms[:] = terms
    nu = 2.0
    iterations = 0
    converged = False
    while True:
        ok, largest, predicted = _damped_trial(x, grad, diag, a6, lower, upper, free, lam,
                                               band, rhs, step, trial, kt)
        new_loss = _evaluate(chain, tip_rot, caps, goals_p, goals_R, trial, c, collision, True,
                             tterms, tgrad, tdiag, ws)
        iterations += 1
        lam, nu, accept, small, stuck, converged = _damping_update(
            ok, predicted, loss, new_loss, largest, tolerance, lam, nu, grad, free, kt)
        reached = False
        if accept:
            x[:, :] = trial
            grad, tgrad = tgrad, grad
            diag, tdiag = tdiag, diag
            terms[:] = tterms
            loss = new_loss
            checked = False
        if not checked and mode != 2:
            checked = True
            if _check(chain, tip_rot, lower, upper, caps, goals_p, goals_R, x, margin, limits,
                      ws, out):
                reached = True
                have_valid = True
                best[:, :] = x
                best_terms[:] = terms
                best_loss = loss
        if mode == 0 and reached:
            return loss, iterations, True, True
        if small or stuck or iterations >= max_iterations:
            if mode == 1 and have_valid:
                x[:, :] = best
                terms[:] = best_terms
                _check(chain, tip_rot, lower, upper, caps, goals_p, goals_R, x, margin, limits,
                       ws, out)
                return best_loss, iterations, converged, True
            return loss, iterations, converged, False


def solve_path(spec: PathSpec, goals_p: np.ndarray, goals_R: np.ndarray, initial: np.ndarray,
               weights: np.ndarray, collision: np.ndarray, max_iterations: int,
               tolerance: float, damping: float, margin: float, limits: np.ndarray,
               mode: int = 0) -> tuple[np.ndarray, float, np.ndarray, int, bool, bool,
                                       np.ndarray]:
    """LM on one pose path from ``initial`` (N, k) (see :func:`_solve_path`: ``mode`` 0 stops
    at the first valid iterate, 1 returns the last valid one, 2 does not check validity):
    ``weights`` = (c0, c1, c6), ``collision`` = (clearance [mm], self clearance [mm], weight;
    weight 0: no penalty), ``limits`` as :func:`_check`'s.

    Returns:
        (poses (N, k), loss, terms (7,), iterations, converged, valid, (largest position error
        [mm], rotation error [deg], revolute step [deg])).
    """
    x = np.array(initial, dtype=float, order="C")
    terms, out = np.zeros(7), np.zeros(3)
    loss, iterations, converged, valid = _solve_path(  # type: ignore[call-arg]
        *spec.args(), np.ascontiguousarray(goals_p, dtype=float),
        np.ascontiguousarray(goals_R, dtype=float), x, np.asarray(weights, dtype=float),
        np.asarray(collision, dtype=float), int(max_iterations), float(tolerance),
        float(damping), float(margin), np.asarray(limits, dtype=float), int(mode), terms, out)
    return x, float(loss), terms, int(iterations), bool(converged), bool(valid), out
