"""Timing along the path (--timing constant|min-jerk|topp): the limits hold by finite
differences of the outputs, topp beats the constant timing within the same limits, min-jerk is
the analytic bell, the ROS export is self-consistent, the emulator plays topp within the servo
limits, and constant is what it always was."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import ikbench
from ikbench.cli import main
from ikbench.core.timing import (
    Limits,
    constant_duration_within,
    finite_differences,
    limit_use,
    min_jerk_inverse,
    min_jerk_profile,
    retime,
)
from ikbench.core.timing_topp import toppra_available
from ikbench.core.trajectory import read_trajectory_csv
from ikbench.hw.limits import timing_limits

REPO = Path(__file__).resolve().parents[1]
PAPER = [REPO / "results" / "ours" / f"trajectory_{i}.csv" for i in range(1, 8)]
PANDA = REPO / "results" / "cartesian" / "ours-lm" / "trajectory_panda__1cube_seed1.csv"
#: "within the stated limits (to 1 %)"
TOLERANCE = 1.01
needs_toppra = pytest.mark.skipif(not toppra_available(), reason="needs toppra")


def _poses(robot, path: Path) -> np.ndarray:
    return read_trajectory_csv(path, robot)[list(robot.joint_names)].to_numpy(dtype=float)


def _check_topp(robot, poses, limits: Limits):
    """Every check of the issue on one path; returns the timing."""
    timed = retime(robot, poses, "topp", limits=limits)
    assert np.all(np.diff(timed.times_s) > 0)
    np.testing.assert_array_equal(timed.poses, poses)  # the path is kept
    v_use, a_use = limit_use(timed.times_s, poses, limits)  # the plan's samples
    assert v_use.max() <= TOLERANCE and a_use.max() <= TOLERANCE
    t = np.linspace(0.0, timed.duration_s, 4001)  # the motion between them, densely
    v_dense, a_dense = limit_use(t, timed.sample(t)[0], limits)
    assert v_dense.max() <= TOLERANCE and a_dense.max() <= TOLERANCE
    assert v_use.max() > 0.9 or a_use.max() > 0.9  # time-optimal: some limit is reached
    assert timed.duration_s <= constant_duration_within(poses, limits)
    np.testing.assert_allclose(timed.velocity[[0, -1]], 0.0, atol=1e-9)  # rest to rest
    return timed


@needs_toppra
@pytest.mark.parametrize("path", PAPER, ids=lambda p: p.stem)
def test_topp_on_the_papers_trajectories_stays_within_nicos_servo_limits(path):
    robot = ikbench.load_robot()
    limits = timing_limits(robot)
    np.testing.assert_array_equal(limits.velocity, 270.0)  # the Dynamixel table
    np.testing.assert_array_equal(limits.acceleration, 1000.0)
    _check_topp(robot, _poses(robot, path), limits)


@needs_toppra
def test_topp_on_a_panda_pose_path_stays_within_its_urdf_and_moveit_limits():
    robot = ikbench.load_robot("panda")
    limits = timing_limits(robot)
    rad = np.pi / 180.0
    np.testing.assert_allclose(limits.velocity * rad, [2.175] * 4 + [2.61] * 3)  # the URDF
    np.testing.assert_allclose(limits.acceleration * rad, [3.75, 1.875, 2.5, 3.125, 3.75, 5, 5])
    assert "panda.limits.json" in limits.source
    _check_topp(robot, _poses(robot, PANDA), limits)


def test_finite_differences_count_the_rest_at_both_ends():
    times, q = np.array([0.0, 1.0, 2.0]), np.array([[0.0], [1.0], [2.0]])
    v, a = finite_differences(times, q)
    np.testing.assert_allclose(v[:, 0], [1.0, 1.0])
    np.testing.assert_allclose(a[:, 0], [2.0, 0.0, -2.0])  # (1 - 0) / (1 / 2)
    limits = Limits(np.array([1.0]), np.array([2.0]), "test")
    assert constant_duration_within(q, limits) == pytest.approx(2.0)


def test_min_jerk_profile_and_its_inverse():
    tau = np.linspace(0.0, 1.0, 101)
    u, du, ddu = min_jerk_profile(tau)
    assert u[0] == 0.0 and u[-1] == 1.0 and du[0] == du[-1] == 0.0 and ddu[0] == ddu[-1] == 0.0
    assert du.max() == pytest.approx(1.875)
    np.testing.assert_allclose(min_jerk_profile(min_jerk_inverse(u))[0], u, atol=1e-14)
    np.testing.assert_allclose(min_jerk_inverse(u), tau, atol=1e-5)  # flat at both ends


@pytest.mark.parametrize("path", PAPER, ids=lambda p: p.stem)
def test_min_jerk_moves_the_fingertip_on_the_analytic_bell(path):
    robot = ikbench.load_robot()
    poses = _poses(robot, path)
    timed = retime(robot, poses, "min-jerk", duration_s=2.0)
    assert timed.duration_s == 2.0 and timed.acceleration is not None
    tip = robot.fk(poses).point_mm
    length_mm = np.linalg.norm(np.diff(tip, axis=0), axis=1).sum()  # the path's arc length
    t = np.linspace(0.0, 2.0, 4001)
    q, qd, _ = timed.sample(t)
    np.testing.assert_allclose(qd[[0, -1]], 0.0, atol=1e-9)  # zero speed at both ends
    points = robot.fk(q).point_mm
    speed = np.linalg.norm(np.diff(points, axis=0), axis=1) / np.diff(t)
    t_mid = 0.5 * (t[1:] + t[:-1])
    analytic = length_mm / 2.0 * min_jerk_profile(t_mid / 2.0)[1]
    peak = analytic.max()
    assert np.abs(speed - analytic).max() <= 0.01 * peak
    assert speed[0] < 0.01 * peak and speed[-1] < 0.01 * peak


def test_min_jerk_refuses_a_path_where_the_fingertip_does_not_move():
    robot = ikbench.load_robot()
    poses = np.repeat(ikbench.load_targets(None, robot).start_pose[None], 5, axis=0)
    with pytest.raises(ikbench.InputError, match="fingertip does not move"):
        retime(robot, poses, "min-jerk")


def _export(tmp_path, capsys, *extra) -> tuple[dict, str]:
    out = tmp_path / "t.json"
    assert main(["export", str(PAPER[0]), "--format", "ros-json", "--output", str(out),
                 *extra]) == 0
    return json.loads(out.read_text()), capsys.readouterr().err


@pytest.mark.parametrize("timing", ["min-jerk", pytest.param("topp", marks=needs_toppra)])
def test_ros_export_velocities_agree_with_finite_differences(tmp_path, capsys, timing):
    robot = ikbench.load_robot()
    message, note = _export(tmp_path, capsys, "--timing", timing)
    from ikbench.viewer.export import from_joint_trajectory

    _, q, t = from_joint_trajectory(message)
    v = np.array([p["velocities"] for p in message["points"]])
    a = np.array([p["accelerations"] for p in message["points"]])
    assert a.shape == v.shape and np.allclose(v[[0, -1]], 0.0)
    assert np.allclose(np.diff(t)[:-1], 1 / 250, atol=2e-9)  # 250 Hz
    assert 0.5 / 250 <= t[-1] - t[-2] < 1.5 / 250  # and the end
    fd = (q[2:] - q[:-2]) / (t[2:] - t[:-2])[:, None]
    scale = np.abs(robot.scale) * np.pi / 180  # rad per motor deg
    reference = (timing_limits(robot).velocity * scale if timing == "topp"
                 else np.abs(v).max(axis=0))
    assert (np.abs(fd - v[1:-1]) / reference).max() <= 0.01
    assert "fingertip strays up to" in note
    if timing == "topp":  # the output samples keep the limits too
        limits = timing_limits(robot)
        v_use, a_use = limit_use(t, robot.from_urdf(q), limits)
        assert v_use.max() <= TOLERANCE and a_use.max() <= TOLERANCE


def test_constant_is_the_default_and_byte_identical(tmp_path, capsys):
    default = tmp_path / "d.yaml"
    for name, extra in (("d.yaml", []), ("c.yaml", ["--timing", "constant"])):
        assert main(["export", str(PAPER[1]), "--format", "ros-yaml", "--output",
                     str(tmp_path / name), *extra]) == 0
        assert main(["plan", str(PAPER[1]), "--out", str(tmp_path / f"{name}.plan.csv"),
                     *extra]) == 0
    assert default.read_bytes() == (tmp_path / "c.yaml").read_bytes()
    assert (tmp_path / "d.yaml.plan.csv").read_bytes() == \
        (tmp_path / "c.yaml.plan.csv").read_bytes()
    header = (tmp_path / "d.yaml.plan.csv").read_text().splitlines()[0]
    assert "velocity" not in header and "acceleration" not in header  # today's columns
    message = json.loads(json.dumps(__import__("yaml").safe_load(default.read_text())))
    assert all(p["accelerations"] == [] for p in message["points"])


@needs_toppra
def test_plan_table_carries_the_retimed_times_velocities_and_accelerations(tmp_path, capsys):
    out, figure = tmp_path / "p.csv", tmp_path / "p.png"
    assert main(["plan", str(PAPER[0]), "--timing", "topp", "--out", str(out), "--figure",
                 str(figure)]) == 0
    text = capsys.readouterr().out
    assert "--timing topp" in text and "constant timing within the same limits" in text
    assert figure.stat().st_size > 20_000
    import pandas as pd

    table = pd.read_csv(out)
    assert {"r_elbow_y_velocity_deg_s", "r_elbow_y_acceleration_deg_s2"} <= set(table.columns)
    assert table["t_end_s"].iloc[-1] < 2.0 and not table["flagged"].any()
    assert np.all(table["t_end_s"].to_numpy() > table["t_start_s"].to_numpy())


@needs_toppra
def test_execute_on_the_emulator_plays_topp_within_the_servo_limits():
    from ikbench.hw.emulator import Emulator
    from ikbench.hw.executor import execute
    from ikbench.hw.motors import load_motor_config, raw_to_speed
    from ikbench.hw.plan import plan_trajectory_file

    config = load_motor_config()
    limits = timing_limits(ikbench.load_robot(), config)
    plan, _ = plan_trajectory_file(PAPER[2], config, timing="topp", limits=limits)
    assert plan.timing == "topp" and plan.duration_s < 2.0
    with Emulator(config, plan.poses_motor_deg[0]) as emulator:
        result = execute(plan, emulator.port, log=lambda line: None)
        writes = emulator.sync_writes()
        assert not emulator.violations
    assert result.segments_sent == plan.n_segments == len(writes)
    speeds = np.array([[raw_to_speed(w.word(i, 2)) for i in config.ids] for w in writes])
    goals = np.array([[w.word(i) for i in config.ids] for w in writes])
    np.testing.assert_array_equal(goals, plan.goal_raw)  # the solved poses, retimed
    assert (speeds / config.max_speed_deg_s).max() <= TOLERANCE
    assert (speeds / config.max_speed_deg_s).max() > 0.9  # as fast as the servos allow


@needs_toppra
def test_execute_cli_emulator_topp(capsys):
    assert main(["execute", str(PAPER[3]), "--port", "emulator", "--timing", "topp"]) == 0
    out = capsys.readouterr().out
    assert "--timing topp" in out and "0 limit violations" in out and "goal speeds up to" in out


@pytest.mark.parametrize("args, words", [
    (["--timing", "fast"], "--timing: 'fast'; allowed: constant, min-jerk, topp"),
    (["--timing", "topp", "--max-velocity", "-3"], "--max-velocity: '-3'; give one positive"),
    (["--timing", "topp", "--max-acceleration", "1,2"], "--max-acceleration: '1,2'; give one"),
])
def test_bad_timing_options_are_one_line_errors(tmp_path, capsys, args, words):
    code = main(["plan", str(PAPER[0]), "--out", str(tmp_path / "p.csv"), *args])
    err = capsys.readouterr().err
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "p.csv").exists()


def test_limits_of_a_robot_without_a_stated_acceleration_say_so():
    limits = timing_limits(ikbench.load_robot("fetch"), max_acceleration=None)
    assert "assumed" in limits.source
    np.testing.assert_allclose(limits.acceleration, limits.velocity / 0.5)
    override = timing_limits(ikbench.load_robot(), max_velocity="90", max_acceleration="500")
    np.testing.assert_array_equal(override.velocity, 90.0)
    np.testing.assert_array_equal(override.acceleration, 500.0)


@needs_toppra
def test_viewer_and_animation_play_the_chosen_timing(tmp_path):
    from ikbench.core.task import line_tasks
    from ikbench.render.animation import render_frames
    from ikbench.viewer.folders import load_runs

    robot, runs = load_runs([REPO / "results" / "ours"])
    trajectory = runs[0].trajectories["1"]
    trajectory.retime(robot, "topp", timing_limits(robot))
    assert trajectory.duration_s < 2.0 and trajectory.times_s is not None
    assert trajectory.index_at(trajectory.times_s[7] + 1e-6) == 7
    assert trajectory.index_at(10.0) == trajectory.steps
    tasks = line_tasks(robot, ikbench.load_targets(None, robot))[:2]
    poses = {t.name: _poses(robot, PAPER[int(t.name) - 1]) for t in tasks}
    frames, durations = render_frames(robot, tasks, poses, "", 2.0, max_frames=6, dpi=30,
                                      timing="topp", limits=timing_limits(robot))
    assert len(frames) == 6 and durations[1] < 400  # 5 intervals of a topp T < 2 s


def test_run_times_its_animation(tmp_path, capsys):
    """`ikbench run --timing`: the animation is retimed, the trajectory files are not."""
    from ikbench.cli import main

    for timing in ("constant", "min-jerk"):
        out = tmp_path / timing
        assert main(["run", "--method", "ours-lm", "--only", "1", "--steps", "10", "--timing",
                     timing, "--output", str(out), "--quiet"]) == 0
        assert (out / "ours-lm" / "animation.gif").stat().st_size > 0
    same = [(tmp_path / t / "ours-lm" / "trajectory_1.csv").read_text()
            for t in ("constant", "min-jerk")]
    assert same[0] == same[1]
    gifs = [(tmp_path / t / "ours-lm" / "animation.gif").read_bytes()
            for t in ("constant", "min-jerk")]
    assert gifs[0] != gifs[1]
    capsys.readouterr()
    assert main(["run", "--method", "ours-lm", "--timing", "fast", "--output",
                 str(tmp_path / "bad")]) == 2
    assert capsys.readouterr().err.strip() == (
        "ikbench: error: --timing: 'fast'; allowed: constant, min-jerk, topp")


@needs_toppra
def test_topp_keeps_the_grid_of_its_last_solve_when_refinements_run_out(monkeypatch):
    """When every refinement still finds an interval over a limit, the timing is the last
    solve on its own grid (it once refined the grid once more and failed to broadcast the
    speeds of the old one: the committed fetch rot_yz2 exports)."""
    import ikbench.core.timing_topp as timing_topp
    from ikbench.core.timing_limits import urdf_limits

    monkeypatch.setattr(timing_topp, "REFINEMENTS", 0)
    panda = ikbench.load_robot("panda")
    poses = (np.linspace(0.0, 1.0, 6)[:, None] * np.array([60.0, -40, 30, -50, 20, 60, 40])
             + np.array([0.0, 0, 0, -90, 0, 90, 0]))
    poses[3, 1] += 8.0  # a kink: the first solve exceeds a limit inside an interval
    timed = retime(panda, poses, "topp", limits=urdf_limits(panda))
    assert np.isfinite(timed.duration_s) and timed.duration_s > 0
    np.testing.assert_allclose(timed.sample(timed.times_s)[0], poses, atol=1e-9)


@needs_toppra
def test_a_path_turning_the_hand_about_a_still_fingertip_is_timed_by_pose_index():
    """fetch_arm__rot_yz2 turns the gripper about a fingertip that moves only by the solver's
    jitter (< 0.01 mm a segment); a spline on those chords overshot by metres (topp: T = 2819 s,
    1.77 m off the path). Parametrised by the pose index it follows the path."""
    from ikbench.core.timed_path import STILL_TIP_MM, path_parameter
    from ikbench.core.timing import fingertip_deviation_mm
    from ikbench.core.timing_limits import urdf_limits

    arm = ikbench.load_robot("fetch_arm")
    poses = read_trajectory_csv(Path(__file__).parents[1] / "results" / "cartesian" / "ours-lm"
                                / "trajectory_fetch_arm__rot_yz2_seed1.csv", arm)
    poses = poses[list(arm.joint_names)].to_numpy(dtype=float)
    tip = arm.fk(poses).point_mm
    assert np.linalg.norm(np.diff(tip, axis=0), axis=1).mean() < STILL_TIP_MM
    np.testing.assert_array_equal(path_parameter(tip), np.arange(len(poses)))
    for timing in ("topp", "min-jerk"):
        timed = retime(arm, poses, timing, limits=urdf_limits(arm), duration_s=5.0)
        dense = timed.sample(np.linspace(0.0, timed.duration_s, 4 * len(poses)))[0]
        assert fingertip_deviation_mm(arm, dense, tip) < 1.0, timing
        assert timed.duration_s < 30.0, timing
