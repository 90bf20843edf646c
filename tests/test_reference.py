"""Reproduce the figures measured from the authors' published trajectories, shipped in
ikbench/paper/data/reference/ (its README.md), with our metrics, to 0.01."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ikbench.core.metrics import trajectory_metrics
from ikbench.core.task import line_tasks
from ikbench.paper.reference import (
    KINDS,
    REFERENCE_DIR,
    TRAJECTORIES,
    authors_trajectory,
    authors_trajectory_path,
)

# k: (line distance mean, std [mm], pointing deviation mean, std [deg])
REFERENCE_FIGURES = {
    "1": (3.13, 1.83, 11.82, 11.81),
    "2": (2.58, 1.27, 11.63, 11.98),
    "3": (2.77, 1.28, 10.77, 10.54),
    "4": (3.77, 2.23, 10.57, 10.19),
    "5": (4.04, 2.49, 11.81, 11.33),
    "6": (3.59, 2.55, 12.67, 13.10),
    "7": (2.32, 2.27, 13.88, 12.10),
}


def test_reference_table_reproduced(robot, paper_targets):
    for task in line_tasks(robot, paper_targets):
        csv = authors_trajectory_path("adam", task.name)
        poses = pd.read_csv(csv)[list(robot.joint_names)].to_numpy()
        m = trajectory_metrics(robot, task, poses)
        got = (m["line_distance_mean_mm"], m["line_distance_std_mm"],
               m["pointing_deviation_mean_deg"], m["pointing_deviation_std_deg"])
        assert got == pytest.approx(REFERENCE_FIGURES[task.name], abs=0.0051), task.name


def test_every_reference_file_is_shipped_and_readable(robot):
    assert (REFERENCE_DIR / "README.md").read_text().count("andylucny/nico2") >= 1
    for kind in KINDS:
        for k in TRAJECTORIES:
            poses = authors_trajectory(kind, k)
            assert poses.shape == (51, robot.dof) and np.isfinite(poses).all(), (kind, k)
    assert authors_trajectory("adam", 1)[0] == pytest.approx(
        [-24.919514, 81.44796, 46.55304, 94.367348, -59.027802, 28.002731, 45.669998])


@pytest.mark.parametrize("kind, k, message", [
    ("ours", 1, "reference kind 'ours' is not one of adam, sequential-ikpy"),
    ("adam", 8, "reference trajectory 8 is not one of 1, 2, 3, 4, 5, 6, 7"),
])
def test_an_unknown_reference_is_named(kind, k, message):
    from ikbench.core.errors import InputError

    with pytest.raises(InputError, match=message):
        authors_trajectory_path(kind, k)
