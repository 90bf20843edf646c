"""The run's 3-D figure: one scale on every axis, a view with depth, readable ticks, the goal
line on top of the fingertip path, the arm at the first and last poses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikbench.core.robot import load_robot
from ikbench.core.targets import load_targets
from ikbench.core.task import line_tasks
from ikbench.render.arm_plots import frame_labels, plot_trajectories_3d

DATA = Path(__file__).parent / "data"


def interpolated(robot, targets, only):
    """Line tasks and joint-interpolated poses (no solver needed) of some targets."""
    targets = targets.select(only).with_steps(10)
    tasks = line_tasks(robot, targets)
    poses = {t.name: np.linspace(t.required.start_pose, t.required.end_pose, 11) for t in tasks}
    return tasks, poses, {k: robot.fk(p).point_mm for k, p in poses.items()}


@pytest.mark.parametrize("which", ["nico", "unaligned"])
def test_figure_is_equal_scale_not_face_on_with_goal_over_path_and_arms(which):
    if which == "nico":
        robot, only = load_robot(), "1,3,6"
        targets = load_targets(None, robot)
    else:
        robot, only = load_robot(DATA / "unaligned_arm.urdf", "tool"), None
        targets = load_targets(DATA / "unaligned_arm.targets.json", robot)
    tasks, poses, points = interpolated(robot, targets, only)
    fig = plot_trajectories_3d(tasks, points, "title", robot, poses)
    ax = fig.axes[0]
    spans = [np.diff(getattr(ax, f"get_{a}lim")())[0] for a in "xyz"]
    assert spans == pytest.approx([spans[0]] * 3)
    _, (elev, azim) = frame_labels(robot)
    assert (ax.elev, ax.azim) == (elev, azim) and elev >= 10 and azim % 90 != 0
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        assert 2 <= len([t for t in axis.get_major_locator()()]) <= 6
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert [f"trajectory {t.name}" for t in tasks] == [x for x in labels if "trajectory" in x]
    assert {"goal line", "touch point", "arm at the first pose", "arm at the last pose"} <= set(
        labels)
    lines = ax.get_lines()
    goals = [line for line in lines if line.get_linestyle() == "--" and len(line.get_xdata())]
    paths = [line for line in lines if line.get_label().startswith("trajectory")]
    assert len(goals) == len(paths) == len(tasks)
    assert min(g.get_zorder() for g in goals) > max(p.get_zorder() for p in paths)
    arms = [line for line in lines if line.get_alpha() is not None and line.get_alpha() < 0.5
            and len(line.get_xdata()) == robot.dof + 2]
    assert len(arms) == 1 + len(tasks)  # one shared first pose, each last pose
