"""The task contract (ikbench.core.contract) and the figures it judges (contract_metrics)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ikbench.core.contract import (
    DEFAULT_TOLERANCES,
    Contract,
    contract_for,
    judge,
    parse_tolerances,
)
from ikbench.core.errors import InputError
from ikbench.core.metrics import contract_metrics, line_distances_mm, pointing_deviations_deg
from ikbench.core.robot import load_robot
from ikbench.core.task import line_task, line_tasks

DATA = Path(__file__).parent / "data"


def test_nico_contract_fixes_both_poses_and_allows_10_8_motor_deg_per_segment(robot):
    contract = contract_for(robot)
    assert contract.fixed_poses == ("start_pose", "touch_pose")
    assert contract.pointing  # NICO's config names the finger as pointing axis
    # 270 motor deg/s (the Dynamixel table), T = 2 s, n = 50
    assert np.allclose(contract.max_step(50), 270 * 2 / 50)
    assert np.allclose(contract.max_step(50), 10.8)
    assert "dynamixel" in contract.speed_source
    assert contract.judged_from(50) == 10  # the last 80 % of the steps
    assert contract.criteria() == ["start_pose", "end_pose", "limits", "speed", "line",
                                   "pointing"]
    assert contract.with_track("touch").criteria() == ["end_pose", "limits", "speed", "line",
                                                       "pointing"]
    text = contract.describe(50, "motor deg")
    assert "start pose within 0.5 motor deg" in text and "10.8 motor deg per segment" in text


def test_a_bare_urdf_has_pointing_off_and_its_urdf_velocity_limits():
    robot = load_robot(DATA / "unaligned_arm.urdf", end_frame="tool")
    contract = contract_for(robot)
    assert not contract.pointing and "pointing" not in contract.criteria()
    assert contract_for(robot, pointing="on").pointing
    if contract.max_speed is not None:  # URDF velocity [rad/s, m/s] -> pose units per s
        assert np.all(contract.max_speed > 0)
    targets_tasks = line_tasks(robot, _targets_for(robot), contract)
    assert targets_tasks[0].hints.default_weights["L1"] == 0.0  # ours/ours-lm drop pointing


def _targets_for(robot):
    from ikbench.core.targets import Targets

    rng = np.random.default_rng(0)
    start = robot.sample_lower + 0.4 * (robot.sample_upper - robot.sample_lower)
    touch = start + 0.1 * (robot.sample_upper - robot.sample_lower) * rng.uniform(-1, 1,
                                                                                   robot.dof)
    return Targets(tuple(robot.joint_names), start, {"1": touch}, 10, "test")


@pytest.mark.parametrize("text, message", [
    ("nope=1", "unknown criterion 'nope'"),
    ("start_pose_deg=-1", "must be a number >= 0"),
    ("line_distance_max_mm=x", "must be a number >= 0"),
])
def test_bad_tolerances_name_the_value(text, message):
    with pytest.raises(InputError, match=message):
        parse_tolerances(text)


def test_tolerances_override_only_what_is_named():
    tol = parse_tolerances("start_pose_deg=0.1,line_distance_max_mm=2")
    assert tol == {**DEFAULT_TOLERANCES, "start_pose_deg": 0.1, "line_distance_max_mm": 2.0}


def test_judge_fails_nan_and_checks_each_criterion():
    contract = Contract(max_speed=np.full(7, 270.0))
    good = {"start_pose_error_deg": 0.1, "end_pose_error_deg": 0.0, "within_limits": True,
            "speed_limit_use": 1.0, "line_distance_max_mm": 4.9,
            "pointing_deviation_judged_mean_deg": 14.0}
    assert all(judge(contract, good).values())
    assert judge(contract, {**good, "start_pose_error_deg": 0.6})["start_pose"] is False
    assert judge(contract, {**good, "speed_limit_use": 1.01})["speed"] is False
    assert judge(contract, {**good, "within_limits": False})["limits"] is False
    assert judge(contract, {**good, "pointing_deviation_judged_mean_deg": math.nan})[
        "pointing"] is False
    assert "start_pose" not in judge(contract.with_track("touch"), good)


def test_contract_metrics_against_a_direct_computation(robot, paper_targets):
    contract = contract_for(robot)
    task = line_task(robot, paper_targets.start_pose, paper_targets.touch_poses["3"], 20, "3")
    task = replace(task, required=replace(task.required, contract=contract))
    poses = np.linspace(task.required.start_pose, task.required.end_pose, 21)  # joint interpolation
    poses[5, 0] += 3.0  # one joint jumps: two larger steps
    figures = contract_metrics(robot, task, poses, contract)
    steps = np.abs(np.diff(poses, axis=0))
    assert figures["speed_limit_use"] == pytest.approx(steps.max() / (270 * 2 / 20))
    fk = robot.fk(poses)
    assert figures["line_distance_max_mm"] == pytest.approx(
        line_distances_mm(fk.point_mm, task.goal.start_point_mm, task.goal.end_point_mm).max())
    judged = pointing_deviations_deg(fk.direction[4:], task.goal.directions[4:])  # ceil(0.2 20)
    assert figures["pointing_deviation_judged_mean_deg"] == pytest.approx(judged.mean())
    assert figures["start_pose_error_deg"] == 0 and figures["within_limits"]
    assert figures["max_step_limit_deg"] == pytest.approx(27.0)
