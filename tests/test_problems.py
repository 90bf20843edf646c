"""Cartesian path problems in CppFlow's format: the shipped ones, goal poses, bad files.

The reference goal poses below were computed independently of ikbench (a separate script
with its own quaternion conversion and Pinocchio on the makers' Fetch URDF, following
CppFlow's ``offset_target_path``: p + path_xyz_offset + offset frame at q = 0,
R(q_path) @ path_R_offset), rounded to 9 decimals; waypoints 0, 136 and the last.
"""

from __future__ import annotations

import fnmatch
import tomllib
from pathlib import Path

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.problems import (
    data_dir,
    load_problem,
    read_problem,
    resolve_problems,
    shipped_problems,
)
from ikbench.core.rotations import matrix_to_quat_wxyz

REPO = Path(__file__).resolve().parents[1]
#: problem -> waypoint -> (x, y, z [m], qw, qx, qy, qz), base frame
GOALS = {
    "fetch_arm__hello": {
        0: (0.713125, 0.45, 0.62743, 1, 0, 0, 0),
        136: (0.713125, 0.167226, 0.801379, 1, 0, 0, 0),
        552: (0.713125, -0.68285, 0.757618, 1, 0, 0, 0)},
    "fetch__rot_yz2": {
        0: (0.713125, 0.0, 0.72743, 1, 0, 0, 0),
        136: (0.713125, 0.0, 0.72743, 0.988468358, 0, 0, 0.151427556),
        248: (0.713125, 0.0, 0.72743, 1, 0, 0, 0)},
    "panda__square": {
        0: (0.75, 0.0, 0.5, 0.707106781, 0, 0.707106781, 0),
        136: (0.45, 0.155, 0.3, 0.707106781, 0, 0.707106781, 0),
        319: (0.75, 0.0, 0.5, 0.707106781, 0, 0.707106781, 0)},
}


#: CppFlow's benchmark list (cppflow/data_type_utils.py ALL_PROBLEM_FILENAMES, 13 problems).
CPPFLOW_BENCHMARK = [
    "fetch_arm__hello", "fetch_arm__circle", "fetch_arm__rot_yz2", "fetch_arm__s",
    "fetch_arm__square", "fetch__circle", "fetch__hello", "fetch__rot_yz2", "fetch__s",
    "fetch__square", "panda__1cube", "panda__2cubes", "panda__flappy_bird"]
#: Its problems with obstacles (ALL_OBS_PROBLEM_FILENAMES).
CPPFLOW_OBSTACLE_PROBLEMS = [
    "fetch_arm__circle", "fetch_arm__s", "fetch_arm__square", "fetch__circle", "fetch__s",
    "fetch__square", "panda__1cube", "panda__2cubes", "panda__flappy_bird"]


def test_every_problem_of_cppflows_benchmark_ships():
    # the 13 of the benchmark list, plus rot_yz (kept for the older results) and panda__square
    assert sorted(shipped_problems()) == sorted(
        CPPFLOW_BENCHMARK + ["fetch__rot_yz", "fetch_arm__rot_yz", "panda__square"])
    for name in shipped_problems():
        _, task, _ = load_problem(name)
        assert bool(task.required.obstacles) == (name in CPPFLOW_OBSTACLE_PROBLEMS), name
    assert [p.stem for p in resolve_problems("shipped")] == list(shipped_problems())
    assert sorted(p.stem for p in resolve_problems("cppflow")) == sorted(CPPFLOW_BENCHMARK)
    attribution = (data_dir() / "ATTRIBUTION.md").read_text()
    assert "jstmn/cppflow" in attribution and "Permission is hereby granted" in attribution
    assert "TORM" in attribution


def test_the_wheel_carries_the_problem_data():
    """Every file under ikbench/data/cppflow matches a package-data glob of pyproject.toml."""
    globs = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"]["ikbench"]
    files = [str(p.relative_to(REPO / "ikbench")) for p in data_dir().rglob("*") if p.is_file()]
    assert files and all(any(fnmatch.fnmatch(f, g) for g in globs) for f in files), files


@pytest.mark.parametrize("name", sorted(GOALS))
def test_goal_poses_match_an_independent_computation(name):
    robot, task, problem = load_problem(name)
    assert robot.name == name.split("__")[0]
    quats = matrix_to_quat_wxyz(task.goal.rotations)
    for i, goal in GOALS[name].items():
        np.testing.assert_allclose(task.goal.points_mm[i] / 1000.0, goal[:3], atol=1e-9)
        np.testing.assert_allclose(quats[i], goal[3:], atol=1e-8)
    assert task.goal.steps + 1 == max(GOALS[name]) + 1
    np.testing.assert_allclose(task.goal.directions, task.goal.rotations @ robot.pointing_axis)
    lower, upper = task.limits(robot)
    np.testing.assert_array_equal(lower, robot.validity_lower)


def _write(folder: Path, yaml: str, csv: str | None = None, name="mine") -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(yaml)
    if csv is not None:
        (folder / "mypath.csv").write_text(csv)
    return path


