"""``ikbench robot init`` (issue 49): from a robot of an installed description package (or a
URDF) to a config and targets file that ``letters`` and ``run`` take with no other file."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.core.robot import load_robot
from ikbench.core.robot_init import MAX_LINE_MM, MIN_LINE_MM, auto_axis, choose_end_frame
from ikbench.core.robot_packages import robots_folder
from tests.conftest import REPO

needs_erd = pytest.mark.skipif(robots_folder("example-robot-data") is None,
                               reason="needs example-robot-data: pip install 'ikbench[robots]'")


@needs_erd
def test_robot_init_writes_a_config_and_targets_that_letters_and_run_take(tmp_path, capsys):
    assert main(["robot", "init", "example-robot-data:z1", "--output", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "end frame gripperStator (chosen; other candidates: gripperMover" in err
    assert "pointing axis x of gripperStator" in err  # z1's tool sticks out along x
    config = tomllib.loads((tmp_path / "z1.toml").read_text())
    assert config["end_frame"] == "gripperStator" and config["pointing_axis"] == [1.0, 0, 0]
    robot = load_robot(tmp_path / "z1.toml")
    targets = json.loads((tmp_path / "z1.targets.json").read_text())
    assert len(targets["targets"]) == 7 and targets["joint_names"] == list(robot.joint_names)
    start = robot.fk(np.array(targets["start_pose"])).point_mm[0]
    for pose in targets["targets"].values():
        length = np.linalg.norm(robot.fk(np.array(pose)).point_mm[0] - start)
        assert MIN_LINE_MM <= length <= MAX_LINE_MM
        assert robot.within_limits(np.array([pose]))
    assert main(["letters", "P", "--robot", str(tmp_path / "z1.toml"), "--method", "ours-lm",
                 "--steps", "20", "--output", str(tmp_path / "runs"), "--quiet"]) == 0
    assert (tmp_path / "runs" / "ours-lm" / "trajectory_P.csv").exists()
    assert main(["run", "--robot", str(tmp_path / "z1.toml"), "--method", "sequential-ik",
                 "--only", "1", "--steps", "10", "--output", str(tmp_path / "runs"),
                 "--quiet"]) in (0, 1)
    assert (tmp_path / "runs" / "sequential-ik" / "trajectory_1.csv").exists()


def test_the_end_frame_and_axis_chosen_for_the_shipped_panda():
    """Panda's URDF: the flange's hand (7 joints), its approach axis z."""
    robot = load_robot("panda")
    assert auto_axis(robot) == "z"
    chosen, candidates = choose_end_frame(REPO / "urdf" / "panda.urdf", None)
    assert chosen in candidates


def test_bad_input_is_one_line(tmp_path, capsys):
    assert main(["robot", "init", str(tmp_path / "none.urdf"), "--output", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is neither a URDF file nor a robot of an installed package" in err[0]
    assert main(["robot", "init", str(REPO / "urdf" / "panda.urdf"), "--end-frame", "nope",
                 "--output", str(tmp_path)]) == 2
    assert "nope" in capsys.readouterr().err


def test_an_output_that_is_a_file_is_refused_naming_the_option(tmp_path, capsys):
    """Issue 64: ``--output afile`` said ``afile: File exists``, naming no option."""
    afile = tmp_path / "afile"
    afile.write_text("mine\n")
    assert main(["robot", "init", str(REPO / "urdf" / "panda.urdf"), "--end-frame",
                 "panda_hand", "--output", str(afile)]) == 2
    err = capsys.readouterr().err
    assert err == f"ikbench: error: --output: cannot write {afile}: it is a file, not a " \
                  "directory\n"
    assert afile.read_text() == "mine\n"


@pytest.mark.parametrize("name", ["résumé", "ロボット"])
def test_a_name_of_unicode_letters_is_taken(tmp_path, capsys, name):
    """Issue 64: ``--name résumé`` was refused as not letters."""
    assert main(["robot", "init", str(REPO / "urdf" / "panda.urdf"), "--end-frame",
                 "panda_hand", "--output", str(tmp_path), "--name", name]) == 0
    assert load_robot(tmp_path / f"{name}.toml").name == name


@pytest.mark.parametrize("name", [".hidden", "a/b", "-x", "a b"])
def test_a_name_that_is_no_file_stem_is_refused(tmp_path, capsys, name):
    assert main(["robot", "init", str(REPO / "urdf" / "panda.urdf"), "--end-frame",
                 "panda_hand", "--output", str(tmp_path), f"--name={name}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"ikbench: error: --name: {name!r} must be a file stem") \
        and err.count("\n") == 1, err
    assert not list(tmp_path.iterdir())
