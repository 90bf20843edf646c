"""The vectorised line figures equal ikbench.core.metrics, trajectory by trajectory."""

from __future__ import annotations

import numpy as np
import pytest

from ikbench.core.metrics import smoothness, trajectory_metrics
from ikbench.core.metrics_batch import line_metrics, velocity_sign_changes
from ikbench.core.task import line_task
from tests.conftest import PAPER_START

TOUCH = [[33, 39, 25, 134, 102, 77, -168], [57, 33, 40, 134, 80, 36, -159],
         [34, 17, 39, 107, 106, 78, -180]]


def test_line_metrics_equal_trajectory_metrics(robot):
    rng = np.random.default_rng(0)
    tasks = [line_task(robot, PAPER_START, pose, 12, str(k)) for k, pose in enumerate(TOUCH)]
    poses = np.stack([np.linspace(t.required.start_pose, t.required.end_pose, 13) for t in tasks])
    poses = np.clip(poses + rng.normal(0.0, 2.0, poses.shape), robot.lower,
                    robot.upper)
    fk = [robot.fk(p) for p in poses]
    ours = line_metrics(np.stack([f.point_mm for f in fk]), np.stack([f.direction for f in fk]),
                        poses, np.stack([t.goal.start_point_mm for t in tasks]),
                        np.stack([t.goal.end_point_mm for t in tasks]),
                        np.stack([t.required.start_pose for t in tasks]),
                        np.stack([t.required.end_pose for t in tasks]))
    for k, task in enumerate(tasks):
        expected = trajectory_metrics(robot, task, poses[k])
        assert set(ours) == set(expected)
        for key, value in expected.items():
            assert ours[key][k] == pytest.approx(value, rel=1e-12, abs=1e-12), key


def test_velocity_sign_changes_equal_smoothness():
    rng = np.random.default_rng(1)
    steps = rng.normal(0.0, 1.0, (40, 9, 3))
    steps[rng.random(steps.shape) < 0.3] = 0.0       # still joints between moves
    steps[rng.random(steps.shape) < 0.1] = 5e-4      # below the threshold
    poses = np.concatenate([np.zeros((40, 1, 3)), np.cumsum(steps, axis=1)], axis=1)
    expected = [smoothness(p)["velocity_sign_changes"] for p in poses]
    assert velocity_sign_changes(np.diff(poses, axis=1)).tolist() == expected
    assert max(expected) > 0
