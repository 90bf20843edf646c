"""ours-lm's pose-path search with obstacles: stitching carried paths, and what it returns."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ikbench.core.collision import collision_model
from ikbench.core.metrics import frame_metrics
from ikbench.core.problems import load_problem
from ikbench.methods.ours_lm import OursLM
from ikbench.methods.ours_lm.avoidance import Avoidance
from ikbench.methods.ours_lm.start_search import STITCH_MAX_STEP, stitch


def _free_solution(name: str, seed: int = 1):
    robot, task, _ = load_problem(name)
    free = dataclasses.replace(task, required=dataclasses.replace(task.required, obstacles=()))
    return robot, task, OursLM(seed=seed).solve(robot, free).poses


def test_stitch_switches_between_partial_tracks_where_they_meet():
    robot, task, poses = _free_solution("panda__1cube")
    task = dataclasses.replace(task, required=dataclasses.replace(task.required, obstacles=()))
    n = len(poses)
    first, second = np.full_like(poses, np.nan), np.full_like(poses, np.nan)
    first[:80], second[60:] = poses[:80], poses[60:]
    wrong = poses + 40.0                       # reaches no goal: never a node
    avoid = Avoidance(collision_model(robot), (), 2.0, 10.0)
    path = stitch(robot.chain_kinematics().frames, task, avoid,
                  np.stack([wrong, first, second]))
    assert path is not None
    np.testing.assert_allclose(path, poses)
    assert np.abs(np.diff(path, axis=0)).max() <= STITCH_MAX_STEP
    # a gap no track covers: no path
    second[:90] = np.nan
    first[70:] = np.nan
    assert stitch(robot.chain_kinematics().frames, task, avoid,
                  np.stack([first, second])) is None
    assert n == task.goal.steps + 1


def test_ours_lm_passes_between_the_flappy_bird_boxes():
    robot, task, _ = load_problem("panda__flappy_bird")
    solution = OursLM(seed=2).solve(robot, task)
    metrics = frame_metrics(robot, task, solution.poses)
    assert metrics["valid"], metrics["failed_criteria"]
    assert metrics["env_collisions"] == 0 and metrics["min_clearance_mm"] > 0
    assert solution.info["stitched"]
    # without the boxes the same search is the obstacle-free one (no stitching), and its
    # path hits them
    _, _, free = _free_solution("panda__flappy_bird", seed=2)
    assert collision_model(robot).check(free, task.required.obstacles).env_colliding.any()


def test_a_users_problem_file_with_the_cube_moved(tmp_path):
    """Any CppFlow-format file with obstacles, not only the shipped ones (the path resolves to
    the shipped 1cube.csv; the cube is moved by obstacle_xyz_offset)."""
    from ikbench.core.problems import shipped_problems

    text = shipped_problems()["panda__1cube"].read_text()
    moved = tmp_path / "moved_cube.yaml"
    moved.write_text(text.replace("obstacle_xyz_offset: [0, 0, 0]",
                                  "obstacle_xyz_offset: [0.05, -0.04, 0.03]"))
    robot, task, _ = load_problem(moved)
    np.testing.assert_allclose(task.required.obstacles[0].center_mm, [50.0, 160.0, 730.0])
    metrics = frame_metrics(robot, task, OursLM(seed=1).solve(robot, task).poses)
    assert metrics["valid"], metrics["failed_criteria"]
    assert metrics["min_clearance_mm"] > 0


@pytest.mark.parametrize("name, offset_m, seed", [
    # a 10 deg step past the arm's swing by q2 = 0 that the LM could not smooth
    ("panda__flappy_bird", (0.0, -0.01, 0.0), 3),
    # a jump of 27 deg where the tracks ran past the boxes on the wrong side of the arm's
    # self-motion: the sweeps of the whole path find the way round
    ("panda__flappy_bird", (0.02, 0.0, 0.0), 2),
    # the first waypoint's only collision-free IK branch (0.5 mm clearance), which no IK
    # seed found: the end's sweeps and more seeds find it
    ("panda__2cubes", (0.0, -0.03, 0.0), 4),
])
def test_moved_obstacles_that_failed_before_are_solved(tmp_path, name, offset_m, seed):
    """Problem files with their obstacles moved (``obstacle_xyz_offset``) on which the search
    failed at this seed before its repairs, sweeps and resumed tracks (see
    benchmarks/moved_obstacles.py); validity recomputed from the poses."""
    from ikbench.core.problems import shipped_problems

    text = shipped_problems()[name].read_text()
    moved = tmp_path / f"{name}_moved.yaml"
    moved.write_text(text.replace("obstacle_xyz_offset: [0, 0, 0]",
                                  f"obstacle_xyz_offset: {list(offset_m)}"))
    robot, task, _ = load_problem(moved)
    original = load_problem(name)[1].required.obstacles
    np.testing.assert_allclose(task.required.obstacles[0].center_mm,
                               original[0].center_mm + 1000.0 * np.array(offset_m))
    method = OursLM(seed=seed)
    method.prepare(robot)
    metrics = frame_metrics(robot, task, method.solve(robot, task).poses)
    assert metrics["valid"], metrics["failed_criteria"]
    assert metrics["env_collisions"] == 0 and metrics["min_clearance_mm"] > 0


def test_ours_lm_names_its_own_collision_avoidance():
    """The leaderboard's label of ours-lm's own avoidance (inside its time): the geometry and
    the engine it checks with; nothing for a robot without a collision model."""
    from ikbench.core.robot import load_robot

    z1 = load_robot("example-robot-data:z1", end_frame="gripperStator")
    assert OursLM().collision_avoidance(z1) == \
        "avoids self-collision (convex hulls of the URDF meshes, coal)"
    assert OursLM().collision_avoidance(load_robot("panda")).startswith(
        "avoids self-collision (capsules, ")
