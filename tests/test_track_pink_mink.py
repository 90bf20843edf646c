"""pink and mink on the tracking scheme (ikbench/schemes/track.py): from the recorded start pose
along the goal points onto the touch pose, judged by the task contract on two of NICO's paper
targets; the walk (``scheme="walk"``) still lands on the touch pose but leaves the start pose.

Each library's tests are skipped only when the library is not installed.
"""

from __future__ import annotations

import importlib.util
from dataclasses import replace

import numpy as np
import pytest

from ikbench.core.contract import contract_for, judge
from ikbench.core.errors import InputError
from ikbench.core.metrics import contract_metrics
from ikbench.core.task import line_task
from ikbench.schemes.chain import goals_of
from ikbench.schemes.diffik import SpeedBox, posture_weights

LIBRARIES = {"pink": "pink", "mink": "mink"}
TARGETS = ("1", "7")
STEPS = 50


def method_class(name: str):
    """The method's class; skipped only when its library is not installed."""
    if importlib.util.find_spec(LIBRARIES[name]) is None:
        pytest.skip(f"{name} is not installed")
    if name == "pink":
        from ikbench.baselines.pink_ik import PinkIK

        return PinkIK
    from ikbench.baselines.mink_ik import MinkIK

    return MinkIK


@pytest.fixture(scope="module")
def contract(robot):
    return contract_for(robot, track="paper")


@pytest.fixture(scope="module")
def tasks(robot, paper_targets, contract):
    """Two paper targets as /tmp/check_contract.py builds them: the line from FK(start) to
    FK(touch) in 50 steps, with the paper track's contract."""
    tasks = [line_task(robot, paper_targets.start_pose, paper_targets.touch_poses[name], STEPS,
                       name) for name in TARGETS]
    return [replace(t, required=replace(t.required, contract=contract)) for t in tasks]


def solve_all(robot, method, tasks):
    method.check_tasks(robot, tasks)
    method.prepare(robot)
    return [method.solve(robot, task) for task in tasks]


@pytest.mark.parametrize("name", list(LIBRARIES))
def test_track_meets_the_contract_from_start_to_touch_pose(robot, tasks, contract, name):
    method = method_class(name)()
    assert method.settings.scheme == "track"
    assert method.fixed_poses() == frozenset({"start_pose", "touch_pose"})
    for task, solution in zip(tasks, solve_all(robot, method, tasks)):
        poses = solution.poses
        assert poses.shape == (STEPS + 1, robot.dof)
        np.testing.assert_array_equal(poses[0], task.required.start_pose)
        np.testing.assert_array_equal(poses[-1], task.required.end_pose)
        figures = contract_metrics(robot, task, poses, contract)
        verdict = judge(contract, figures)
        assert set(verdict) >= {"start_pose", "end_pose", "speed", "line", "pointing"}
        assert all(verdict.values()), (name, task.name, verdict, figures)
        assert figures["speed_limit_use"] <= 1.0
        # the box keeps every joint within 95 % of its speed limit
        assert figures["speed_limit_use"] <= 0.95 + 1e-9, figures["speed_limit_use"]
        assert figures["line_distance_max_mm"] < 1e-3, figures["line_distance_max_mm"]
        assert figures["pointing_deviation_judged_mean_deg"] < 5.0
        assert robot.within_limits(poses, tol_deg=0.0)
        assert solution.converged and solution.info["points_not_converged"] == 0
        assert solution.info["scheme"] == "track" and solution.info["speed_box"]


@pytest.mark.parametrize("name", list(LIBRARIES))
def test_walk_lands_on_the_touch_pose_but_leaves_the_start_pose(robot, tasks, name):
    method = method_class(name)(scheme="walk")
    assert method.fixed_poses() == frozenset({"touch_pose"})
    for task, solution in zip(tasks, solve_all(robot, method, tasks)):
        np.testing.assert_array_equal(solution.poses[-1], task.required.end_pose)
        assert np.abs(solution.poses[0] - task.required.start_pose).max() > 1.0


