"""Start search for 6-D pose paths: no start pose is given, so finding one is part of the task.

A 7-DoF arm reaches each pose in infinitely many ways; the path is solved by:

1. **Seeds**: IK for the first waypoint from the task's reference (home) pose and
   ``ik_seeds - 1`` poses drawn uniformly within the task's limits (``numpy`` generator seeded
   with ``seed``), by damped least squares with an adaptive damping, all seeds at once;
   converged seeds that coincide (within 1 deg) are merged.
2. **Carry**: each seed is carried along the path, waypoint by waypoint, each solve warm
   started from the previous waypoint's (minimum-norm damped least-squares steps with
   joint-limit avoidance in the null space, :func:`carry`), all seeds at once. Candidates are
   ranked by the waypoints they lost, then by whether a step reaches CppFlow's 7 deg, then by
   their joint path length.
3. **Refine**: the ``refine`` best candidates are refined together by the LM solver on the
   6-D objective with the smoothness term (:mod:`.frames`, default weights
   :data:`ikbench.core.losses.FRAME_WEIGHTS`) until one meets CppFlow's criteria
   (:mod:`ikbench.core.validity`) with its pose errors below :data:`SEARCH_MARGIN` of the
   thresholds; the valid one with the lowest loss is kept. When none gets there, the next
   ``refine`` candidates are tried, and so on; failing all, the lowest-loss one is returned.

With obstacles (a task's ``obstacles`` and the robot's collision model), the candidates come
from :func:`stitched_candidates` instead of step 2: paths carried from both ends (and, where
needed, from waypoints along the path) with a push away from close pairs in the null space,
stitched together where they meet into one collision-free path; the LM objective gains a
clearance penalty (:mod:`.avoidance`) and a valid path must be collision-free. Without
obstacles nothing changes.

Everything is deterministic for a seed. Errors are in mm and degrees throughout.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ikbench.core.errors import InputError
from ikbench.core.validity import (
    MAX_JOINT_CHANGE_DEG,
    MAX_JOINT_CHANGE_MM,
    MAX_POSITION_ERROR_MM,
    MAX_ROTATION_ERROR_DEG,
)
from ikbench.methods.ours_lm.avoidance import Avoidance, avoidance_for
from ikbench.methods.ours_lm.devices import cpu_backend
from ikbench.methods.ours_lm.frames import FrameProblem, errors_from_frames, evaluate_frames
from ikbench.methods.ours_lm.search_common import (  # noqa: F401  (moved; re-exported)
    AVOIDANCE_GAIN,
    CARRY_DAMPING,
    CARRY_ITERATIONS,
    CARRY_RETRY,
    DROP_MM_DEG,
    DUPLICATE_DEG,
    IK_ITERATIONS,
    IK_MAX_STEP,
    IK_STALLED,
    IK_TOLERANCE,
    SEARCH_MARGIN,
    STITCH_JUMP_COST,
    STITCH_MAX_STEP,
    STITCH_REACHED,
    STITCH_STEP_SHARE,
    OursLMSettings,
    SearchResult,
    _dls,
    _stack,
    distinct,
    first_waypoint_ik,
    stitch_costs,
)
from ikbench.methods.ours_lm.solver import solve_batch

if TYPE_CHECKING:
    from ikbench.core.kinematics.chain import Frames
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task

#: A carried waypoint further than this from its goal [mm or deg] counts as lost.
LOST_MM_DEG = 5.0
#: Seeds whose first-waypoint error is below this [mm and deg] are carried.
SEED_TOLERANCE = 1e-3
#: Carried candidates refined at most, when the task has obstacles.
OBSTACLE_MAX_REFINED = 8














def limit_avoidance(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Joint motion (K, dof) [pose units] away from the limits, for the null space: with
    u = (q - middle) / half-range in [-1, 1], -:data:`AVOIDANCE_GAIN` half-range u^3 (small in
    the middle of the range, strong near a limit)."""
    bounded = np.isfinite(lower) & np.isfinite(upper)  # a continuous joint has +-inf
    middle = 0.5 * (np.where(bounded, upper, 0.0) + np.where(bounded, lower, 0.0))
    half = 0.5 * (upper - lower)
    half = np.where(bounded, half, 1.0)
    u = np.where(bounded, (q - np.where(bounded, middle, 0.0)) / half, 0.0)
    return -AVOIDANCE_GAIN * half * u**3


