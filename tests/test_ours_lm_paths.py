"""ours-lm's compiled pose-path search: each kernel equals its numpy reference (carrying,
nodes, the stitch, the pose-path LM with and without the clearance penalty), continuous joints
turn the short way, and the search keeps Fetch clear of itself without obstacles."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ikbench.core.metrics import frame_metrics
from ikbench.core.problems import load_problem
from ikbench.core.validity import MAX_JOINT_CHANGE_DEG
from ikbench.methods.ours_lm import OursLM
from ikbench.methods.ours_lm import start_search as reference
from ikbench.methods.ours_lm.avoidance import (
    ACTIVATION_MM,
    CARRY_GAIN,
    CARRY_MAX_STEP,
    SELF_CLEARANCE_MM,
    Avoidance,
)
from ikbench.methods.ours_lm.frames import FrameProblem, errors_from_frames, evaluate_frames
from ikbench.methods.ours_lm.solver import LMSettings, solve_batch

pytest.importorskip("numba")

from ikbench.core.capsules import capsule_model  # noqa: E402  (needs numba)
from ikbench.methods.ours_lm import anchor_ik, path_search, self_motion  # noqa: E402
from ikbench.methods.ours_lm import compiled_paths as kernels  # noqa: E402

CARRY = np.array([reference.CARRY_ITERATIONS, reference.CARRY_RETRY, reference.DROP_MM_DEG,
                  reference.CARRY_DAMPING, reference.AVOIDANCE_GAIN, ACTIVATION_MM, CARRY_GAIN,
                  CARRY_MAX_STEP])
WEIGHTS = {"L0": 1.0, "L1": 1.0, "L6": 0.001}


def _setting(name, seed=0, count=12):
    """(robot, task, frames, limits, capsule model, collision-free IK solutions at waypoint 0)."""
    robot, task, _ = load_problem(name)
    frames = robot.chain_kinematics().frames
    lower, upper = (np.asarray(v, dtype=float) for v in task.limits(robot))
    rng = np.random.default_rng(seed)
    seeds = rng.uniform(robot.sample_lower, robot.sample_upper, (count, robot.dof))
    q, position, rotation, _ = reference.first_waypoint_ik(
        frames, task.goal.points_mm[0], task.goal.rotations[0], seeds, lower, upper)
    found = reference.distinct(q, (position < 1e-3) & (rotation < 1e-3))
    caps = capsule_model(robot)
    free = caps.check(q[found], task.required.obstacles).distances_mm.min(axis=1) > 0
    return robot, task, frames, (lower, upper), caps, q[found][free]


def _carry_both(name, avoid):
    robot, task, frames, (lower, upper), caps, starts = _setting(name)
    avoidance = Avoidance(caps, task.required.obstacles, 0.5, 10.0) if avoid else None
    numpy, _ = reference.carry(frames, task, starts, lower, upper, avoidance)
    spec = kernels.PathSpec(robot, lower, upper, caps.scene(task.required.obstacles))
    n = len(task.goal.points_mm)
    compiled, _ = kernels.carry_tracks(spec, task.goal.points_mm, task.goal.rotations,
                                       np.zeros(len(starts), int), np.ones(len(starts), int),
                                       np.full(len(starts), n), starts, avoid, CARRY)
    return numpy, compiled


def test_carrying_equals_numpy():
    numpy, compiled = _carry_both("fetch__circle", avoid=False)
    assert len(numpy) >= 5
    np.testing.assert_allclose(compiled, numpy, rtol=0, atol=1e-6)


def test_carrying_with_the_collision_push_equals_numpy():
    """The numpy reference on the same capsule distances (CapsuleScene); a track grazing a box
    may pick another witness point on a flat stretch of the box after rounding, so most
    tracks are compared to 1e-6 and all to the same waypoints reached."""
    numpy, compiled = _carry_both("panda__1cube", avoid=True)
    differ = np.abs(compiled - numpy).max(axis=(1, 2))
    assert np.sum(differ < 1e-6) >= len(numpy) - 1, differ


def test_nodes_and_the_stitch_equal_numpy():
    robot, task, frames, (lower, upper), caps, starts = _setting("fetch__circle")
    spec = kernels.PathSpec(robot, lower, upper, caps.scene(task.required.obstacles))
    n = len(task.goal.points_mm)
    forward, _ = kernels.carry_tracks(spec, task.goal.points_mm, task.goal.rotations,
                                      np.zeros(len(starts), int), np.ones(len(starts), int),
                                      np.full(len(starts), n), starts, False, CARRY)
    backward, _ = kernels.carry_tracks(spec, task.goal.points_mm, task.goal.rotations,
                                       np.full(len(starts), n - 1), -np.ones(len(starts), int),
                                       np.full(len(starts), 120), forward[:, -1], False, CARRY)
    tracks = np.concatenate([forward, backward])
    avoid = Avoidance(caps, task.required.obstacles, 0.5, 10.0)
    nodes = reference.stitch_nodes(frames, task, avoid, tracks)
    assert np.array_equal(kernels.track_nodes(spec, task.goal.points_mm, task.goal.rotations,
                                              tracks, reference.STITCH_REACHED), nodes)
    assert nodes.any(axis=0).all() and not nodes.all()
    weights, max_step = reference.stitch_costs(robot)
    period = path_search.turns(robot, lower, upper)
    assert period.tolist() == [0, 0, 0, 360, 0, 360, 0, 360]
    expected = reference.stitch(frames, task, avoid, tracks, nodes, weights, max_step, period)
    stitched = kernels.stitch_path(tracks, nodes, weights, max_step,
                                   reference.STITCH_JUMP_COST, period)
    np.testing.assert_array_equal(stitched, expected)


def test_the_stitch_is_the_shortest_path_and_jumps_least():
    """Three made-up tracks: the stitch switches where a shorter way continues, and where no
    track continues it takes the smallest jump."""
    n, dof = 6, 2
    t = np.arange(n, dtype=float)[:, None]
    tracks = np.stack([np.hstack([t, 0 * t]), np.hstack([t, 0 * t + 4.0]),
                       np.hstack([t, 10.0 + 0 * t])])
    tracks[0, 3:, 1] += 30.0                     # track 0 jumps by 30 after waypoint 2
    node = np.ones((3, n), dtype=bool)
    node[1:, :3] = False                         # tracks 1 and 2 start at waypoint 3
    weights, max_step = np.ones(dof), np.full(dof, 6.5)
    choice = kernels.stitch_choice(tracks, node, weights, max_step, 1e6)
    assert choice.tolist() == [0, 0, 0, 1, 1, 1]  # 4 sideways: no jump, the shortest
    node[1] = False
    choice = kernels.stitch_choice(tracks, node, weights, max_step, 1e6)
    assert choice.tolist() == [0, 0, 0, 2, 2, 2]  # a jump of 10, not 30
    node[:, 4] = False
    assert kernels.stitch_choice(tracks, node, weights, max_step, 1e6) is None


@pytest.mark.parametrize("penalty", [False, True])
def test_the_pose_path_lm_equals_numpy(penalty):
    """From a carried path clear of the cube, perturbed; the penalty asks for 30 mm of
    clearance (so that it acts on separated, smooth pairs: inside a box the deepest point of a
    capsule's axis may jump between equally deep ones)."""
    robot, task, frames, (lower, upper), caps, starts = _setting("panda__1cube", seed=3,
                                                                 count=16)
    clearance = 30.0
    avoid = Avoidance(caps, task.required.obstacles, clearance, 10.0) if penalty else None
    carried, _ = reference.carry(frames, task, starts, lower, upper)
    clear = [k for k in range(len(carried))
             if caps.check(carried[k], task.required.obstacles).distances_mm.min() > 1.0]
    initial = carried[clear[0]] + 0.3 * np.sin(np.arange(carried[0].size)).reshape(
        carried[0].shape)
    if penalty:
        assert caps.check(initial, task.required.obstacles).distances_mm.min() < clearance
    problem = FrameProblem.from_tasks(robot, [task], [WEIGHTS], frames)
    numpy = solve_batch(robot, [task], LMSettings(backend="numpy", max_iterations=40),
                        [WEIGHTS], initial=initial[None], problem=problem,
                        evaluator=avoid.evaluator(evaluate_frames) if avoid else evaluate_frames,
                        until=lambda poses, _: reference.check_paths(
                            robot, task, poses, frames, reference.SEARCH_MARGIN, avoid)[0])
    spec = kernels.PathSpec(robot, lower, upper,
                            caps.scene(task.required.obstacles) if penalty else None)
    poses, loss, terms, iterations, converged, valid, _ = kernels.solve_path(
        spec, task.goal.points_mm, task.goal.rotations, initial, [1.0, 1.0, 0.001],
        [clearance, SELF_CLEARANCE_MM, 10.0 if penalty else 0.0], 40, 1e-9, 1e-3,
        reference.SEARCH_MARGIN, path_search.LIMITS, mode=0)
    assert iterations == numpy.iterations[0] and valid == bool(numpy.converged[0])
    assert loss == pytest.approx(numpy.loss[0], rel=1e-9)
    np.testing.assert_allclose(terms, numpy.terms[0], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(poses, numpy.poses[0], rtol=0, atol=1e-8)


def test_anchor_ik_equals_numpy():
    """The compiled IK of single waypoints against :func:`.search_common.first_waypoint_ik`,
    from random seeds at random waypoints (one goal per seed)."""
    robot, task, _ = load_problem("panda__1cube")
    frames = robot.chain_kinematics().frames
    lower, upper = (np.asarray(v, dtype=float) for v in task.limits(robot))
    rng = np.random.default_rng(3)
    at = rng.integers(0, len(task.goal.points_mm), 40)
    seeds = rng.uniform(robot.sample_lower, robot.sample_upper, (40, robot.dof))
    goals = task.goal.points_mm[at], task.goal.rotations[at]
    q, position, rotation, iterations = reference.first_waypoint_ik(frames, *goals, seeds,
                                                                   lower, upper)
    spec = kernels.PathSpec(robot, lower, upper, None)
    cq, cposition, crotation, citerations = anchor_ik.first_waypoint_ik(spec, *goals, seeds)
    assert citerations == iterations
    assert np.sum((position < 1e-3) & (rotation < 1e-3)) >= 5
    np.testing.assert_allclose(cq, q, rtol=0, atol=1e-8)
    np.testing.assert_allclose(cposition, position, rtol=0, atol=1e-9)
    np.testing.assert_allclose(crotation, rotation, rtol=0, atol=1e-9)


def _specialisations() -> dict[str, int]:
    """Compiled kernel -> its specialisations in this process, over every module of the
    search (numba compiles one per argument layout: a new one is a compilation)."""
    from numba.core.dispatcher import Dispatcher

    from ikbench.core import capsules
    from ikbench.methods.ours_lm import compiled_chain

    return {f"{module.__name__}.{name}": len(value.signatures)
            for module in (anchor_ik, kernels, self_motion, path_search, capsules,
                           compiled_chain)
            for name, value in vars(module).items() if isinstance(value, Dispatcher)}


def test_the_anchor_ik_has_one_argument_layout():
    """One goal for every seed, one per seed, or one seed: the same specialisation (a
    read-only goal made a second one, compiled inside a timed solve)."""
    robot, task, _ = load_problem("panda__1cube")
    lower, upper = (np.asarray(v, dtype=float) for v in task.limits(robot))
    spec = kernels.PathSpec(robot, lower, upper, None)
    seeds = np.random.default_rng(0).uniform(robot.sample_lower, robot.sample_upper,
                                             (4, robot.dof))
    goal_p, goal_R = task.goal.points_mm, task.goal.rotations
    anchor_ik.first_waypoint_ik(spec, goal_p[0], goal_R[0], seeds)
    anchor_ik.first_waypoint_ik(spec, goal_p[:4], goal_R[:4], seeds)
    anchor_ik.first_waypoint_ik(spec, goal_p[:1], goal_R[:1], seeds[:1])
    assert len(anchor_ik._ik_all.signatures) == 1


def test_a_solve_after_the_warm_up_compiles_nothing():
    """The warm-up (untimed) compiles every specialisation a solve uses: panda__2cubes seed 4
    once compiled the anchor IK inside its timed solve (11.9 s against a 0.3 s median)."""
    robot, task, _ = load_problem("panda__2cubes")
    method = OursLM(seed=4)
    method.check_tasks(robot, [task])
    method.prepare(robot)
    before = _specialisations()
    assert method.solve(robot, task).info["search"] == "compiled"
    after = _specialisations()
    assert {k: v for k, v in after.items() if v != before.get(k)} == {}


def test_a_sweep_equals_numpy_and_stays_on_the_pose():
    """The compiled sweep of a waypoint's self-motion manifold against
    :func:`.self_motion.sweep_reference`; every sample reaches the goal, consecutive samples
    are at most a step apart, and the sweep travels far along the manifold."""
    robot, task, frames, (lower, upper), caps, starts = _setting("panda__flappy_bird")
    spec = kernels.PathSpec(robot, lower, upper, caps.scene(task.required.obstacles))
    steps, point, rotation = 60, task.goal.points_mm[0], task.goal.rotations[0]
    assert len(starts) >= 2
    swept = self_motion.sweep_manifolds(spec, task.goal.points_mm, task.goal.rotations,
                                        np.zeros(len(starts), dtype=int), starts, steps)
    for row, start in zip(swept, starts):
        numpy = self_motion.sweep_reference(frames, point, rotation, start, lower, upper, steps)
        np.testing.assert_allclose(row, numpy, rtol=0, atol=1e-6)   # NaN where numpy's are
        samples = row[~np.isnan(row[:, 0])]
        assert len(samples) > steps
        assert np.abs(samples - start).max() > 60.0
        assert np.abs(np.diff(samples, axis=0)).max() <= self_motion.SWEEP_STEP * (
            1.0 + self_motion.SWEEP_BEND)
        p, r, _, _ = frames(samples, False)
        e_point, e_rot, _, _ = errors_from_frames(p, r, None, None, point, rotation)
        assert np.abs(e_point).max() < self_motion.SWEEP_TOLERANCE
        assert np.abs(e_rot).max() < self_motion.SWEEP_TOLERANCE
        assert np.all((samples >= lower) & (samples <= upper))


def test_a_repair_window_holds_the_steps_below_the_limit():
    """A carried path with 20 of its poses moved ~25 deg along the arm's self-motion (two
    jumps) is repaired within the window: every step below the limit, the window's ends kept,
    every pose on its goal and collision-free."""
    robot, task, frames, (lower, upper), caps, starts = _setting("panda__1cube", seed=3,
                                                                 count=16)
    carried, _ = reference.carry(frames, task, starts, lower, upper)
    clear = [k for k in range(len(carried))
             if caps.check(carried[k], task.required.obstacles).distances_mm.min() > 1.0]
    path = carried[clear[0]]
    spec = kernels.PathSpec(robot, lower, upper, caps.scene(task.required.obstacles))
    moved = np.arange(40, 60)
    swept = self_motion.sweep_manifolds(spec, task.goal.points_mm, task.goal.rotations, moved,
                                        path[moved], 20)
    offset = next(o for o in (16, -16, 12, -12) if not np.isnan(swept[:, 20 + o]).any())
    broken = path.copy()
    broken[moved] = swept[:, 20 + offset]
    limit = np.full(robot.dof, 0.99 * MAX_JOINT_CHANGE_DEG)
    assert np.abs(np.diff(broken, axis=0)).max() > 20.0
    weights, _ = reference.stitch_costs(robot)
    repaired = self_motion.repair_window(spec, task.goal.points_mm, task.goal.rotations,
                                         broken, 10, 89, 100, weights, limit,
                                         reference.STITCH_JUMP_COST, np.zeros(robot.dof), 1.0)
    assert repaired is not None
    assert np.abs(np.diff(repaired, axis=0)).max() <= limit[0]
    np.testing.assert_array_equal(repaired[:11], broken[:11])
    np.testing.assert_array_equal(repaired[89:], broken[89:])
    metrics = frame_metrics(robot, dataclasses.replace(task), repaired)
    assert metrics["position_error_max_mm"] < 1.0 and metrics["rotation_error_max_deg"] < 1.0
    assert metrics["env_collisions"] == 0 and metrics["self_collisions"] == 0


def test_continuous_joints_wrap_and_unwrap():
    robot, task, _ = load_problem("fetch_arm__hello")
    lower, upper = task.limits(robot)
    period = path_search.turns(robot, lower, upper)
    assert period.tolist() == [0, 0, 360, 0, 360, 0, 360]
    path = np.zeros((4, 7))
    path[:, 2] = [170.0, 178.0, -176.0, -168.0]        # upperarm roll across +-180
    path[:, 1] = [10.0, 20.0, 30.0, 40.0]
    straight = path_search.unwrap(path, period)
    assert straight[:, 2].tolist() == [170.0, 178.0, 184.0, 192.0]
    assert straight[:, 1].tolist() == path[:, 1].tolist()
    np.testing.assert_allclose(path_search.wrap(straight, period, lower), path)
    steps = reference.joint_steps(path[:-1], path[1:], period)
    assert steps[:, 2].tolist() == [8.0, 6.0, 8.0]


@pytest.mark.parametrize("name, seed", [("fetch__rot_yz2", 1), ("fetch_arm__hello", 1)])
def test_self_collision_is_avoided_without_obstacles(name, seed):
    """Both self-collided at seed 1 before (the avoidance ran only with obstacles)."""
    robot, task, _ = load_problem(name)
    assert not task.required.obstacles
    method = OursLM(seed=seed)
    method.check_tasks(robot, [task])
    method.prepare(robot)
    solution = method.solve(robot, task)
    metrics = frame_metrics(robot, task, solution.poses)
    assert metrics["valid"], metrics["failed_criteria"]
    assert metrics["self_collisions"] == 0 and metrics["min_self_clearance_mm"] > 0
    assert solution.info["search"] == "compiled" and solution.info["self_collision_avoided"]
    assert metrics["max_joint_change_deg"] < MAX_JOINT_CHANGE_DEG   # wrapped: a roll may turn


def test_the_search_is_deterministic_and_the_numpy_search_still_runs():
    robot, task, _ = load_problem("panda__1cube")
    short = dataclasses.replace(task, goal=dataclasses.replace(
        task.goal, points_mm=task.goal.points_mm[:40], rotations=task.goal.rotations[:40],
        directions=task.goal.directions[:40]))
    a, b = OursLM(seed=4).solve(robot, short), OursLM(seed=4).solve(robot, short)
    np.testing.assert_array_equal(a.poses, b.poses)
    assert frame_metrics(robot, short, a.poses)["valid"]
    numpy = OursLM(seed=4, backend="numpy").solve(robot, short)
    assert "search" not in numpy.info           # the numpy search (coal for collisions)
    metrics = frame_metrics(robot, short, numpy.poses)
    assert metrics["self_collisions"] == 0 and metrics["env_collisions"] == 0


def test_3d_trajectories_clear_of_themselves_are_unchanged(robot):
    """The paper's seven on NICO (whose capsules never meet within its motor ranges) are the
    same trajectories as the plain batch solve."""
    from ikbench.core.losses import resolve_weights
    from ikbench.core.targets import load_targets
    from ikbench.core.task import line_tasks

    tasks = line_tasks(robot, load_targets(None, robot))
    method = OursLM()
    weights = [resolve_weights(method.settings.weights, t) for t in tasks]
    plain = solve_batch(robot, tasks, method.settings, weights=weights)
    solutions = method.solve_many(robot, tasks)
    for solution, poses in zip(solutions, plain.poses):
        np.testing.assert_array_equal(solution.poses, poses)
        assert not solution.info["solved_again_without_self_collision"]


def test_a_3d_trajectory_through_the_robot_itself_is_solved_again():
    """A Panda line bent into the robot itself (poses of it replaced by one whose links meet)
    is solved again, clear of itself."""
    from ikbench.core.losses import resolve_weights
    from ikbench.core.robot import load_robot
    from ikbench.core.targets import load_targets
    from ikbench.core.task import line_tasks
    from ikbench.methods.ours_lm.avoidance import collision_checker, self_colliding

    panda = load_robot("panda")
    tasks = line_tasks(panda, load_targets(None, panda))[:1]
    method = OursLM()
    weights = [resolve_weights(method.settings.weights, t) for t in tasks]
    checker = collision_checker(panda)
    rng = np.random.default_rng(0)
    samples = rng.uniform(panda.lower, panda.upper, (2000, panda.dof))
    touching = samples[checker.check(samples).self_colliding]
    bent = solve_batch(panda, tasks, method.settings, weights=weights)
    assert self_colliding(checker, bent.poses)[0] == 0
    middle = len(bent.poses[0]) // 2
    bent.poses[0, middle - 2:middle + 2] = touching[0]
    assert self_colliding(checker, bent.poses)[0] >= 4
    assert method._without_self_collisions(panda, tasks, bent, weights) == [0]
    assert self_colliding(checker, bent.poses)[0] == 0
