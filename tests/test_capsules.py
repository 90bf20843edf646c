"""The compiled capsule distances against coal (the field's library, through Pinocchio), their
gradients against finite differences, and where they do not apply (meshes)."""

from __future__ import annotations

import numpy as np
import pytest

from ikbench.core.collision import collision_model
from ikbench.core.obstacles import box, capsule, halfspace, rpy_to_matrix, sphere
from ikbench.core.robot import load_robot
from tests.conftest import central_differences

pytest.importorskip("numba")

from ikbench.core.capsules import capsule_model  # noqa: E402  (needs numba)

#: One obstacle of every kind, a box turned about two axes.
OBSTACLES = (box("b", [400.0, 100.0, 500.0], [200.0, 300.0, 150.0],
                 rotation=rpy_to_matrix(0.6, 0.0, 1.2)),
             sphere("s", [200.0, -300.0, 600.0], 80.0),
             halfspace("h", [0.0, 0.0, 100.0], [0.1, 0.2, 1.0]),
             capsule("c", [300.0, 300.0, 300.0], [500.0, 0.0, 800.0], 40.0))


def _poses(robot, count, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.sample_lower, robot.sample_upper, (count, robot.dof))


@pytest.mark.parametrize("name", ["panda", "fetch", "nico_right_arm"])
def test_distances_agree_with_coal(name):
    robot = load_robot(name)
    coal, mine = collision_model(robot), capsule_model(robot)
    poses = _poses(robot, 150)
    np.testing.assert_allclose(mine.world_segments(poses) * 1000.0,
                               coal.capsule_segments(poses), atol=1e-9)
    a, b = mine.check(poses, OBSTACLES), coal.check(poses, OBSTACLES)
    assert a.pairs == b.pairs and np.array_equal(a.is_env, b.is_env)
    apart = b.distances_mm > 0
    assert apart.sum() > 1000 and (~apart).sum() > 100      # both kinds met
    assert np.abs(a.distances_mm - b.distances_mm)[apart].max() < 0.1
    # overlapping: the depth is measured differently (the deepest point of the axis inside a
    # box, not coal's separating translation), the verdict is the same
    assert np.array_equal(a.colliding, b.colliding)


def test_distance_gradients_match_finite_differences():
    robot = load_robot("panda")
    model = capsule_model(robot)
    poses = _poses(robot, 12, seed=1)
    rows, pairs, distances, gradients, names = model.distance_jacobians(poses, OBSTACLES, 1e9)
    assert len(rows) == len(poses) * len(names)
    step, worst, checked = 1e-4, 0.0, 0
    for row, pair, distance, gradient in zip(rows, pairs, distances, gradients):
        if distance < -5.0:      # deep inside a box the deepest point may jump: not smooth
            continue
        numeric = central_differences(
            lambda q, pair=pair: model.check(q[None], OBSTACLES).distances_mm[0, pair],
            poses[row], step)
        worst = max(worst, float(np.abs(numeric - gradient).max()))
        checked += 1
    assert checked > 300 and worst < 1e-3, worst   # mm per deg


def test_far_pairs_report_a_lower_bound_only():
    robot = load_robot("fetch")
    scene = capsule_model(robot).scene(OBSTACLES)
    poses = _poses(robot, 40, seed=2)
    exact, _, _, _ = scene.distances(poses)
    bounded, _, _, normal = scene.distances(poses, below_mm=30.0)
    near = exact * 1000.0 < 30.0
    np.testing.assert_array_equal(bounded[near], exact[near])
    assert np.all(bounded <= exact + 1e-12) and np.all(bounded[~near] * 1000.0 > 30.0 - 1e-9)
    only_bound = bounded < exact - 1e-12           # not resolved: a bound and no normal
    assert only_bound.sum() > 100 and np.all(normal[only_bound] == 0.0)


def test_meshes_are_left_to_coal():
    robot = load_robot("example-robot-data:ur5")
    assert collision_model(robot) is not None and capsule_model(robot) is None
