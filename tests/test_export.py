"""ikbench export: JointTrajectory layout, sec/nanosec, velocities, URDF units through the motor
map (checked against the map file itself), and round trips back to pose units."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.core.robot import load_robot
from ikbench.core.targets import load_targets
from ikbench.core.trajectory import read_trajectory_poses, write_trajectory_csv
from ikbench.viewer.export import (
    joint_trajectory,
    read_export,
    sample_times_ns,
    split_ns,
    to_poses,
)
from tests.conftest import REPO, one_line_error

DATA = Path(__file__).parent / "data"


def _trajectory(robot, targets, target, steps=50):
    """Joint interpolation from the start to a touch pose with a wiggle (not linear)."""
    start, end = targets.start_pose, targets.touch_poses[target]
    s = np.linspace(0.0, 1.0, steps + 1)[:, None]
    return start + (s - 0.05 * np.sin(2 * np.pi * s)) * (end - start)


@pytest.fixture(scope="module")
def nico_csv(tmp_path_factory):
    robot = load_robot()
    path = tmp_path_factory.mktemp("export") / "trajectory_3.csv"
    write_trajectory_csv(path, robot, _trajectory(robot, load_targets(None, robot), "3"))
    return path


def test_ros_json_positions_are_the_motor_maps_urdf_angles_to_1e9_rad(tmp_path, nico_csv):
    assert main(["export", str(nico_csv), "--format", "ros-json", "--output",
                 str(tmp_path / "t.json")]) == 0
    message = json.loads((tmp_path / "t.json").read_text())
    spec = json.loads((REPO / "urdf" / "nico_right_arm.motors.json").read_text())
    names = [j["name"] for j in spec["joints"]]
    assert message["joint_names"] == names
    motor_deg = read_trajectory_poses(nico_csv)
    expected_rad = np.radians(np.array([j["scale"] for j in spec["joints"]]) * motor_deg
                              + np.array([j["offset_deg"] for j in spec["joints"]]))
    positions = np.array([p["positions"] for p in message["points"]])
    assert np.abs(positions - expected_rad).max() < 1e-9


def test_layout_times_and_velocities(nico_csv):
    robot = load_robot()
    poses = read_trajectory_poses(nico_csv, robot)
    message = joint_trajectory(robot, poses, 2.0)
    assert message["header"] == {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""}
    assert len(message["points"]) == 51
    for k, point in enumerate(message["points"]):
        assert list(point) == ["positions", "velocities", "accelerations", "effort",
                               "time_from_start"]
        assert point["accelerations"] == [] and point["effort"] == []
        assert point["time_from_start"] == split_ns(k * 40_000_000)  # T/n = 0.04 s apart
    q = np.array([p["positions"] for p in message["points"]])
    v = np.array([p["velocities"] for p in message["points"]])
    assert not v[0].any() and not v[-1].any()  # at rest at the start and the touch
    np.testing.assert_allclose(v[1:-1], (q[2:] - q[:-2]) / 0.08, rtol=0, atol=1e-12)
    one_sided = joint_trajectory(robot, poses, 2.0, end_velocities="one-sided")
    np.testing.assert_allclose(one_sided["points"][0]["velocities"], (q[1] - q[0]) / 0.04)


@pytest.mark.parametrize("count, duration_s, index, expected", [
    (51, 2.0, 3, {"sec": 0, "nanosec": 120_000_000}),  # 3 * 0.04 is 0.12000000000000001
    (51, 2.0, 25, {"sec": 1, "nanosec": 0}),
    (2, 4.35, 1, {"sec": 4, "nanosec": 350_000_000}),  # int(4.35e9) is 4349999999
    (4, 1.0, 1, {"sec": 0, "nanosec": 333_333_333}),
    (4, 1.0, 2, {"sec": 0, "nanosec": 666_666_667}),
    (3, 7200.000000001, 2, {"sec": 7200, "nanosec": 1}),
])
def test_sec_nanosec(count, duration_s, index, expected):
    stamp = split_ns(sample_times_ns(count, duration_s)[index])
    assert stamp == expected and all(type(x) is int for x in stamp.values())


@pytest.mark.parametrize("fmt", ["ros-json", "ros-yaml", "csv-rad"])
def test_round_trip_back_to_motor_degrees(tmp_path, nico_csv, fmt):
    robot = load_robot()
    out = tmp_path / f"t.{fmt}"
    assert main(["export", str(nico_csv), "--format", fmt, "--output", str(out),
                 "--duration", "3"]) == 0
    names, q_urdf, times_s = read_export(out, fmt)
    assert names == list(robot.joint_names)
    np.testing.assert_allclose(times_s, np.linspace(0.0, 3.0, 51), rtol=0, atol=1e-12)
    back = to_poses(robot, names, q_urdf)
    assert np.abs(back - read_trajectory_poses(nico_csv, robot)).max() < 1e-9  # motor deg


def test_a_urdf_without_motor_map_exports_radians_and_metres(tmp_path):
    arm = load_robot(DATA / "unaligned_arm.urdf", "tool")
    poses = _trajectory(arm, load_targets(DATA / "unaligned_arm.targets.json", arm), "b", 20)
    write_trajectory_csv(tmp_path / "b.csv", arm, poses)
    poses = read_trajectory_poses(tmp_path / "b.csv", arm)  # as written (10 digits)
    args = ["--robot", str(DATA / "unaligned_arm.urdf"), "--end-frame", "tool"]
    assert main(["export", str(tmp_path / "b.csv"), "--format", "ros-yaml", "--output",
                 str(tmp_path / "b.yaml"), *args]) == 0
    names, q_urdf, _ = read_export(tmp_path / "b.yaml", "ros-yaml")
    assert names == ["j1", "slide", "j3", "j4", "roll", "j6"]
    np.testing.assert_allclose(q_urdf[:, 1], poses[:, 1] / 1000.0, rtol=0, atol=1e-12)  # mm->m
    np.testing.assert_allclose(q_urdf[:, 4], np.radians(poses[:, 4]), rtol=0, atol=1e-12)
    # the columns may come in any order
    back = to_poses(arm, names[::-1], q_urdf[:, ::-1])
    np.testing.assert_allclose(back, poses, rtol=0, atol=1e-9)


def test_the_file_duration_differs_from_duration_and_a_note_says_so(tmp_path, nico_csv, capsys):
    assert main(["export", str(nico_csv), "--format", "csv-rad", "--output",
                 str(tmp_path / "t.csv"), "--duration", "4"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ("note: the trajectory's time_s column ends at 2 s; exported over "
                            "4 s (--duration)\n")
    assert "csv-rad written to" in captured.out
    assert (tmp_path / "t.csv").read_text().splitlines()[3].startswith("2,0.16,")
    assert math.isclose(float((tmp_path / "t.csv").read_text().splitlines()[-1].split(",")[1]),
                        4.0)


@pytest.mark.parametrize("args, message", [
    (["missing.csv", "--format", "ros-json", "--output", "{tmp}/x.json"],
     "argument TRAJ.csv|RUN_DIR: 'missing.csv' not found; give a trajectory CSV or a run "
     "folder"),
    (["{csv}", "--format", "ros", "--output", "{tmp}/x.json"], "argument --format: invalid choice"),
    (["{csv}", "--format", "ros-json", "--output", "{tmp}/x.json", "--duration", "-1"],
     "argument --duration: -1 is out of range; give a duration [s] from 0.001 to 3600"),
    (["{csv}", "--format", "ros-json", "--output", "{tmp}"], "it is a directory"),
    (["{csv}", "--format", "ros-json"], "--output: give the file to write (required for a "
                                         "trajectory CSV"),
    (["{csv}", "--format", "ros-json", "--output", "{tmp}/x.json", "--robot", str(
        DATA / "unaligned_arm.urdf"), "--end-frame", "tool"], "missing joint column(s) j1"),
])
def test_bad_input_one_line_exit_2(tmp_path, nico_csv, capsys, args, message):
    args = [a.format(csv=nico_csv, tmp=tmp_path) for a in args]
    assert message in one_line_error(capsys, ["export", *args])
    assert not (tmp_path / "x.json").exists()


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    """A run folder of a robot other than the default (the Panda): export must take its robot
    from run.json."""
    out = tmp_path_factory.mktemp("runs")
    assert main(["run", "--robot", "panda", "--method", "ours-lm", "--only", "front,left",
                 "--steps", "10", "--output", str(out), "--quiet"]) in (0, 1)
    return out / "ours-lm"


def test_a_run_folder_exports_every_trajectory_with_its_runs_robot(run_folder, capsys):
    """Issue 64: docs/index.md's ``ikbench export runs/compare/ours-exact --timing topp``
    failed: export ignored the run's run.json and wanted --robot, --format, --output."""
    assert main(["export", str(run_folder), "--timing", "topp"]) == 0
    out = capsys.readouterr().out
    assert f"ros-json: 2 trajectories of {run_folder} (panda, 7 joints" in out
    written = sorted(p.name for p in (run_folder / "export").iterdir())
    assert written == ["trajectory_front.json", "trajectory_left.json"]
    robot = load_robot("panda")
    message = json.loads((run_folder / "export" / "trajectory_front.json").read_text())
    assert message["joint_names"] == list(robot.joint_names)
    poses = read_trajectory_poses(run_folder / "trajectory_front.csv", robot)
    first = np.array(message["points"][0]["positions"])
    assert np.abs(first - robot.to_urdf(poses[0])).max() < 1e-9
    assert main(["export", str(run_folder), "--format", "csv-rad", "--output",
                 str(run_folder.parent / "rad")]) == 0
    assert sorted(p.name for p in (run_folder.parent / "rad").iterdir()) == \
        ["trajectory_front.csv", "trajectory_left.csv"]


def test_a_folder_of_run_folders_is_one_line_naming_them(run_folder, capsys):
    err = one_line_error(capsys, ["export", str(run_folder.parent)])
    assert "holds no run.json" in err and f"give one of its run folders: {run_folder}" in err
