"""The sequential damped-least-squares IK baseline: single-point IK, the walk, options, CLI."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ikbench.baselines.sequential_ik import (
    DLSSettings,
    Residual,
    SequentialIK,
    check_tasks,
    dls_step,
    format_vector,
    parse_up_vector,
    rotation_from_z,
    solve_point,
    walk,
    walk_joint_rad,
)
from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.metrics import line_distances_mm, pointing_deviations_deg
from ikbench.core.task import line_task, line_tasks
from tests.conftest import PAPER_START

TOUCH_7 = [34, 17, 39, 107, 106, 78, -180]  # the paper's touch pose 7


def _random_poses(robot, count, seed):
    """Poses [motor deg] well inside the motor ranges (10 % margin), seeded."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.lower, robot.upper
    return lo + (0.1 + 0.8 * rng.random((count, robot.dof))) * (hi - lo)


def _solve_back(robot, pose_deg, orientation, rng, settings=None):
    """FK of ``pose_deg`` as the goal; solve from a perturbed pose; return the solved pose."""
    pin_fk = robot.pinocchio_fk()
    data = pin_fk.model.createData()
    lower, upper = pin_fk.model.lowerPositionLimit, pin_fk.model.upperPositionLimit
    q_true = robot.motor_to_joint_rad(pose_deg)
    goal = pin_fk.placement(q_true)
    residual = Residual(pin_fk, data, orientation, goal.translation.copy(),
                        rotation=goal.rotation.copy() if orientation == "frame" else None,
                        direction=goal.rotation[:, 2].copy() if orientation == "pointing"
                        else None)
    q0 = np.clip(q_true + np.radians(rng.normal(0.0, 4.0, len(q_true))), lower, upper)
    result = solve_point(residual, q0, settings or DLSSettings(orientation=orientation),
                         lower, upper)
    return result, robot.joint_rad_to_motor_deg(result.q_rad)


@pytest.mark.parametrize("orientation", ["position", "pointing", "frame"])
def test_ik_of_an_fk_point_returns_to_that_fingertip_point(robot, orientation):
    rng = np.random.default_rng(11)
    for pose in _random_poses(robot, 8, seed=3):
        result, solved_deg = _solve_back(robot, pose, orientation, rng)
        assert result.converged, (pose, result)
        # cross-check with the other FK backend (pytorch-kinematics, float64)
        goal = robot.fk(pose, backend="torch")
        got = robot.fk(solved_deg, backend="torch")
        assert np.linalg.norm(got.point_mm - goal.point_mm) < 3e-3  # 3 micrometres
        if orientation != "position":
            assert pointing_deviations_deg(got.direction, goal.direction)[0] < 1e-3


def test_frame_mode_recovers_the_whole_frame(robot):
    rng = np.random.default_rng(5)
    pin_fk = robot.pinocchio_fk()
    for pose in _random_poses(robot, 5, seed=8):
        result, solved_deg = _solve_back(robot, pose, "frame", rng)
        goal = pin_fk.placement(robot.motor_to_joint_rad(pose))
        rotation_goal = goal.rotation.copy()
        got = pin_fk.placement(robot.motor_to_joint_rad(solved_deg))
        angle = np.arccos(np.clip((np.trace(got.rotation.T @ rotation_goal) - 1) / 2, -1, 1))
        assert result.converged and np.degrees(angle) < 1e-3


def test_unreachable_point_stops_unconverged_within_limits(robot):
    pin_fk = robot.pinocchio_fk()
    lower, upper = pin_fk.model.lowerPositionLimit, pin_fk.model.upperPositionLimit
    residual = Residual(pin_fk, pin_fk.model.createData(), "position", np.array([2.0, 0, 0]))
    q0 = robot.motor_to_joint_rad(np.array(PAPER_START))
    result = solve_point(residual, q0, DLSSettings(max_ik_iterations=50), lower, upper)
    assert not result.converged
    assert result.error_norm > 1.0
    assert np.all(result.q_rad >= lower) and np.all(result.q_rad <= upper)


def test_dls_step_leaves_out_joints_pushed_past_a_limit():
    J = np.eye(3)
    lower, upper = -np.ones(3), np.ones(3)
    q = np.array([-1.0, 0.0, 1.0])  # joint 0 on its lower, joint 2 on its upper limit
    dq = dls_step(J, np.array([-0.5, 0.3, -0.2]), 1e-6, q, lower, upper)
    assert dq[0] == 0.0  # would leave through the lower limit: dropped
    assert dq[1] == pytest.approx(0.3, rel=1e-6)
    assert dq[2] == pytest.approx(-0.2, rel=1e-6)  # moves back inside: kept


