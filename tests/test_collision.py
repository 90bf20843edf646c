"""The collision checker against distances computed directly, and its verdicts on trajectories."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from ikbench.core.collision import collision_model
from ikbench.core.errors import InputError
from ikbench.core.metrics import frame_metrics
from ikbench.core.obstacles import (
    box,
    cppflow_obstacles,
    halfspace,
    parse_obstacles,
    read_obstacles,
    rpy_to_matrix,
    sphere,
)
from ikbench.core.problems import load_problem
from ikbench.core.robot import load_robot
from tests.conftest import central_differences


def _segment_box_distance_mm(a, b, radius, center, size, samples=20001):
    """Capsule (segment a-b, radius) to an axis-aligned box, by dense sampling of the segment
    (a capsule-box distance is the segment-box distance minus the radius)."""
    t = np.linspace(0.0, 1.0, samples)[:, None]
    points = a + t * (b - a)
    half = np.asarray(size) / 2.0
    outside = np.maximum(np.abs(points - center) - half, 0.0)
    return float(np.linalg.norm(outside, axis=1).min()) - radius


def _capsule_world(model, poses):
    """(C, 2, 3) end centres [mm] of the robot's capsules at one pose."""
    return model.capsule_segments(poses[None])[0]


@pytest.fixture(scope="module")
def panda():
    return load_robot("panda")


def test_capsule_box_distances_match_a_direct_computation(panda):
    model = collision_model(panda)
    rng = np.random.default_rng(3)
    pose = np.array([0.0, 20.0, 0.0, -120.0, 0.0, 140.0, 45.0])
    for _ in range(5):
        center = rng.uniform([-300, -300, 100], [600, 300, 900])
        size = rng.uniform(50, 300, 3)
        obstacle = box("b", center, size)
        report = model.check(pose[None], (obstacle,))
        segments = _capsule_world(model, pose)
        for k, capsule in enumerate(model.capsules):
            column = report.pairs.index((capsule.link, "b"))
            direct = _segment_box_distance_mm(*segments[k], capsule.radius_mm, center, size)
            if direct > 0:  # separated: the distance itself
                assert report.distances_mm[0, column] == pytest.approx(direct, abs=0.1)
            else:           # overlapping: a collision either way
                assert report.distances_mm[0, column] < 0.1


def test_sphere_and_halfspace_distances_match_a_direct_computation(panda):
    model = collision_model(panda)
    pose = np.array([10.0, -30.0, 20.0, -100.0, 10.0, 120.0, 0.0])
    ball = sphere("s", [400.0, 100.0, 500.0], 80.0)
    floor = halfspace("floor", [0.0, 0.0, 150.0], [0.0, 0.2, 1.0])
    report = model.check(pose[None], (ball, floor))
    segments = _capsule_world(model, pose)
    normal = np.array([0.0, 0.2, 1.0]) / np.linalg.norm([0.0, 0.2, 1.0])
    for k, capsule in enumerate(model.capsules):
        a, b = segments[k]
        t = np.clip((ball.center_mm - a) @ (b - a) / max((b - a) @ (b - a), 1e-12), 0, 1)
        to_ball = np.linalg.norm(a + t * (b - a) - ball.center_mm) - 80.0 - capsule.radius_mm
        height = min((a - [0, 0, 150.0]) @ normal, (b - [0, 0, 150.0]) @ normal)
        to_floor = height - capsule.radius_mm
        assert report.distances_mm[0, report.pairs.index((capsule.link, "s"))] == \
            pytest.approx(to_ball, abs=0.1)
        assert report.distances_mm[0, report.pairs.index((capsule.link, "floor"))] == \
            pytest.approx(to_floor, abs=0.1)


def test_distance_gradients_match_finite_differences(panda):
    model = collision_model(panda)
    obstacles = (box("b", [450.0, 0.0, 300.0], [200.0, 200.0, 200.0]),
                 sphere("s", [200.0, 300.0, 700.0], 60.0))
    rng = np.random.default_rng(0)
    poses = np.array([0.0, 10.0, 0.0, -110.0, 0.0, 120.0, 45.0]) + rng.normal(0, 15, (3, 7))
    rows, pairs, distances, gradients, _ = model.distance_jacobians(poses, obstacles, 1e9)
    assert len(rows) == 3 * len(model.check(poses[:1], obstacles).pairs)
    step = 0.05  # deg: well above the solver's tolerance, small against the curvature
    worst = 0.0
    for row, pair, gradient in zip(rows, pairs, gradients):
        numeric = central_differences(
            lambda q, pair=pair: model.check(q[None], obstacles).distances_mm[0, pair],
            poses[row], step)
        worst = max(worst, float(np.abs(numeric - gradient).max()))
    assert worst < 0.05, worst  # mm per deg