def redundant_step(e: np.ndarray, J: np.ndarray, damping: float, q: np.ndarray,
                   lower: np.ndarray, upper: np.ndarray, extra: np.ndarray | None = None
                   ) -> np.ndarray:
    """A damped least-squares step (K, dof) towards the goal plus the limit-avoidance motion
    (and ``extra`` (K, dof), e.g. collision avoidance) projected into the Jacobian's null
    space; a joint that would pass a limit is held (its column removed) and the step solved
    again, once."""
    held = np.zeros(q.shape, dtype=bool)
    motion = limit_avoidance(q, lower, upper) + (0.0 if extra is None else extra)
    for _ in range(2):
        Jf = J * ~held[:, None, :]
        JJt = Jf @ Jf.swapaxes(-1, -2) + damping**2 * np.eye(J.shape[-2])
        pinv = Jf.swapaxes(-1, -2) @ np.linalg.inv(JJt)                  # (K, dof, 6)
        z = motion * ~held
        step = -(pinv @ e[..., None])[..., 0] + z - (pinv @ (Jf @ z[..., None]))[..., 0]
        passing = ((q + step < lower) | (q + step > upper)) & ~held
        if not passing.any():
            break
        held |= passing
    return step


def carry(frames: Callable[..., Frames], task: Task, start: np.ndarray, lower: np.ndarray,
          upper: np.ndarray, avoid: Avoidance | None = None) -> tuple[np.ndarray, int]:
    """Carry start poses (K, dof) along the task's waypoints, each warm started from the last.

    Waypoint i starts from the linear extrapolation 2 q_{i-1} - q_{i-2} (the previous pose at
    i = 1) and takes one :func:`redundant_step` (damped least squares, limit avoidance and,
    with ``avoid``, collision avoidance in the null space); a pose whose error before the step
    exceeded :data:`CARRY_RETRY` (mm or deg), e.g. at a corner of the path, takes another (at
    most :data:`CARRY_ITERATIONS` in all). The LM refinement polishes what is left.

    Returns:
        (paths (K, N, dof), iterations).
    """
    goals_mm, goals_R = task.goal.points_mm, cast(np.ndarray, task.goal.rotations)  # a pose path
    k, dof = start.shape
    paths = np.repeat(start[:, None], len(goals_mm), axis=1)
    alive = np.arange(k)
    iterations = 0
    for i in range(1, len(goals_mm)):
        q = paths[alive, i - 1] if i == 1 else np.clip(
            2 * paths[alive, i - 1] - paths[alive, i - 2], lower, upper)
        todo = np.arange(len(alive))          # the poses still stepping at this waypoint
        for attempt in range(CARRY_ITERATIONS):
            point, rotation, j_point, j_angular = frames(q[todo])
            e, J = _stack(*errors_from_frames(point, rotation, j_point, j_angular, goals_mm[i],
                                              goals_R[i], exact=False))
            size = np.abs(e).max(1)
            if attempt == 0 and np.any(size > DROP_MM_DEG):     # lost: carried no further
                keep = size <= DROP_MM_DEG
                paths[alive[~keep], i:] = paths[alive[~keep], i - 1, None]
                alive, q, e, J, size = alive[keep], q[keep], e[keep], J[keep], size[keep]
                todo = np.arange(len(alive))
                if not alive.size:
                    return paths, iterations
            extra = avoid.motion(q) if avoid is not None and attempt == 0 else None
            q[todo] = np.clip(q[todo] + redundant_step(e, J, CARRY_DAMPING, q[todo], lower,
                                                       upper, extra), lower, upper)
            iterations += 1
            todo = todo[size > CARRY_RETRY]
            if not todo.size:
                break
        paths[alive, i] = q
    return paths, iterations


