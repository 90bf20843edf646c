"""``ikbench robot init`` (issue 49): from a robot of an installed description package (or a
URDF) to a config and targets file that ``letters`` and ``run`` take with no other file."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.robot import load_robot, robot_from_config
from ikbench.core.robot_init import (
    MAX_LINE_MM,
    MIN_LINE_MM,
    POINTING_DEG,
    START_POINTING_DEG,
    auto_axis,
    choose_end_frame,
    init_robot,
    sensor_like,
)
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


@needs_erd
def test_a_humanoid_gets_an_arm_not_its_gaze_and_the_config_names_the_package(tmp_path, capsys):
    """Issue 64: Romeo's ``gaze`` frame was chosen, the trunk was in the chain and the config
    held an absolute path into the venv. Now: an arm (a gripper frame, not a finger, camera or
    foot); ``--base-link torso`` leaves TrunkYaw out; ``urdf`` is the package name."""
    assert main(["robot", "init", "example-robot-data:romeo", "--output", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "end frame l_gripper (chosen; other candidates: r_gripper," in err
    config = tomllib.loads((tmp_path / "romeo.toml").read_text())
    assert config["urdf"] == config["source"] == "example-robot-data:romeo"
    assert "/" not in (tmp_path / "romeo.toml").read_text().split("[targets]")[0]
    robot = load_robot(tmp_path / "romeo.toml")
    assert robot.end_frame == "l_gripper" and robot.joint_names[0] == "TrunkYaw"
    assert robot.urdf_path.name == "romeo.urdf" and robot.urdf_path.is_file()
    assert main(["robot", "init", "example-robot-data:romeo", "--base-link", "torso",
                 "--end-frame", "r_gripper", "--output", str(tmp_path)]) == 0
    robot = robot_from_config(tmp_path / "romeo.toml")
    assert robot.root_link == "torso" and robot.end_frame == "r_gripper"
    assert robot.joint_names[0] == "RShoulderPitch" and "TrunkYaw" not in robot.joint_names


@needs_erd
def test_a_base_link_above_no_end_frame_is_refused_naming_both(tmp_path, capsys):
    assert main(["robot", "init", "example-robot-data:romeo", "--base-link", "RShoulderPitchLink",
                 "--end-frame", "l_gripper", "--output", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ikbench: error: --base-link: 'RShoulderPitchLink' is not an "
                          "ancestor of the end frame 'l_gripper' in romeo.urdf; its ancestors: ")
    assert err.count("\n") == 1 and not list(tmp_path.iterdir())
    assert main(["robot", "init", "example-robot-data:romeo", "--base-link", "nope",
                 "--output", str(tmp_path)]) == 2
    assert "--base-link: 'nope' is not a link of romeo.urdf" in capsys.readouterr().err


def test_a_config_may_name_a_package_robot_or_a_path(tmp_path):
    """A plain path (relative to the config) keeps working beside the package form."""
    (tmp_path / "mine.toml").write_text(
        f'urdf = "{(REPO / "urdf" / "panda.urdf").as_posix()}"\nend_frame = "panda_hand"\n')
    assert robot_from_config(tmp_path / "mine.toml").dof == 7
    (tmp_path / "bad.toml").write_text('urdf = "example-robot-data:nope"\nend_frame = "x"\n')
    with pytest.raises(InputError, match="urdf: robot: example-robot-data:nope"):
        robot_from_config(tmp_path / "bad.toml")


@pytest.mark.parametrize("link, last", [("gaze", True), ("CameraLeftEye_frame", True),
                                        ("r_sole", True), ("ImuTorsoGyrometer_frame", True),
                                        ("r_gripper", False), ("tool0", False),
                                        ("panda_hand_tcp", False)])
def test_sensor_head_and_foot_frames_rank_last(link, last):
    assert sensor_like(link) is last


def test_the_drawn_touch_poses_point_along_their_lines(tmp_path):
    """The contract judges the pointing at the line's end, where the touch pose fixes it."""
    made = init_robot(str(REPO / "urdf" / "panda.urdf"), "panda_hand", seed=3)
    robot = made["robot"]
    start = robot.fk(np.array(made["targets"]["start_pose"]))
    for pose in made["targets"]["targets"].values():
        end = robot.fk(np.array(pose))
        line = end.point_mm[0] - start.point_mm[0]
        cos = float(end.direction[0] @ line / np.linalg.norm(line))
        assert np.degrees(np.arccos(min(cos, 1.0))) <= POINTING_DEG + 1e-6
    assert "not checked by a solve" in made["targets"]["description"]