def test_rotation_from_z_builds_a_right_handed_frame_with_z_along_d():
    d = np.array([-0.55, -0.42, -0.73])
    d /= np.linalg.norm(d)
    up = np.array([0.0, 0.0, 1.0])
    R = rotation_from_z(d, up)
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert np.allclose(R[:, 2], d)
    assert abs(R[:, 0] @ up) < 1e-12  # x = up x d is orthogonal to up
    with pytest.raises(InputError, match="parallel") as error:
        rotation_from_z(d, 2 * d)
    assert "float64" not in str(error.value)
    assert "(-1.09357, -0.835087, -1.45146) is parallel to the goal direction (-0.546783, " \
        "-0.417544, -0.725731)" in str(error.value)


def test_vectors_in_messages_are_plain_numbers():
    assert format_vector(np.array([np.float64(-0.5312345678), 0.0, 1e-7])) == \
        "(-0.531235, 0, 1e-07)"


def test_up_vector_parallel_to_a_line_fails_before_any_solve(robot, paper_targets):
    task = line_tasks(robot, paper_targets.select("3"))[0]
    settings = DLSSettings(scheme="walk", orientation="frame",
                           up_vector=tuple(-task.goal.directions[0]))
    with pytest.raises(InputError, match=r"--up-vector: \(.*\) is parallel to the goal "
                       r"direction of trajectory 3 \(-?0\.\d+, "):
        check_tasks(robot, [task], settings)
    check_tasks(robot, [task], DLSSettings(orientation="position",
                                           up_vector=settings.up_vector))  # unused there