def test_a_trajectory_through_a_box_is_invalid_with_its_first_colliding_waypoint():
    robot, task, _ = load_problem("panda__1cube")
    free = dataclasses.replace(task, required=dataclasses.replace(task.required, obstacles=()))
    from ikbench.methods.ours_lm import OursLM

    poses = OursLM(seed=1).solve(robot, free).poses       # ignores the cube
    report = collision_model(robot).check(poses, task.required.obstacles)
    first = report.first_collision()
    assert first is not None
    metrics = frame_metrics(robot, task, poses)
    assert not metrics["valid"] and "env_collision" in metrics["failed_criteria"].split(",")
    assert metrics["first_collision_waypoint"] == first[0]
    assert metrics["first_collision_pair"] == f"{first[1]} / {first[2]}"
    assert first[2] == "box0" and first[1].startswith("panda_")
    assert not report.env_colliding[:first[0]].any() and report.env_colliding[first[0]]
    # the same poses without the cube: valid (the obstacle-free check is unchanged)
    assert frame_metrics(robot, free, poses)["valid"]


def test_ours_lm_keeps_clear_of_the_cube():
    robot, task, _ = load_problem("panda__1cube")
    from ikbench.methods.ours_lm import OursLM

    solution = OursLM(seed=2).solve(robot, task)
    metrics = frame_metrics(robot, task, solution.poses)
    assert metrics["valid"], metrics["failed_criteria"]
    assert metrics["min_clearance_mm"] > 0 and metrics["env_collisions"] == 0


def test_cppflow_boxes_are_read_as_cppflow_writes_them():
    items = [[{"x": 0.4}, {"y": -0.4}, {"z": 0.825}, {"roll": 0.0}, {"pitch": 0.0},
              {"yaw": 0.5}, {"size_x": 0.3}, {"size_y": 0.05}, {"size_z": 0.8}]]
    (b,) = cppflow_obstacles(items, [0.0, 0.1, 0.0], "t.yaml")
    np.testing.assert_allclose(b.center_mm, [400.0, -300.0, 825.0])
    np.testing.assert_allclose(b.size_mm, [300.0, 50.0, 800.0])
    np.testing.assert_allclose(b.rotation, rpy_to_matrix(0.0, 0.0, 0.5))


def test_obstacle_files_round_trip_and_bad_items_fail_in_one_line(tmp_path):
    obstacles = (box("table", [500, 0, -20], [800, 1200, 40], rpy_to_matrix(0.1, 0.2, 0.3)),
                 sphere("ball", [300, 200, 400], 50), halfspace("wall", [0, -400, 0], [0, 1, 0]))
    path = tmp_path / "obstacles.json"
    path.write_text(json.dumps({"obstacles": [o.to_dict() for o in obstacles]}))
    back = read_obstacles(str(path))
    for a, b in zip(obstacles, back):
        assert a.kind == b.kind and a.name == b.name
        np.testing.assert_allclose(a.center_mm, b.center_mm, atol=1e-6)
        np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-9)
    with pytest.raises(InputError, match=r"obstacle 0: type = 'cube' is not one of box"):
        parse_obstacles([{"type": "cube"}], "f.json")
    with pytest.raises(InputError, match=r"radius_mm = -1 must be a positive number"):
        parse_obstacles([{"type": "sphere", "center_mm": [0, 0, 0], "radius_mm": -1}], "f")
    with pytest.raises(InputError, match=r"obstacles: 'nothing' is neither"):
        read_obstacles("nothing", load_robot("nico_right_arm"))


def test_nicos_touchscreen_is_a_named_obstacle_set_and_the_touches_clear_it():
    robot = load_robot("nico_right_arm")
    (screen,) = read_obstacles("touchscreen", robot)
    assert screen.kind == "halfspace"
    from ikbench.core.targets import load_targets

    targets = load_targets(None, robot)
    touches = np.array(list(targets.touch_poses.values()))
    report = collision_model(robot).check(touches, (screen,))
    assert not report.env_colliding.any() and not report.self_colliding.any()
    assert math.isfinite(report.min_clearance_mm(env=True))


def test_a_urdfs_collision_meshes_work_as_their_hulls():
    """A robot without a collision file uses its URDF's <collision> elements (meshes here, as
    their convex hulls): UR5 of example-robot-data folded onto itself collides; a box on its
    forearm too."""
    robot = load_robot("example-robot-data:ur5")
    model = collision_model(robot)
    assert model is not None and "<collision>" in model.source and not model.capsules
    folded = np.zeros((1, robot.dof))
    folded[0, 2] = 150.0  # the elbow folded: the wrist meets the base
    assert model.check(folded).self_colliding.all()
    home = np.zeros((1, robot.dof))
    on_forearm = box("b", [400.0, 100.0, 0.0], [300.0, 300.0, 100.0])
    above = box("b", [400.0, 100.0, 400.0], [300.0, 300.0, 100.0])
    report = model.check(home, (on_forearm,))
    hit = {a for (a, _), c in zip(report.pairs, report.colliding[0]) if c}
    assert report.env_colliding.all() and "forearm_link" in hit
    assert not model.check(home, (above,)).env_colliding.any()
    assert not model.check(home).self_colliding.any()