GOOD_YAML = ('robot: "panda"\npath_name: "mypath"\npath_offset_frame: "world"\n'
             'path_xyz_offset: [0.5, 0.0, 0.4]\npath_R_offset: [[1, 0, 0], [0, -1, 0], '
             '[0, 0, -1]]\n')
GOOD_CSV = "time,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n1,0,0.01,0,1,0,0,0\n"


def test_a_path_next_to_the_yaml_is_used_and_composed_as_cppflow_does(tmp_path):
    _write(tmp_path, GOOD_YAML, GOOD_CSV)
    robot, task, problem = load_problem(tmp_path / "mine.yaml")
    assert problem.path_file == tmp_path / "mypath.csv" and task.name == "mine"
    np.testing.assert_allclose(task.goal.points_mm, [[500, 0, 400], [500, 10, 400]])
    np.testing.assert_allclose(task.goal.rotations[0], np.diag([1.0, -1.0, -1.0]), atol=1e-15)


def test_the_offset_frame_is_a_link_at_the_zero_configuration(tmp_path):
    yaml = GOOD_YAML.replace('robot: "panda"', 'robot: "fetch"').replace(
        '"world"', '"torso_lift_link"').replace("[[1, 0, 0], [0, -1, 0], [0, 0, -1]]",
                                                 "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]")
    _write(tmp_path, yaml, GOOD_CSV)
    _, task, _ = load_problem(tmp_path / "mine.yaml")
    # torso_lift_link at q = 0: (-0.086875, 0, 0.37743) m in base_link (the maker's URDF)
    np.testing.assert_allclose(task.goal.points_mm[0], [500 - 86.875, 0, 400 + 377.43],
                               atol=1e-9)


@pytest.mark.parametrize("yaml, csv, message", [
    (GOOD_YAML + "obstacles: [[x: 0.4]]\n", GOOD_CSV, "obstacle 0: missing y, z, roll, pitch, "
     "yaw, size_x, size_y, size_z; a CppFlow obstacle has x, y, z"),
    (GOOD_YAML + "obstacles: [{x: 0, y: 0, z: 0, roll: 0, pitch: 0, yaw: 0, size_x: 0, "
     "size_y: 1, size_z: 1}]\n", GOOD_CSV, "size_x, size_y, size_z = [0.0, 1.0, 1.0] must be "
     "positive"),
    (GOOD_YAML + "speed: 3\n", GOOD_CSV, "unknown key(s) 'speed'; allowed: robot, path_name"),
    (GOOD_YAML.replace('path_name: "mypath"\n', ""), GOOD_CSV, "missing key(s) path_name"),
    (GOOD_YAML.replace('"panda"', '"ur5"'), GOOD_CSV, "robot 'ur5' is not a shipped robot"),
    (GOOD_YAML.replace('"world"', '"no_link"'), GOOD_CSV, "path_offset_frame: 'no_link' is "
     "not a link of panda"),
    (GOOD_YAML.replace("[0.5, 0.0, 0.4]", "[0.5, 0.0]"), GOOD_CSV, "path_xyz_offset: [0.5, "
     "0.0] must be [x, y, z]"),
    (GOOD_YAML.replace("[0, -1, 0]", "[0, 2, 0]"), GOOD_CSV, "is not a rotation matrix"),
    (GOOD_YAML.replace("mypath", "nopath"), GOOD_CSV, "path_name 'nopath': no nopath.csv next "
     "to the problem file and no shipped path of that name (1cube, 2cubes, circle, "
     "flappy_bird, hello, rot_yz, rot_yz2, s, square)"),
    (GOOD_YAML + "robot: [\n", GOOD_CSV, "not valid YAML"),
    (GOOD_YAML, "t,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n", "line 1 must be the header "
     "time,x,y,z,qw,qx,qy,qz"),
    (GOOD_YAML, GOOD_CSV + "2,0,0.02,zero,1,0,0,0\n", "line 4: '2,0,0.02,zero,1,0,0,0' is not "
     "8 finite numbers"),
    (GOOD_YAML, GOOD_CSV + "2,0,0.02,0,2,0,0,0\n", "line 4: the quaternion (qw, qx, qy, qz) "
     "has norm 2"),
    (GOOD_YAML, "time,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n", "a path needs at least 2 poses"),
])
def test_bad_problem_files_fail_in_one_line_through_the_cli(tmp_path, capsys, yaml, csv,
                                                             message):
    path = _write(tmp_path, yaml, csv)
    code = main(["run", "--method", "ours-lm", "--problem", str(path), "--output",
                 str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "out").exists()


def test_unknown_problem_names_list_the_shipped_ones():
    with pytest.raises(InputError, match="neither a shipped problem .*fetch_arm__hello"):
        read_problem("fetch_arm__nope")
    with pytest.raises(InputError, match="named twice"):
        resolve_problems("fetch_arm__hello,cppflow")