def test_cli_parallel_up_vector_is_one_readable_line_and_creates_nothing(
        robot, paper_targets, tmp_path, capsys):
    d = line_tasks(robot, paper_targets.select("1"))[0].goal.directions[0]
    out = tmp_path / "out"
    code = main(["run", "--method", "sequential-ik-walk", "--only", "1", "--output", str(out),
                 f"--up-vector={','.join(repr(float(v)) for v in d)}", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "is parallel to the goal direction of trajectory 1" in err
    assert "np.float64" not in err and "[" not in err
    assert not out.exists()


@pytest.mark.parametrize("orientation", ["frame", "pointing", "position"])
def test_walk_joint_values_respect_the_limits_and_the_walk_is_deterministic(
        robot, paper_targets, orientation):
    settings = DLSSettings(orientation=orientation)
    pin_fk = robot.pinocchio_fk()
    lower, upper = pin_fk.model.lowerPositionLimit, pin_fk.model.upperPositionLimit
    for task in line_tasks(robot, paper_targets.with_steps(20)):
        raw = walk_joint_rad(robot, task, settings)
        # the IK's own joint values [rad], before any conversion or clip: inside the URDF
        assert raw.q_rad.shape == (21, robot.dof)
        assert np.all(raw.q_rad >= lower) and np.all(raw.q_rad <= upper)
        # ... and so inside the motor ranges: walk()'s final clip moves nothing
        motor_deg = robot.joint_rad_to_motor_deg(raw.q_rad)
        assert np.all(motor_deg >= robot.lower - 1e-9)
        assert np.all(motor_deg <= robot.upper + 1e-9)
        first, second = walk(robot, task, settings), walk(robot, task, settings)
        assert np.max(np.abs(first.poses - motor_deg)) <= 1e-9
        assert np.array_equal(first.poses, second.poses)
        assert first.iterations == raw.iterations >= task.goal.steps and first.loss is None
        assert first.info["points_not_converged"] == raw.points_not_converged
        assert first.converged == (raw.points_not_converged == 0)


@pytest.mark.parametrize("orientation", ["frame", "pointing", "position"])
def test_the_walk_starts_at_the_touch_pose_and_solves_point_n_minus_1_from_it(
        robot, paper_targets, orientation):
    """Pose n is the touch pose by design (the walk's start, not solved; the module doc);
    pose n-1 is the IK's first solve, from that pose, for P_{n-1}."""
    settings = DLSSettings(orientation=orientation)
    for task in line_tasks(robot, paper_targets.with_steps(20)):
        raw = walk_joint_rad(robot, task, settings)
        # row n is the touch pose in radians: its conversion back changes it by round-off only
        assert np.max(np.abs(robot.joint_rad_to_motor_deg(raw.q_rad[-1])
                             - task.required.end_pose)) < 1e-9
        solution = walk(robot, task, settings)
        fk = robot.fk(solution.poses, backend="torch")
        error_mm = np.linalg.norm(fk.point_mm - task.goal.points_mm, axis=1)
        assert error_mm[-1] < 1e-9  # P_n = P_e
        assert 0.0 < np.max(np.abs(solution.poses[-2] - solution.poses[-1]))
        # the largest point error the solver reports is what the written poses show
        assert np.max(error_mm[:-1]) == pytest.approx(
            solution.info["max_position_error_mm"], abs=1e-6)
        if orientation != "frame":  # reachable: the IK itself lands on P_{n-1}
            assert error_mm[-2] < 1e-3


@pytest.mark.parametrize("orientation", ["pointing", "position"])
def test_reachable_modes_follow_the_line_exactly(robot, paper_targets, orientation):
    for task in line_tasks(robot, paper_targets):
        solution = walk(robot, task, DLSSettings(orientation=orientation))
        assert solution.info["points_not_converged"] == 0
        fk = robot.fk(solution.poses, backend="torch")
        assert np.max(line_distances_mm(fk.point_mm, task.goal.start_point_mm,
                                        task.goal.end_point_mm)) < 1e-2
        assert np.linalg.norm(fk.point_mm[0] - task.goal.start_point_mm) < 1e-2
        if orientation == "pointing":  # every solved pose points along d (the touch pose need not)
            assert np.max(pointing_deviations_deg(fk.direction[:-1], task.goal.directions[0])) \
                < 1e-2


def test_the_walk_starts_next_to_the_touch_pose(robot):
    task = line_task(robot, PAPER_START, TOUCH_7, 50, "7")
    solution = walk(robot, task, DLSSettings(orientation="position"))
    # pose n-1 is solved from the touch pose for a point 1/50 of the line away: a small step
    assert np.max(np.abs(solution.poses[-2] - solution.poses[-1])) < 5.0


def test_frame_target_with_the_touch_roll_is_reached_on_trajectory_7(robot):
    task = line_task(robot, PAPER_START, TOUCH_7, 50, "7")
    solution = walk(robot, task, DLSSettings())
    assert solution.info["points_not_converged"] == 0
    assert solution.info["max_position_error_mm"] < 1e-3
    assert solution.info["max_orientation_error_deg"] < 1e-3


def test_up_vector_parsing():
    assert parse_up_vector("touch") == "touch"
    assert parse_up_vector("0, 0, 1") == (0.0, 0.0, 1.0)
    assert parse_up_vector([1, 0, 0]) == (1.0, 0.0, 0.0)
    for bad in ("0,0,0", "1,2", "a,b,c", "1,nan,0"):
        with pytest.raises(InputError, match="--up-vector"):
            parse_up_vector(bad)


@pytest.mark.parametrize("kwargs, flag", [
    ({"orientation": "roll"}, "--orientation"), ({"damping": 0.0}, "--damping"),
    ({"ik_step": 1.5}, "--ik-step"), ({"tolerance": -1.0}, "--tolerance"),
    ({"max_ik_iterations": 0}, "--max-ik-iterations"),
])
def test_bad_options_name_the_flag(kwargs, flag):
    with pytest.raises(InputError, match=flag):
        SequentialIK(**kwargs)


def test_cli_runs_both_orientation_modes_and_writes_table2(tmp_path, capsys):
    for orientation in ("frame", "pointing"):
        out = tmp_path / orientation
        code = main(["run", "--method", "sequential-ik", "--orientation", orientation,
                     "--only", "1,7", "--steps", "10", "--output", str(out), "--quiet",
                     "--no-animation"])
        assert code == 0
        folder = out / "sequential-ik"
        assert {p.name for p in folder.glob("trajectory_*.csv")} == {"trajectory_1.csv",
                                                                    "trajectory_7.csv"}
        report = (folder / "report.md").read_text()
        assert "Beside the paper's Table 2" in report and "ikpy" in report
        assert "points_not_converged" in (folder / "details.csv").read_text()
    capsys.readouterr()


def test_cli_bad_option_is_one_line_exit_2(tmp_path, capsys):
    code = main(["run", "--method", "sequential-ik", "--damping", "-1", "--only", "1",
                 "--output", str(tmp_path), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "--damping" in err
    code = main(["run", "--method", "sequential-ik", "--up-vector", "0,0,0", "--only", "1",
                 "--output", str(tmp_path), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--up-vector" in err


def test_a_smaller_run_removes_stale_trajectories_of_its_folder(tmp_path, capsys):
    common = ["run", "--method", "sequential-ik", "--steps", "4", "--output", str(tmp_path),
              "--quiet", "--no-animation"]
    assert main([*common, "--only", "1,7"]) == 0
    folder = tmp_path / "sequential-ik"
    (folder / "notes.txt").write_text("mine")
    (folder / "trajectory_7.csv.bak").write_text("mine")
    assert main([*common, "--only", "1"]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in folder.glob("trajectory_*")) == ["trajectory_1.csv",
                                                                   "trajectory_7.csv.bak"]
    assert (folder / "notes.txt").read_text() == "mine"
    table = pd.read_csv(folder / "table.csv", dtype={"trajectory": str})
    assert list(table["trajectory"]) == ["1"]


def test_report_shows_durations_to_four_decimals(tmp_path, capsys):
    """A few-ms walk must not read 0.01 s (two decimals)."""
    assert main(["run", "--method", "sequential-ik", "--only", "7", "--steps", "4",
                 "--output", str(tmp_path), "--quiet", "--no-animation"]) == 0
    capsys.readouterr()
    folder = tmp_path / "sequential-ik"
    duration = pd.read_csv(folder / "table.csv")["duration_s"].iloc[0]
    row = next(line for line in (folder / "report.md").read_text().splitlines()
               if line.startswith("| 7 |"))
    assert f"| {duration:.4f} |" in row