def test_an_initial_configuration_is_part_of_validity(tmp_path):
    """CppFlow's Problem may give an initial configuration: the first pose must be within 0.2
    (URDF units) of it."""
    from ikbench.core.problems import shipped_problems

    robot, task, _ = load_problem("fetch_arm__hello")
    from ikbench.methods.ours_lm import OursLM

    poses = OursLM(seed=1).solve(robot, task).poses
    first_rad = robot.to_urdf(poses[0])
    text = shipped_problems()["fetch_arm__hello"].read_text()
    for offset, ok in ((0.05, True), (0.5, False)):
        near = tmp_path / f"near{offset}.yaml"
        near.write_text(text + "\ninitial_configuration: "
                        + json.dumps([float(v) for v in first_rad + offset / math.sqrt(7)])
                        + "\n")
        _, with_initial, _ = load_problem(near)
        metrics = frame_metrics(robot, with_initial, poses)
        assert metrics["initial_configuration_distance"] == pytest.approx(offset, abs=1e-6)
        assert ("initial_configuration" not in metrics["failed_criteria"].split(",")) == ok


def test_urdf_meshes_become_convex_hulls_that_are_never_farther_than_the_meshes():
    """z1's gripper meshes are checked as their convex hulls: a hull contains its mesh, so on
    random poses every hull pair distance is at most the mesh pair distance (coal's GJK
    tolerance aside), and the error is measured against the meshes."""
    from ikbench.core.collision import hull_distance_error

    robot = load_robot("example-robot-data:z1", end_frame="gripperStator")
    model = collision_model(robot)
    meshes = model.mesh_model()
    assert model.geometry == "convex hulls of the URDF meshes" and meshes is not None
    assert meshes.geometry == "URDF meshes" and meshes.self_pairs == model.self_pairs
    kinds = {type(g.geometry).__name__ for g in model._geometry.geometryObjects}
    assert "Convex" in kinds and not any("BVH" in k for k in kinds)
    poses = np.random.default_rng(3).uniform(robot.sample_lower, robot.sample_upper,
                                             size=(60, robot.dof))
    report = model.check(poses)
    hull_mm, mesh_mm = report.distances_mm, meshes.check(poses).distances_mm
    assert np.all(hull_mm <= mesh_mm + 0.01)
    assert np.any(hull_mm < mesh_mm - 1.0)  # the hulls are a simplification, not the meshes
    error = hull_distance_error(model, samples=60, seed=3)
    assert error["geometry"] == model.geometry and error["samples"] == 60
    with_mesh = [bool({"gripperStator", "gripperMover"} & set(p)) for p in report.pairs]
    assert error["pairs"] == sum(with_mesh) > 0
    assert error["min_mm"] >= -0.01 and error["median_mm"] <= error["max_mm"]
    assert error["max_mm"] == pytest.approx(float(np.max((mesh_mm - hull_mm)[:, with_mesh])),
                                            abs=1e-9)


@pytest.mark.parametrize("name", ["panda", "nico_right_arm"])
def test_a_capsule_robot_keeps_its_capsules(name):
    from ikbench.core.collision import hull_distance_error

    model = collision_model(load_robot(name))
    assert model.geometry == "capsules" and model.capsules
    assert model.mesh_model() is None and hull_distance_error(model) is None
    kinds = {type(g.geometry).__name__ for g in model._geometry.geometryObjects}
    assert kinds <= {"Capsule", "Sphere"}


def test_a_packages_srdf_and_always_touching_pairs_are_not_checked():
    """PR2's meshes put its shoulder into the torso's hull at every pose: with every pair
    checked, every path on PR2 was in self-collision. The pairs the package's SRDF disables
    are skipped (PR2); where there is no SRDF (Baxter), the pairs in collision at every one of
    the sampled poses are (MoveIt's setup assistant's 'always in collision'), named in the
    model's source."""
    from ikbench.core.collision import ALWAYS_SAMPLES, always_colliding

    pr2 = collision_model(load_robot("example-robot-data:pr2", "r_gripper_tool_frame"))
    assert "pr2.srdf" in pr2.source
    assert ("base_link", "r_shoulder_pan_link") not in pr2.self_pairs
    assert not always_colliding(pr2).any()
    baxter = collision_model(load_robot("example-robot-data:baxter", "right_gripper"))
    assert "srdf" not in baxter.source and f"every one of {ALWAYS_SAMPLES}" in baxter.source
    assert "right_lower_elbow / right_upper_elbow_visual" in baxter.source
    assert ("right_lower_elbow", "right_upper_elbow_visual") not in baxter.self_pairs
    assert not always_colliding(baxter).any()
    poses = np.random.default_rng(5).uniform(pr2.robot.sample_lower, pr2.robot.sample_upper,
                                             (20, pr2.robot.dof))
    assert not pr2.check(poses).self_colliding.all()  # some poses are free