def lost_waypoints(frames: Callable[..., Frames], task: Task, paths: np.ndarray) -> np.ndarray:
    """(K,) waypoints of carried paths (K, N, dof) whose error exceeds :data:`LOST_MM_DEG`
    (mm or deg): where a candidate lost track of the path (e.g. held by a joint limit)."""
    k, n, dof = paths.shape
    point, rotation, _, _ = frames(paths.reshape(-1, dof), False)
    e_point, e_rot, _, _ = errors_from_frames(
        point, rotation, None, None, np.tile(task.goal.points_mm, (k, 1)),
        np.tile(cast(np.ndarray, task.goal.rotations), (k, 1, 1)))
    size = np.maximum(np.abs(e_point).max(-1), np.abs(e_rot).max(-1)).reshape(k, n)
    return np.sum(size > LOST_MM_DEG, axis=1)


def check_paths(robot: Robot, task: Task, paths: np.ndarray, frames: Callable[..., Frames],
                margin: float = 1.0, avoid: Avoidance | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """CppFlow's validity of paths (K, N, dof): (valid (K,), max position error [mm],
    max rotation error [deg], max revolute step [deg]) (see :mod:`ikbench.core.validity`);
    ``margin`` scales the position and rotation thresholds; with ``avoid`` a valid path is
    also collision-free."""
    point, rotation, _, _ = frames(paths.reshape(-1, robot.dof), False)
    e_point, e_rot, _, _ = errors_from_frames(
        point, rotation, None, None, np.tile(task.goal.points_mm, (len(paths), 1)),
        np.tile(cast(np.ndarray, task.goal.rotations), (len(paths), 1, 1)))
    position = np.linalg.norm(e_point, axis=1).reshape(len(paths), -1).max(1)
    rotation = np.linalg.norm(e_rot, axis=1).reshape(len(paths), -1).max(1)
    q = robot.to_urdf(paths)
    steps = np.diff(q, axis=1)
    prismatic = robot.prismatic
    revolute = np.degrees(np.abs(np.remainder(steps[..., ~prismatic] + np.pi, 2 * np.pi)
                                 - np.pi)).max(axis=(1, 2))
    sliding = np.abs(steps[..., prismatic]).max(axis=(1, 2)) * 1000.0 if prismatic.any() \
        else np.zeros(len(paths))
    lower, upper = task.limits(robot)
    within = np.all((paths >= lower - 1e-9) & (paths <= upper + 1e-9), axis=(1, 2))
    valid = (position < margin * MAX_POSITION_ERROR_MM) \
        & (rotation < margin * MAX_ROTATION_ERROR_DEG) \
        & (revolute < MAX_JOINT_CHANGE_DEG) & (sliding < MAX_JOINT_CHANGE_MM) & within
    if avoid is not None and valid.any():
        valid[valid] = avoid.collision_free(paths[valid])
    return valid, position, rotation, revolute


def search(robot: Robot, task: Task, settings: OursLMSettings, weights: dict) -> SearchResult:
    """Solve a 6-D pose path without a start pose: by the compiled search
    (:mod:`.path_search`) when the numba backend runs and the robot's collision geometry is
    capsules (or it has none), else by the numpy search (see the module docstring)."""
    compiled = _compiled_search(robot, settings)
    if compiled is not None:
        return compiled.search_compiled(robot, task, settings, weights)
    return search_numpy(robot, task, settings, weights)


def warm_up_search(robot: Robot, settings: OursLMSettings) -> None:
    """Compile (or load) the compiled search's kernels when it will run (untimed)."""
    compiled = _compiled_search(robot, settings)
    if compiled is not None:
        compiled.warm_up(robot)


def _compiled_search(robot: Robot, settings: OursLMSettings) -> Any:
    """The :mod:`.path_search` module when it can run for these settings and robot."""

    if settings.device is not None or cpu_backend(settings) != "numba":
        return None
    try:
        path_search = importlib.import_module("ikbench.methods.ours_lm.path_search")
    except ImportError:
        if settings.backend == "numba":
            raise InputError("--lm-backend numba: numba does not import; use --lm-backend "
                             "numpy") from None
        return None
    return path_search if path_search.available(robot) else None


def search_numpy(robot: Robot, task: Task, settings: OursLMSettings, weights: dict
                 ) -> SearchResult:
    """The numpy search (the reference; see the module docstring)."""
    started = time.perf_counter()
    frames = robot.chain_kinematics().frames
    lower, upper = (np.asarray(v, dtype=float) for v in task.limits(robot))
    low = np.where(np.isfinite(lower), lower, robot.sample_lower)
    high = np.where(np.isfinite(upper), upper, robot.sample_upper)
    rng = np.random.default_rng(settings.seed)
    avoid = avoidance_for(robot, task, settings.clearance_mm, settings.collision_weight)
    seeds = rng.uniform(low, high, (settings.ik_seeds, robot.dof))
    if task.hints.reference_pose is not None:
        seeds[0] = task.hints.reference_pose
    q0, pos, rot, ik_iterations = first_waypoint_ik(
        frames, task.goal.points_mm[0], cast(np.ndarray, task.goal.rotations)[0], seeds, lower,
        upper)
    found = distinct(q0, (pos < SEED_TOLERANCE) & (rot < SEED_TOLERANCE))
    if not found.size:
        raise InputError(f"trajectory {task.name!r}: the first waypoint was not reached from "
                         f"any of {settings.ik_seeds} IK seeds (out of reach?); try more "
                         "--lm-ik-seeds or another --lm-seed")
    t_seeds = time.perf_counter()
    stitch_info: dict = {}
    if avoid is None:
        paths, carry_iterations = carry(frames, task, q0[found], lower, upper)
    else:  # carried from several waypoints both ways, stitched where they meet (see stitch)
        paths, carry_iterations, stitch_info = stitched_candidates(
            frames, task, avoid, lower, upper, low, high, rng)
    missed = lost_waypoints(frames, task, paths)
    colliding = avoid.colliding_waypoints(paths) if avoid is not None else np.zeros(len(paths))
    t_carry = time.perf_counter()
    order = _rank(robot, paths, missed, colliding)
    if stitch_info.get("stitched"):  # the stitched path first
        order = np.concatenate([[0], order[order != 0]])
    problem_of = _problem_factory(robot, task, weights, frames)
    evaluator = avoid.evaluator(evaluate_frames) if avoid is not None else evaluate_frames
    lm_settings = replace(settings, weights=weights)
    refined, lm_iterations, best = 0, 0, None
    if avoid is not None:  # a bounded search: colliding candidates rarely refine to valid
        order = order[:OBSTACLE_MAX_REFINED]
    for start in range(0, len(order), settings.refine):
        chosen = order[start:start + settings.refine]
        tasks = [task] * len(chosen)
        result = solve_batch(robot, tasks, lm_settings, [weights] * len(chosen),
                             initial=paths[chosen], problem=problem_of(len(chosen)),
                             evaluator=evaluator,
                             until=lambda poses, _: np.full(len(poses), check_paths(
                                 robot, task, poses, frames, SEARCH_MARGIN, avoid)[0].any()))
        refined += len(chosen)
        lm_iterations += int(result.iterations.max())
        valid, position, rotation, step = check_paths(robot, task, result.poses, frames,
                                                      SEARCH_MARGIN, avoid)
        k = int(np.argmin(np.where(valid, result.loss, np.inf) if valid.any()
                          else result.loss))
        if best is None or valid[k] or result.loss[k] < best[1].loss[best[2]]:
            best = (bool(valid[k]), result, k, position[k], rotation[k], step[k])
        if valid[k]:
            break
    assert best is not None
    is_valid, result, k, position, rotation, step = best
    t_end = time.perf_counter()
    info = {"ik_seeds": settings.ik_seeds, "seeds_reaching_first_waypoint": int(found.size),
            "carried_candidates_missing_waypoints": int(np.sum(missed > 0)),
            "candidates_refined": refined, "lm_iterations": lm_iterations,
            "seed": settings.seed,
            "search_max_position_error_mm": float(position),
            "search_max_rotation_error_deg": float(rotation),
            "search_max_joint_step_deg": float(step),
            "carried_candidates_colliding": int(np.sum(colliding > 0)), **stitch_info,
            "seeds_s": t_seeds - started, "carry_s": t_carry - t_seeds,
            "refine_s": t_end - t_carry}
    return SearchResult(result.poses[k], float(result.loss[k]), result.terms[k],
                        is_valid, ik_iterations + carry_iterations + lm_iterations,
                        bool(result.converged[k]), info)


#: Stitching (tasks with obstacles): waypoints spread over the path that paths are carried from
#: in the second round, IK seeds at each waypoint carried from, and the largest joint step
#: [pose units] the stitched path may take (a prismatic joint: this share of CppFlow's 20 mm).
STITCH_ANCHORS = 9
STITCH_SEEDS = 64
#: Rounds of carrying from around where the stitched path still jumps (waypoint offsets).
STITCH_ROUNDS = 4
STITCH_AROUND = np.array([-12, -5, 0, 1, 6, 13])
#: Jumps carried from around per round at most, and how far [waypoints] each way.
STITCH_JUMPS = 3
STITCH_REACH = 30


def stitched_candidates(frames: Callable[..., Frames], task: Task, avoid: Avoidance,
                        lower: np.ndarray, upper: np.ndarray, low: np.ndarray, high: np.ndarray,
                        rng: np.random.Generator) -> tuple[np.ndarray, int, dict[str, Any]]:
    """Candidates for a task with obstacles: the stitched path (:func:`stitch`) first, then the
    paths carried forward from the first waypoint.

    From the first and the last waypoint, :data:`STITCH_SEEDS` random IK seeds whose solutions
    are collision-free are carried forward to the last waypoint and backward to the first
    (:func:`carry`, with collision avoidance). Every carried pose that reaches its goal
    and collides with nothing is a node; the stitched path picks one node per waypoint,
    minimising the sum of squared joint steps plus :data:`STITCH_JUMP_COST` per step above
    :data:`STITCH_MAX_STEP` (dynamic programming), so it can switch between carried paths
    where they meet: a narrow passage that no single carried path gets through may be passed
    by pieces of several.
    While the stitched path still jumps (or none exists), more paths are carried, from around
    each jump (:data:`STITCH_AROUND`, :data:`STITCH_REACH` waypoints each way) and, the first
    time, from :data:`STITCH_ANCHORS` waypoints spread over the path (to both ends), for at most
    :data:`STITCH_ROUNDS` more rounds.

    Returns:
        (paths (K, N, dof), carrying iterations, info): the stitched path at index 0 when one
        was found (``info["stitched"]``), then the forward-carried paths.
    """
    n, dof = len(task.goal.points_mm), len(lower)
    weights, max_step = stitch_costs(avoid.model.robot)
    jobs: list[tuple[np.ndarray, int]] = [(np.array([0, n - 1]), n)]   # (anchors, reach)
    tracks: list[np.ndarray] = []
    nodes: list[np.ndarray] = []      # each track's node mask, found once
    forward, iterations = np.zeros((0, n, dof)), 0
    path, rounds = None, 0
    while True:
        for anchors, reach in jobs:
            count, first = _carry_from(frames, task, avoid, anchors, reach, lower, upper, low,
                                       high, rng, tracks)
            iterations += count
            if first is not None:
                forward = first
        nodes += [stitch_nodes(frames, task, avoid, t) for t in tracks[len(nodes):]]
        if tracks:
            path = stitch(frames, task, avoid, np.concatenate(tracks), np.concatenate(nodes),
                          weights, max_step)
        jumps = np.zeros(0, dtype=int) if path is None else np.flatnonzero(
            np.any(np.abs(np.diff(path, axis=0)) > max_step, axis=1))
        rounds += 1
        if path is not None and not jumps.size or rounds > STITCH_ROUNDS:
            break
        # carry from around where the stitched path jumps, the first time also from waypoints
        # spread over the path
        if len(jumps) > STITCH_JUMPS:  # a bounded round: around a few jumps, spread out
            jumps = jumps[np.linspace(0, len(jumps) - 1, STITCH_JUMPS).round().astype(int)]
        around = np.unique(np.clip((jumps[:, None] + STITCH_AROUND).ravel(), 0, n - 1))
        jobs = [(around, STITCH_REACH)]
        if rounds == 1 or not jumps.size:
            spread = np.linspace(0, n - 1, STITCH_ANCHORS)[1:-1].round().astype(int)
            jobs.append((spread, n))
    if not tracks:
        raise InputError(f"trajectory {task.name!r}: no collision-free IK solution found at "
                         "any of the stitching waypoints; try another --lm-seed")
    info = {"stitched": path is not None, "stitch_tracks": int(sum(len(t) for t in tracks)),
            "stitch_rounds": rounds}
    paths = forward if path is None else np.concatenate([path[None], forward])
    if not len(paths):
        paths = np.nan_to_num(np.concatenate(tracks))[:1]
    return paths, iterations, info


def _carry_from(frames, task, avoid: Avoidance, anchors, reach: int, lower, upper, low, high,
                rng, tracks):
    """Carry collision-free IK solutions at each anchor waypoint forward and backward, at most
    ``reach`` waypoints each way, adding (M, N, dof) arrays (NaN where not carried) to
    ``tracks``; returns (carrying iterations, the paths carried forward from waypoint 0 to the
    last, or None)."""
    n, dof = len(task.goal.points_mm), len(lower)
    iterations, forward = 0, None
    for anchor in anchors:
        seeds = rng.uniform(low, high, (STITCH_SEEDS, dof))
        if anchor == 0 and task.hints.reference_pose is not None:
            seeds[0] = task.hints.reference_pose
        q, position, rotation, _ = first_waypoint_ik(
            frames, task.goal.points_mm[anchor], task.goal.rotations[anchor], seeds, lower, upper)
        found = distinct(q, (position < SEED_TOLERANCE) & (rotation < SEED_TOLERANCE))
        if found.size:
            found = found[avoid.collision_free(q[found][:, None])]
        if not found.size:
            continue
        for index in (np.arange(anchor, min(n, anchor + reach + 1)),
                      np.arange(anchor, max(-1, anchor - reach - 1), -1)):
            if len(index) < 2:
                continue
            part = replace(task, goal=replace(task.goal, points_mm=task.goal.points_mm[index],
                                              rotations=task.goal.rotations[index]))
            carried, count = carry(frames, part, q[found], lower, upper, avoid)
            iterations += count
            track = np.full((len(found), n, dof), np.nan)
            track[:, index] = carried
            tracks.append(track)
            if anchor == 0 and index[-1] == n - 1:
                forward = carried
    return iterations, forward


def stitch_nodes(frames: Callable[..., Frames], task: Task, avoid: Avoidance,
                 tracks: np.ndarray) -> np.ndarray:
    """(M, N) True where a carried track (M, N, dof) (NaN where it does not reach) is a node
    of the stitch: within :data:`STITCH_REACHED` of its goal and colliding with nothing."""
    m, n, dof = tracks.shape
    reached = ~np.isnan(tracks[..., 0])
    waypoint = np.broadcast_to(np.arange(n), (m, n))[reached]
    poses = tracks[reached]
    point, rotation, _, _ = frames(poses, False)
    e_point, e_rot, _, _ = errors_from_frames(
        point, rotation, None, None, task.goal.points_mm[waypoint],
        cast(np.ndarray, task.goal.rotations)[waypoint])
    close = np.maximum(np.abs(e_point).max(-1), np.abs(e_rot).max(-1)) < STITCH_REACHED
    free = np.zeros(len(poses), dtype=bool)
    free[close] = avoid.model.check(poses[close], avoid.obstacles).distances_mm \
        .min(axis=1, initial=np.inf) > 0
    node = np.zeros((m, n), dtype=bool)
    node[reached] = close & free
    return node




def joint_steps(a: np.ndarray, b: np.ndarray, period: np.ndarray | None = None) -> np.ndarray:
    """|b - a| per joint [pose units]; a joint with ``period`` > 0 (one turn [pose units]:
    a continuous joint) the shorter way round."""
    step = np.abs(b - a)
    if period is None or not np.any(period > 0):
        return step
    turn = np.where(period > 0, period, 1.0)
    wrapped = np.remainder(step, turn)
    return np.where(period > 0, np.minimum(wrapped, turn - wrapped), step)


def stitch(frames: Callable[..., Frames], task: Task, avoid: Avoidance, tracks: np.ndarray,
           node: np.ndarray | None = None, weights: np.ndarray | None = None,
           max_step: np.ndarray | float = STITCH_MAX_STEP,
           period: np.ndarray | None = None) -> np.ndarray | None:
    """The stitched path (N, dof) through the nodes of carried tracks (M, N, dof) (NaN where a
    track does not reach; ``node``: their :func:`stitch_nodes`, found here when None), see
    :func:`stitched_candidates`; None when no node sequence exists.

    The path minimises its weighted joint path length, sum_i sum_j w_j |p_{i+1,j} - p_{i,j}|
    (``weights`` w (dof,), default 1: :func:`stitch_costs`), plus :data:`STITCH_JUMP_COST`
    times every joint's step beyond ``max_step`` (dof,) or a number [pose units]: the
    shortest path through the nodes, globally (dynamic programming), with the smallest jumps
    where it must jump. ``period`` (dof,): continuous joints step the shorter way round
    (:func:`joint_steps`)."""
    m, n, dof = tracks.shape
    if node is None:
        node = stitch_nodes(frames, task, avoid, tracks)
    w = np.ones(dof) if weights is None else np.asarray(weights, dtype=float)
    poses = np.nan_to_num(tracks).swapaxes(0, 1)                    # (N, M, dof)
    nodes = [np.flatnonzero(node[:, i]) for i in range(n)]
    if any(not len(k) for k in nodes):
        return None
    cost = np.zeros(len(nodes[0]))
    back = []
    for i in range(1, n):
        step = joint_steps(poses[i - 1, nodes[i - 1]][:, None], poses[i, nodes[i]][None],
                           period)
        total = cost[:, None] + np.sum(w * step, axis=-1) \
            + STITCH_JUMP_COST * np.sum(np.maximum(step - max_step, 0.0), axis=-1)
        back.append(np.argmin(total, axis=0))
        cost = total[back[-1], np.arange(len(nodes[i]))]
    k = int(np.argmin(cost))
    path = np.empty((n, dof))
    for i in range(n - 1, -1, -1):
        path[i] = poses[i, nodes[i][k]]
        if i:
            k = int(back[i - 1][k])
    return path


def _rank(robot, paths, missed, colliding) -> np.ndarray:
    """Candidate order: fewest lost waypoints, then fewest colliding waypoints, then those
    whose steps all stay below CppFlow's joint-change limit, then the shortest joint path
    (pose units)."""
    steps = np.abs(np.diff(paths, axis=1))
    jumps = steps.max(axis=(1, 2)) >= MAX_JOINT_CHANGE_DEG
    return np.lexsort((steps.sum(axis=(1, 2)), jumps, colliding, missed))


def _problem_factory(robot, task, weights, frames):
    def make(count: int) -> FrameProblem:
        return FrameProblem.from_tasks(robot, [task] * count, [weights] * count, frames)
    return make


#: IK seeds per waypoint of :func:`waypoint_reach`.
REACH_SEEDS = 32


def waypoint_reach(robot: Robot, task: Task, count: int = REACH_SEEDS, seed: int = 0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """How closely each waypoint can be reached on its own within the task's limits: IK of
    every waypoint from ``count`` random poses (seeded), all at once.

    Returns:
        (position errors (n+1,) [mm], rotation errors (n+1,) [deg]) of each waypoint's best
        solution (the one with the smallest larger of the two).
    """
    frames = robot.chain_kinematics().frames
    lower, upper = (np.asarray(v, dtype=float) for v in task.limits(robot))
    low = np.where(np.isfinite(lower), lower, robot.sample_lower)
    high = np.where(np.isfinite(upper), upper, robot.sample_upper)
    n = task.goal.steps + 1
    seeds = np.random.default_rng(seed).uniform(low, high, (n * count, robot.dof))
    _, position, rotation, _ = first_waypoint_ik(
        frames, np.repeat(task.goal.points_mm, count, axis=0),
        np.repeat(cast(np.ndarray, task.goal.rotations), count, axis=0), seeds, lower, upper)
    position, rotation = position.reshape(n, count), rotation.reshape(n, count)
    best = np.argmin(np.maximum(position, rotation), axis=1)
    rows = np.arange(n)
    return position[rows, best], rotation[rows, best]