def _angles_deg(robot, start_pose, poses) -> list[tuple[float, float]]:
    """Per touch pose: (the end frame's angle to the line at the start, at the touch) [deg]."""
    start = robot.fk(np.array(start_pose))
    angles = []
    for pose in poses:
        end = robot.fk(np.array(pose))
        line = end.point_mm[0] - start.point_mm[0]
        line = line / np.linalg.norm(line)
        angles.append(tuple(float(np.degrees(np.arccos(min(float(d @ line), 1.0))))
                            for d in (start.direction[0], end.direction[0])))
    return angles


def test_the_drawn_lines_start_pointing_along_them_too():
    """The contract judges the pointing from a fifth of the way on: the end frame may not
    start pointing away from the line (issue 64)."""
    made = init_robot(str(REPO / "urdf" / "panda.urdf"), "panda_hand", seed=3)
    angles = _angles_deg(made["robot"], made["targets"]["start_pose"],
                         made["targets"]["targets"].values())
    assert len(angles) == 7
    assert all(at_start <= START_POINTING_DEG + 1e-6 for at_start, _ in angles), angles
    assert "the start pose (the middle of the limits)" in made["targets"]["description"]


@needs_erd
def test_romeos_right_arm_gets_a_start_from_which_its_lines_can_be_pointed_along(tmp_path,
                                                                                 capsys):
    """Romeo's right arm from its torso: from the middle of its limits the gripper points
    112-133 deg away from every line it can draw, so no target was solvable; robot init draws
    a start pose instead, says so, and ours-exact solves every line (issue 64)."""
    assert main(["robot", "init", "example-robot-data:romeo", "--end-frame", "r_gripper",
                 "--base-link", "torso", "--name", "romeo-right", "--check-targets",
                 "--output", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "start pose drawn within the limits by seed [1, 1]" in err
    assert "every target solved" in err
    targets = json.loads((tmp_path / "romeo-right.targets.json").read_text())
    assert "the start pose (drawn within the limits" in targets["description"]
    assert "every target solved" in targets["description"]
    robot = load_robot(tmp_path / "romeo-right.toml")
    assert robot.dof == 7 and robot.end_frame == "r_gripper"
    middle = (robot.lower + robot.upper) / 2
    assert not np.allclose(targets["start_pose"], middle, atol=0.01)
    angles = _angles_deg(robot, targets["start_pose"], targets["targets"].values())
    assert all(a <= START_POINTING_DEG + 1e-6 and b <= POINTING_DEG + 1e-6
               for a, b in angles), angles


@needs_erd
def test_check_targets_solves_each_line_and_says_so(tmp_path, capsys):
    """``--check-targets``: ours-exact solves every default line of Romeo's left arm under
    the contract; the description says how many draws were replaced."""
    assert main(["robot", "init", "example-robot-data:romeo", "--check-targets",
                 "--output", str(tmp_path)]) == 0
    assert "every target solved" in capsys.readouterr().err
    targets = json.loads((tmp_path / "romeo.targets.json").read_text())
    assert "checked under the task contract by ours-exact" in targets["description"]
    assert "of the first 7 draws replaced, every target solved" in targets["description"]
    assert len(targets["targets"]) == 7


def test_an_unsolved_target_is_replaced_by_the_next_draw(monkeypatch):
    """The replacement rule, with a fake judge: the first draw fails, the next one holds."""
    from ikbench.studies import target_check

    made = init_robot(str(REPO / "urdf" / "panda.urdf"), "panda_hand", seed=3)
    first = [list(p) for p in made["targets"]["targets"].values()]
    calls = []

    def fake(robot, solver, start, pose, steps):
        calls.append(list(pose))
        return len(calls) != 1, ([] if len(calls) != 1 else ["line"])

    monkeypatch.setattr(target_check, "_solved", fake)
    check = target_check.check_targets(made)
    kept = list(made["targets"]["targets"].values())
    assert check.replaced == 1 and all(check.solved) and check.solves == 8
    assert kept[0] != first[0] and kept[1:] == first[1:]
    assert "1 of the first 7 draws replaced, every target solved" in \
        made["targets"]["description"]
