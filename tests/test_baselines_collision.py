"""The library baselines that avoid obstacles with their library's own avoidance (issue 23):
Drake ``MinimumDistanceLowerBoundConstraint`` (drake-ik, drake-trajopt), pink
``SelfCollisionBarrier`` and mink ``CollisionAvoidanceLimit``.

Every check of a solution is ikbench's own (``collision_model(robot).check``), not the
library's. The scene: a Panda path whose goals come from FK of a joint path that sweeps the
elbow through a ball placed at the elbow's middle position; the goals (the hand) stay far from
the ball, and the 7-DoF arm can lift its elbow around it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ikbench import load_robot
from ikbench.core.collision import collision_model
from ikbench.core.obstacles import box, capsule, halfspace, sphere
from ikbench.core.task import Goal, Requirements, Task
from ikbench.schemes.collision import obstacle_shape, scene_of
from tests.conftest import method_class

AVOIDING = ("drake-ik", "drake-trajopt", "pink", "mink")
#: Each method's default clearance [mm]; the checker must see at least this less round-off.
CLEARANCE_MM = 5.0
STEPS = 20


@pytest.fixture(scope="module")
def panda():
    robot = load_robot("panda")
    if collision_model(robot) is None or not collision_model(robot).capsules:
        pytest.skip("the panda has no capsule collision model")
    return robot


def elbow_task(robot, frames: bool) -> tuple[Task, tuple]:
    """(task with the ball, the ball): goals by FK of a joint-1 sweep; the ball (radius 30
    mm) at the middle pose's elbow capsule (panda_link4)."""
    start = np.array([-35.0, 35.0, 0.0, -100.0, 0.0, 135.0, 45.0])
    end = np.array([35.0, 35.0, 0.0, -100.0, 0.0, 135.0, 45.0])
    poses = np.linspace(start, end, STEPS + 1)
    T = robot.fk_transform(poses)
    model = collision_model(robot)
    assert model is not None
    links = [c.link for c in model.capsules]
    segments = model.capsule_segments(poses)
    ball = (sphere("ball", segments[STEPS // 2, links.index("panda_link4")].mean(axis=0),
                   30.0),)
    task = Task("elbow", Goal(T[:, :3, 3] * 1000.0, T[:, :3, :3] @ robot.pointing_axis,
                              T[:, :3, :3] if frames else None),
                Requirements(start, end, obstacles=ball))
    return task, ball


def position_errors_mm(robot, task, poses) -> np.ndarray:
    T = robot.fk_transform(poses)
    return np.linalg.norm(T[:, :3, 3] * 1000.0 - task.goal.points_mm, axis=1)


@pytest.mark.parametrize("name", AVOIDING)
def test_avoiding_methods_say_so(name):
    assert method_class(name).capabilities.obstacles


@pytest.mark.parametrize("name", AVOIDING)
def test_a_six_d_path_keeps_clear_of_a_ball_it_hits_without_avoidance(panda, name):
    cls = method_class(name)
    task, ball = elbow_task(panda, frames=True)
    model = collision_model(panda)
    method = cls()
    method.prepare(panda)
    plain = method.solve(panda, dataclasses.replace(
        task, required=dataclasses.replace(task.required, obstacles=())))
    assert model.check(plain.poses, ball).summary()["env_collisions"] > 0
    assert "collision_avoidance" not in plain.info  # no obstacle, no change
    solution = method.solve(panda, task)
    report = model.check(solution.poses, ball).summary()
    assert solution.info["collision_avoidance"] == "on"
    assert report["env_collisions"] == 0 and report["self_collisions"] == 0
    assert report["min_clearance_mm"] > CLEARANCE_MM - 0.5
    assert solution.converged
    assert position_errors_mm(panda, task, solution.poses).max() < 0.01


@pytest.mark.parametrize("name", AVOIDING)
def test_a_tracked_pointing_path_keeps_clear_of_the_ball(panda, name):
    """Goal points and pointing directions, start and touch pose fixed (the track scheme;
    pink and mink without their speed box, which keeps the elbow from swinging around the
    ball in time)."""
    cls = method_class(name)
    task, ball = elbow_task(panda, frames=False)
    options = {"speed_fraction": 0.0} if name in ("pink", "mink") else {}
    method = cls(**options)
    method.prepare(panda)
    model = collision_model(panda)
    plain = method.solve(panda, dataclasses.replace(
        task, required=dataclasses.replace(task.required, obstacles=())))
    assert model.check(plain.poses, ball).summary()["env_collisions"] > 0
    solution = method.solve(panda, task)
    report = model.check(solution.poses, ball).summary()
    assert report["env_collisions"] == 0 and report["self_collisions"] == 0
    assert report["min_clearance_mm"] > CLEARANCE_MM - 0.5
    assert position_errors_mm(panda, task, solution.poses).max() < 0.01


def _obstacles():
    return (box("box", [350.0, -250.0, 300.0], [120.0, 80.0, 200.0],
                [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
            sphere("ball", [300.0, 250.0, 600.0], 40.0),
            capsule("bar", [-300.0, -300.0, 700.0], [-300.0, 300.0, 750.0], 25.0),
            halfspace("floor", [0.0, 0.0, -50.0], [0.0, 0.0, 1.0]))


def _checker_distances(robot, poses, obstacles) -> np.ndarray:
    """(N, links, obstacles) ikbench's signed distances [mm] of each link to each obstacle."""
    model = collision_model(robot)
    assert model is not None
    report = model.check(poses, obstacles)
    links = list(dict.fromkeys(c.link for c in model.capsules))
    names = [o.name for o in obstacles]
    out = np.full((len(poses), len(links), len(names)), np.inf)
    for p, (a, b) in enumerate(report.pairs):
        if report.is_env[p]:
            out[:, links.index(a), names.index(b)] = report.distances_mm[:, p]
    return out


def _poses(robot) -> np.ndarray:
    rng = np.random.default_rng(7)
    lo, hi = robot.sample_lower, robot.sample_upper
    return lo + rng.random((4, robot.dof)) * (hi - lo)


def _scene_and_distances(robot):
    """The test's obstacles, their scene, four poses, the checker's distances (pose, capsule
    link, obstacle) [mm] and the capsules' links in that order."""
    obstacles = _obstacles()
    poses = _poses(robot)
    links = list(dict.fromkeys(c.link for c in collision_model(robot).capsules))
    return (obstacles, scene_of(robot, obstacles), poses,
            _checker_distances(robot, poses, obstacles), links)


def test_drakes_geometry_is_ikbenchs(panda):
    """Drake's signed distances on the plant with collision geometry equal the checker's
    (within 0.1 mm) for a box, a sphere, a capsule and a half-space (a large box for Drake)."""
    pytest.importorskip("pydrake")
    from ikbench.baselines.drake.common import drake_scene_chain
    from ikbench.schemes.chain import chain_of

    obstacles, scene, poses, expected, links = _scene_and_distances(panda)
    drake = drake_scene_chain(chain_of(panda), scene)
    names = [obstacle_shape(o, k).name for k, o in enumerate(obstacles)]
    for i, pose in enumerate(poses):
        drake.plant.SetPositions(drake.context, drake.positions(panda.to_urdf(pose)))
        query = drake.plant.get_geometry_query_input_port().Eval(drake.context)
        inspector = query.inspector()
        got = np.full(expected.shape[1:], np.inf)
        for pair in query.ComputeSignedDistancePairwiseClosestPoints(0.3):
            a, b = (inspector.GetName(pair.id_A).split("::")[-1],
                    inspector.GetName(pair.id_B).split("::")[-1])
            if b.startswith("obstacle") and not a.startswith("obstacle"):
                link = a.split("__")[0]
                k = names.index(b)
                got[links.index(link), k] = min(got[links.index(link), k],
                                                pair.distance * 1000.0)
        near = expected[i] < 250.0
        near[links.index("panda_link0")] = False  # welded to the world: Drake filters it
        assert np.all(np.isfinite(got[near]))
        np.testing.assert_allclose(got[near], expected[i][near], atol=0.1, rtol=0)


def test_mujocos_geometry_is_ikbenchs(panda):
    """MuJoCo's geom distances (mj_geomDistance) on mink's model with the geoms equal the
    checker's (within 0.1 mm)."""
    mujoco = pytest.importorskip("mujoco")
    pytest.importorskip("mink")
    from ikbench.baselines.mink_ik import mink_scene_model
    from ikbench.schemes.chain import chain_of

    _, scene, poses, expected, links = _scene_and_distances(panda)
    m = mink_scene_model(chain_of(panda), scene)
    data = mujoco.MjData(m.model)
    fromto = np.zeros(6)
    for i, pose in enumerate(poses):
        data.qpos[m.qpos] = panda.to_urdf(pose)
        mujoco.mj_kinematics(m.model, data)
        for shape in scene.links:
            for k, obstacle in enumerate(scene.obstacles):
                want = expected[i, links.index(shape.link), k]
                if want > 250.0:
                    continue
                d = mujoco.mj_geomDistance(m.model, data, m.model.geom(shape.name).id,
                                           m.model.geom(obstacle.name).id, 1.0, fromto)
                # one capsule per link on the panda: the link's distance is the capsule's
                assert d * 1000.0 == pytest.approx(want, abs=0.1)