@pytest.mark.parametrize("name", list(LIBRARIES))
def test_track_without_pointing_tracks_the_position_only(robot, tasks, name):
    off = contract_for(robot, track="paper", pointing="off")
    task = replace(tasks[0], required=replace(tasks[0].required, contract=off))
    method = method_class(name)()
    (solution,) = solve_all(robot, method, [task])
    figures = contract_metrics(robot, task, solution.poses, off)
    assert "pointing" not in judge(off, figures)
    assert all(judge(off, figures).values()), figures
    assert figures["line_distance_max_mm"] < 1e-3


@pytest.mark.parametrize("name", list(LIBRARIES))
def test_settings_are_checked(name):
    cls = method_class(name)
    prefix = "pink" if name == "pink" else "mink"
    with pytest.raises(InputError, match="--scheme: 'sideways' is not one of track, walk"):
        cls(scheme="sideways")
    with pytest.raises(InputError, match=f"--{prefix}-speed-fraction"):
        cls(speed_fraction=1.5)
    with pytest.raises(InputError, match=f"--{prefix}-posture-cost"):
        cls(posture_cost=-1.0)


def test_speed_box_bounds():
    step = np.array([0.1, 0.2])
    touch = np.array([1.0, -1.0])
    box = SpeedBox(step, touch, n=10, lower=[-2.0, -2.0], upper=[2.0, 2.0], gain=0.5)
    # step 8 from 0.75: within 0.1 of it and within 2 * 0.1 of the touch pose's 1.0
    box.set_step(8, [0.75, -0.9])
    np.testing.assert_allclose(box.lo, [0.8, -1.1])
    np.testing.assert_allclose(box.hi, [0.85, -0.7])
    # too far to land in time: the landing wins, the nearest value in reach of the touch pose
    box.set_step(9, [0.5, -0.9])
    np.testing.assert_allclose(box.lo, [0.9, -1.1])
    np.testing.assert_allclose(box.hi, [0.9, -0.8])
    G, h = box.inequalities(np.array([0.5, -0.9]))  # G dq <= h: dq <= hi - q, -dq <= q - lo
    np.testing.assert_array_equal(G, np.vstack([np.eye(2), -np.eye(2)]))
    np.testing.assert_allclose(h, [0.4, 0.1, -0.4, 0.2])
    # near a joint limit, which the configuration limit (gain 0.5) lets a QP step cover only
    # half of the way to, the box asks no more than that (the two stay compatible)
    near = SpeedBox(step, [1.95, 0.0], n=10, lower=[-2.0, -2.0], upper=[2.0, 2.0], gain=0.5)
    near.set_step(9, [1.5, 0.0])
    np.testing.assert_allclose(near.lo[0], 1.85)
    G, h = near.inequalities(np.array([1.5, 0.0]))
    assert h[0] == pytest.approx(1.85 - 1.5)
    assert -h[2] == pytest.approx(0.5 * (2.0 - 1.5))
    # continuous joints (infinite limits and steps) give no rows
    free = SpeedBox([np.inf], [0.0], n=4, lower=[-np.inf], upper=[np.inf], gain=0.5)
    free.set_step(1, [0.0])
    G, h = free.inequalities(np.array([0.0]))
    assert G.shape == (0, 1) and h.shape == (0,)


def test_posture_weights_and_segment_step_are_per_pose_unit(robot, tasks, contract):
    weights = posture_weights(robot)
    per_unit = np.abs(robot.to_urdf(np.ones(robot.dof)) - robot.to_urdf(np.zeros(robot.dof)))
    np.testing.assert_allclose(weights * per_unit, np.radians(1.0))
    step = goals_of(robot, tasks[0]).max_step
    np.testing.assert_allclose(step, contract.max_step(STEPS) * per_unit)
