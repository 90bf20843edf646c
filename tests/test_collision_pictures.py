"""Obstacles and collisions in the pictures (issue 23): the pose-path figure draws a task's
obstacles and marks the colliding waypoints, the animation draws them and turns the arm red
while it collides, the viewer adds them to its scene; tasks without obstacles draw nothing
new."""

from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np
import pytest

from ikbench.core.collision import collision_model
from ikbench.core.obstacles import box, halfspace, sphere
from ikbench.core.problems import load_problem
from ikbench.render.animation import render_frames
from ikbench.render.arm_plots import BOX_FACES, box_corners, colliding_waypoints
from ikbench.render.pose_paths import plot_pose_path, reached


@cache
def _colliding():
    """panda__1cube and poses that track its path through the cube (ours-lm, obstacles
    removed; 200 waypoints, some in collision)."""
    from ikbench.methods.ours_lm import OursLM

    robot, task, _ = load_problem("panda__1cube")
    poses = OursLM(seed=1).solve(robot, dataclasses.replace(
        task, required=dataclasses.replace(task.required, obstacles=()))).poses
    return robot, task, np.asarray(poses, dtype=float)


def _obstacle_artists(ax):
    return [a for a in ax.collections if str(a.get_gid() or "").startswith("obstacle:")]


def test_box_corners_and_faces_are_the_box():
    cube = box("b", [10.0, 20.0, 30.0], [2.0, 4.0, 6.0])
    corners = box_corners(cube)
    assert np.allclose(corners.min(axis=0), [9, 18, 27])
    assert np.allclose(corners.max(axis=0), [11, 22, 33])
    for face in BOX_FACES:  # every face is flat: one coordinate fixed
        assert np.sum(np.ptp(corners[face], axis=0) == 0) == 1


def test_pose_path_figure_draws_the_cube_and_marks_each_colliding_waypoint():
    import matplotlib.pyplot as plt

    robot, task, poses = _colliding()
    truth = collision_model(robot).check(poses, task.required.obstacles)
    colliding = truth.env_colliding | truth.self_colliding
    assert 0 < colliding.sum() < len(poses)  # the case is a real test: some, not all
    curve = reached(robot, task, poses)
    assert np.array_equal(curve["colliding"], colliding)
    fig = plot_pose_path(task, {"ours-lm": curve}, "t", robot)
    ax = fig.axes[0]
    (cube,) = _obstacle_artists(ax)
    assert len(cube.get_paths()) == 6  # six faces ...
    faces = np.asarray(cube._faces)[..., :3].reshape(6, 4, 3)  # ... at the cube's corners
    assert np.allclose(np.sort(faces.reshape(-1, 3), axis=0)[[0, -1]],
                       [[-125, 75, 575], [125, 325, 825]])
    (marks,) = [c for c in ax.collections if c.get_gid() == "collisions"]
    assert len(marks._offsets3d[0]) == colliding.sum()
    assert np.allclose(np.column_stack(marks._offsets3d), curve["points_mm"][colliding])
    labels = ax.get_legend_handles_labels()[1]
    assert f"collision ({colliding.sum()} waypoints)" in labels and "obstacle" in labels
    plt.close(fig)


def test_without_obstacles_the_figure_has_no_obstacle_or_collision_artists():
    import matplotlib.pyplot as plt

    robot, task, poses = _colliding()
    free = dataclasses.replace(task, required=dataclasses.replace(task.required, obstacles=()))
    curve = reached(robot, free, poses)
    assert "colliding" not in curve
    fig = plot_pose_path(free, {"ours-lm": curve}, "t", robot)
    ax = fig.axes[0]
    assert not _obstacle_artists(ax)
    assert not [c for c in ax.collections if c.get_gid() == "collisions"]
    assert not any("collision" in label or "obstacle" in label
                   for label in ax.get_legend_handles_labels()[1])
    plt.close(fig)


def test_a_collision_free_path_says_so_and_other_shapes_are_drawn():
    import matplotlib.pyplot as plt

    robot, task, poses = _colliding()
    far = (sphere("ball", [2000.0, 0.0, 0.0], 50.0),
           halfspace("floor", [0.0, 0.0, -500.0], [0.0, 0.0, 1.0]))
    away = dataclasses.replace(task, required=dataclasses.replace(task.required, obstacles=far))
    curve = reached(robot, away, poses)
    fig = plot_pose_path(away, {"m": curve}, "t", robot)
    ax = fig.axes[0]
    assert {a.get_gid() for a in _obstacle_artists(ax)} == {"obstacle:ball", "obstacle:floor"}
    labels = ax.get_legend_handles_labels()[1]
    assert "collision-free" in labels and "obstacles (2)" in labels
    plt.close(fig)


def _red(frame) -> int:
    f = frame.astype(int)
    return int(((f[..., 0] > 180) & (f[..., 1] < 80) & (f[..., 2] < 80)).sum())


def _brown(frame) -> int:
    """Pixels of the cube's edges and faces: r > g > b, clearly (red has g ~ b)."""
    r, g, b = (frame[..., k].astype(int) for k in range(3))
    return int(((r - g > 8) & (g - b > 8) & (r - b > 25)).sum())


def test_the_animation_draws_the_cube_and_a_red_arm_while_colliding():
    robot, task, poses = _colliding()
    colliding = colliding_waypoints(robot, poses, task.required.obstacles)
    frames, durations = render_frames(robot, [task], {task.name: poses}, "cube", 2.0,
                                      max_frames=len(poses), dpi=40)
    assert len(frames) == len(poses)
    red = np.array([_red(f) for f in frames])
    assert np.all(red[colliding] > 20) and np.all(red[~colliding] == 0)
    free = dataclasses.replace(task, required=dataclasses.replace(task.required, obstacles=()))
    bare, _ = render_frames(robot, [free], {task.name: poses}, "cube", 2.0, max_frames=3,
                            dpi=40)
    assert _brown(frames[0]) > 30 and _brown(bare[0]) == 0  # the cube, in every frame
    assert min(_brown(f) for f in frames) > 30
    assert max(_red(f) for f in bare) == 0


def test_the_viewer_adds_the_obstacles_and_markers_at_colliding_tips():
    viser = pytest.importorskip("viser")
    from ikbench.viewer import scene as sc

    robot, task, poses = _colliding()
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.0, 0.1]
    tips = robot.fk(poses).point_mm
    expect = colliding_waypoints(robot, poses, task.required.obstacles)
    got = sc.colliding_tips_m(robot, poses, tips, task.required.obstacles, T)
    assert np.allclose(got, tips[expect] / 1000.0 + [0, 0, 0.1])
    assert not len(sc.colliding_tips_m(robot, poses, tips, (), T))
    server = viser.ViserServer(port=0, verbose=False)
    try:
        shapes = (*task.required.obstacles, sphere("s", [0, 0, 900], 40.0),
                  halfspace("h", [0, 0, 0], [0, 0, 1]))
        handles = sc.add_obstacles(server, shapes, T, around_mm=tips)
        assert len(handles) == 3
        assert np.allclose(handles[0].position, [0.0, 0.2, 0.8])  # 0.7 m up + 0.1 m
        assert np.allclose(handles[0].dimensions, [0.25, 0.25, 0.25])
        marker = sc.add_collision_markers(server, "/hits", robot, poses, tips,
                                          task.required.obstacles, T)
        assert marker is not None and len(marker.points) == expect.sum()
        assert sc.add_collision_markers(server, "/none", robot, poses, tips, (), T) is None
    finally:
        server.stop()
