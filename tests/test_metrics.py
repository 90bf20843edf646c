"""Metrics on constructed trajectories whose answers are known, and the line task."""

from __future__ import annotations

import numpy as np
import pytest

from ikbench.core.errors import InputError
from ikbench.core.metrics import (
    criterion2_mm,
    line_distances_mm,
    pointing_deviations_deg,
    smoothness,
    trajectory_metrics,
)
from ikbench.core.task import line_task
from tests.conftest import PAPER_START


def test_line_distance_known():
    points = np.array([[0, 0, 0], [5, 3, 4], [-2, 0, 1], [10, 0, 0]], dtype=float)
    got = line_distances_mm(points, [0, 0, 0], [1, 0, 0])
    assert np.allclose(got, [0, 5, 1, 0])


def test_pointing_deviation_known():
    dirs = np.array([[1, 0, 0], [0, 1, 0], [1, 1, 0], [-1, 0, 0]], dtype=float)
    assert np.allclose(pointing_deviations_deg(dirs, [1, 0, 0]), [0, 90, 45, 180])


def test_criterion2_straight_descent_is_zero():
    touch = np.array([10.0, 20.0, 0.0])
    start = np.array([110.0, -30.0, 200.0])
    points = start + np.linspace(0, 1, 11)[:, None] * (touch - start)
    assert np.allclose(criterion2_mm(points, touch), 0.0, atol=1e-9)


def test_criterion2_offset_aim_and_window():
    # Moving straight down 1 mm per step from (5, 0, 10): the ray hits the plane z=0 at
    # (5, 0) for every step, 5 mm from a touch point at the origin.
    points = np.array([[5.0, 0.0, 10.0 - i] for i in range(11)])
    assert np.allclose(criterion2_mm(points, [0, 0, 0]), 5.0)
    # A horizontal first segment never reaches the plane: NaN at step 0 only.
    points2 = np.vstack([[[0.0, 0.0, 10.0]], points[:-1] + [[0, 0, 0]]])
    points2[0] = [4.0, 0.0, 10.0]
    got = criterion2_mm(points2, [0, 0, 0], window=0)
    assert np.isnan(got[0]) and np.allclose(got[2:-1], 5.0)


def test_criterion2_window_averages_the_last_segments_including_the_current():
    # segments: down, down-and-right (+1 mm x), down, down; touch point (1, 0, 0)
    points = np.array([[0, 0, 4], [0, 0, 3], [1, 0, 2], [1, 0, 1], [1, 0, 0]], dtype=float)
    touch = [1.0, 0.0, 0.0]
    # step 2, window 0: segment 2 only, straight down from x = 1: hits the touch point
    assert criterion2_mm(points, touch, window=0)[2] == pytest.approx(0.0)
    # window 1: mean of segments 1 and 2 = (0.5, 0, -1), 2 mm above: lands at x = 2
    assert criterion2_mm(points, touch, window=1)[2] == pytest.approx(1.0)
    # default window (10): segments 0..2, mean (1/3, 0, -1): lands at x = 1 + 2/3
    got = criterion2_mm(points, touch)
    assert got[2] == pytest.approx(2 / 3)
    # step 1: segments 0..1, mean (0.5, 0, -1), 3 mm above from x = 0: lands at x = 1.5
    assert got[1] == pytest.approx(0.5)


def test_start_and_end_errors_known(robot):
    touch = np.array([33, 39, 25, 134, 102, 77, -168], dtype=float)
    task = line_task(robot, PAPER_START, touch, 4, "1")
    poses = np.linspace(PAPER_START, touch, 5)
    poses[0, 3] += 2.0   # r_elbow_y 2 deg off at the start
    poses[-1, 6] -= 3.0  # r_indexfinger_x 3 deg off at the end
    m = trajectory_metrics(robot, task, poses)
    assert m["start_pose_error_deg"] == pytest.approx(2.0)
    assert m["end_pose_error_deg"] == pytest.approx(3.0)
    fk = robot.fk(poses[[0, -1]]).point_mm
    assert m["start_point_error_mm"] == pytest.approx(
        np.linalg.norm(fk[0] - task.goal.start_point_mm))
    assert m["end_point_error_mm"] == pytest.approx(np.linalg.norm(fk[1] - task.goal.end_point_mm))
    assert m["start_point_error_mm"] > 1 and m["end_point_error_mm"] > 0.1


def test_smoothness_known():
    poses = np.zeros((5, 2))
    poses[:, 0] = [0, 1, 0, 1, 0]  # shaking joint: 3 sign changes
    poses[:, 1] = [0, 2, 4, 6, 8]  # constant velocity: no jerk, no sign change
    got = smoothness(poses)
    assert got["mean_sq_joint_step_deg2"] == pytest.approx((4 * 1 + 4 * 4) / 8)
    assert got["max_joint_step_deg"] == 2
    assert got["velocity_sign_changes"] == 3
    # third differences of joint 0: [-4, 4] -> mean square over both joints = 32/4
    assert got["mean_sq_jerk_deg2"] == pytest.approx(8.0)


def test_line_task_geometry(robot):
    touch = [33, 39, 25, 134, 102, 77, -168]
    task = line_task(robot, PAPER_START, touch, 50, "1")
    assert task.goal.points_mm.shape == (51, 3) and task.goal.steps == 50
    fk = robot.fk(np.array([PAPER_START, touch]))
    assert np.allclose(task.goal.start_point_mm, fk.point_mm[0])
    assert np.allclose(task.goal.end_point_mm, fk.point_mm[1])
    d = fk.point_mm[1] - fk.point_mm[0]
    assert np.allclose(task.goal.directions, d / np.linalg.norm(d))
    assert np.allclose(np.diff(task.goal.points_mm, axis=0), d / 50)


def test_line_task_degenerate(robot):
    with pytest.raises(InputError, match="coincide"):
        line_task(robot, PAPER_START, PAPER_START, 10, "x")


def test_trajectory_metrics_of_joint_interpolation(robot):
    touch = np.array([33, 39, 25, 134, 102, 77, -168], dtype=float)
    task = line_task(robot, PAPER_START, touch, 20, "1")
    poses = np.linspace(PAPER_START, touch, 21)
    m = trajectory_metrics(robot, task, poses)
    assert m["start_point_error_mm"] < 1e-9 and m["end_point_error_mm"] < 1e-9
    assert m["start_pose_error_deg"] == 0 and m["end_pose_error_deg"] == 0
    fk = robot.fk(poses)
    dists = line_distances_mm(fk.point_mm, task.goal.start_point_mm, task.goal.end_point_mm)
    assert m["line_distance_mean_mm"] == pytest.approx(dists.mean())
    assert m["line_distance_mean_mm"] > 10  # joint-space interpolation is far from a line
    assert m["velocity_sign_changes"] == 0
