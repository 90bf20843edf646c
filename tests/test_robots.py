"""Robots other than NICO: a URDF ikbench has never seen, given as --robot FILE --end-frame.

tests/data/unaligned_arm.urdf has revolute joints about unaligned axes, a prismatic and a
continuous joint, fixed joints with rotations and a branch that is not part of the chain.
Its FK is checked against Pinocchio loading the same URDF on its own (continuous joints as
(cos, sin), the branch joint at 0), and every method must run on it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import ikbench
from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.robot import load_robot
from ikbench.core.targets import load_targets
from ikbench.core.trajectory import read_trajectory_poses

DATA = Path(__file__).parent / "data"
URDF = DATA / "unaligned_arm.urdf"
TARGETS = DATA / "unaligned_arm.targets.json"


@pytest.fixture(scope="module")
def arm():
    return load_robot(URDF, "tool")


def independent_fk_mm(poses):
    """End point [mm] and tool z-axis by Pinocchio on the raw URDF (no ikbench code)."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    frame = model.getFrameId("tool")
    out_p, out_z = [], []
    for pose in poses:
        q = pin.neutral(model)
        values = {"j1": math.radians(pose[0]), "slide": pose[1] / 1000.0,
                  "j3": math.radians(pose[2]), "j4": math.radians(pose[3]),
                  "roll": math.radians(pose[4]), "j6": math.radians(pose[5])}
        for name, value in values.items():
            j = model.getJointId(name)
            i = model.idx_qs[j]
            if model.nqs[j] == 2:  # continuous: (cos, sin)
                q[i:i + 2] = [math.cos(value), math.sin(value)]
            else:
                q[i] = value
        pin.framesForwardKinematics(model, data, q)
        out_p.append(data.oMf[frame].translation * 1000.0)
        out_z.append(data.oMf[frame].rotation[:, 2].copy())
    return np.array(out_p), np.array(out_z)


def random_poses(arm, count, seed=0):
    return np.random.default_rng(seed).uniform(arm.sample_lower, arm.sample_upper,
                                               (count, arm.dof))


def test_chain_units_and_limits_come_from_the_urdf(arm):
    assert arm.joint_names == ("j1", "slide", "j3", "j4", "roll", "j6")
    assert arm.joint_types == ("revolute", "prismatic", "revolute", "revolute", "continuous",
                               "revolute")
    assert arm.pose_unit == "joint deg, mm for prismatic" and not arm.has_motor_map
    assert arm.lower[1] == 0.0 and arm.upper[1] == pytest.approx(250.0)  # mm
    assert arm.upper[0] == pytest.approx(math.degrees(2.5))
    assert arm.lower[4] == -math.inf and arm.upper[4] == math.inf  # continuous: no limits
    assert arm.root_link == "world_link"


@pytest.mark.parametrize("backend", ["pinocchio", "torch"])
def test_fk_agrees_with_pinocchio_on_the_raw_urdf(arm, backend):
    poses = random_poses(arm, 200, seed=1)
    point_mm, z = independent_fk_mm(poses)
    fk = arm.fk(poses, backend=backend)
    assert np.abs(fk.point_mm - point_mm).max() < 1e-6  # mm
    assert np.abs(fk.direction - z).max() < 1e-9


def test_chain_kinematics_and_jacobians_on_unaligned_and_prismatic_joints(arm):
    from ikbench.core.kinematics.chain import pinocchio_kinematics

    poses = random_poses(arm, 20, seed=2)
    ours, reference = arm.chain_kinematics()(poses), pinocchio_kinematics(arm, poses)
    for a, b in zip(ours, reference):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    _, _, j_point, j_dir = ours
    h = 1e-6
    for j in range(arm.dof):
        plus, minus = poses.copy(), poses.copy()
        plus[:, j] += h
        minus[:, j] -= h
        (pp, dp, _, _) = arm.chain_kinematics()(plus, False)
        (pm, dm, _, _) = arm.chain_kinematics()(minus, False)
        np.testing.assert_allclose(j_point[:, :, j], (pp - pm) / (2 * h), atol=1e-9)
        np.testing.assert_allclose(j_dir[:, :, j], (dp - dm) / (2 * h), atol=1e-8)


def test_skeleton_runs_through_the_link_frames_yourdfpy_computes(arm):
    """The skeleton [mm] against yourdfpy (another URDF parser and FK) on the raw URDF."""
    import yourdfpy

    model = yourdfpy.URDF.load(str(URDF), build_scene_graph=True, load_meshes=False)
    for joint in model.robot.joints:  # yourdfpy moves prismatic joints along the raw axis
        if joint.type == "prismatic":
            joint.axis = joint.axis / np.linalg.norm(joint.axis)
    poses = random_poses(arm, 5, seed=3)
    skeleton = arm.skeleton_mm(poses)
    assert skeleton.shape == (5, arm.dof + 2, 3)
    links = ["world_link", "l1", "l2", "l3", "l4", "l5", "l6", "tool"]
    for pose, points in zip(poses, skeleton):
        model.update_cfg({name: value for name, value in zip(arm.joint_names,
                                                              arm.to_urdf(pose))})
        expected = [model.get_transform(link, "world_link")[:3, 3] * 1000 for link in links]
        np.testing.assert_allclose(points, expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(skeleton[:, -1], arm.fk(poses).point_mm, rtol=0, atol=1e-9)


def test_fk_cli_on_a_bare_urdf(capsys):
    pose = "10,100,20,-30,170,5"
    assert main(["fk", "--robot", str(URDF), "--end-frame", "tool", f"--pose={pose}",
                 "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    expected, _ = independent_fk_mm([[10, 100, 20, -30, 170, 5]])
    assert obj["robot"] == "unaligned_arm" and obj["pose_unit"] == "joint deg, mm for prismatic"
    assert np.abs(np.array(obj["point_mm"]) - expected[0]).max() < 1e-6


@pytest.mark.parametrize("args, message", [
    (["--robot", str(URDF)], "a bare URDF needs an end frame, a link (--end-frame LINK; the "
     "chain runs from the URDF's root to that link); candidates (leaf links first, then "
     "tool-like names): tool, sensor"),
    (["--robot", str(URDF), "--end-frame", "nope"], "--end-frame: 'nope' is not a link of "
     "unaligned_arm.urdf; candidates (leaf links first, then tool-like names): tool, sensor"),
    (["--robot", "no_such_robot"], "--robot: 'no_such_robot' is not a shipped robot "
     "(fetch, fetch_arm, nico_right_arm, panda)"),
    (["--robot", "missing.urdf", "--end-frame", "tool"], "URDF 'missing.urdf' not found"),
    (["--robot", str(URDF), "--end-frame", "tool", "--pose=1,2,3"],
     "--pose: expected 6 values (j1, slide, j3, j4, roll, j6; joint deg, mm for prismatic)"),
    (["--robot", str(URDF), "--end-frame", "tool", "--pose=0,300,0,0,0,0"],
     "--pose: slide = 300 mm is outside its range [0, 250]"),
])
def test_bad_robot_input_one_line_exit_2(capsys, args, message):
    assert main(["fk", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


def test_a_robot_config_names_the_urdf_end_frame_and_pointing_axis(tmp_path):
    config = tmp_path / "my_arm.toml"
    config.write_text(f'name = "my_arm"\nurdf = "{URDF}"\nbase_link = "base"\n'
                      'end_frame = "l6"\npointing_axis = [1.0, 0.0, 0.0]\n'
                      f'[targets]\nfile = "{TARGETS}"\nname = "mine"\n')
    robot = load_robot(config)
    assert robot.name == "my_arm" and robot.root_link == "base" and robot.end_frame == "l6"
    pose = np.array([10.0, 100.0, 20.0, -30.0, 170.0, 5.0])
    T = robot.fk_transform(pose)[0]
    np.testing.assert_allclose(robot.fk(pose).direction[0], T[:3, 0], atol=1e-15)
    targets = load_targets(None, robot)
    assert targets.source == "mine" and targets.is_default and targets.ids == ["a", "b"]
    (tmp_path / "bad.toml").write_text(f'urdf = "{URDF}"\nend_frame = "tool"\nendframe = 1\n')
    with pytest.raises(InputError, match="unknown key\\(s\\) 'endframe'"):
        load_robot(tmp_path / "bad.toml")


def _run(tmp_path, method, *extra):
    args = ["run", "--robot", str(URDF), "--end-frame", "tool", "--targets", str(TARGETS),
            "--method", method, "--output", str(tmp_path), "--quiet", "--no-animation", *extra]
    assert main(args) == 0
    folder = tmp_path / (extra[extra.index("--name") + 1] if "--name" in extra else method)
    return folder, pd.read_csv(folder / "table.csv", dtype={"trajectory": str})


@pytest.mark.parametrize("method, extra", [
    ("ours-lm", ()),
    ("ours", ("--only", "a", "--steps", "8", "--max-iterations", "1500")),
])
def test_whole_path_methods_start_at_the_start_pose_and_end_at_the_touch_pose(
        tmp_path, arm, method, extra):
    folder, table = _run(tmp_path, method, *extra)
    targets = load_targets(TARGETS, arm)
    for _, row in table.iterrows():
        poses = read_trajectory_poses(folder / f"trajectory_{row['trajectory']}.csv", arm)
        assert np.abs(poses[0] - targets.start_pose).max() < 0.5
        assert np.abs(poses[-1] - targets.touch_poses[row["trajectory"]]).max() < 0.5
        assert row["start_point_error_mm"] < 0.5 and row["end_point_error_mm"] < 0.5
        assert arm.within_limits(poses)
    record = json.loads((folder / "run.json").read_text())
    assert record["robot"]["name"] == "unaligned_arm"
    assert record["robot"]["urdf_sha256"] == arm.urdf_sha256


def test_sequential_ik_walks_from_the_touch_pose_to_the_start_point(tmp_path, arm):
    folder, table = _run(tmp_path, "sequential-ik", "--orientation", "position")
    targets = load_targets(TARGETS, arm)
    for _, row in table.iterrows():
        poses = read_trajectory_poses(folder / f"trajectory_{row['trajectory']}.csv", arm)
        np.testing.assert_array_equal(poses[-1], targets.touch_poses[row["trajectory"]])
        assert row["start_point_error_mm"] < 1e-3 and row["line_distance_mean_mm"] < 1e-2
        assert arm.within_limits(poses)


def test_a_run_reloads_its_robot_and_refuses_a_changed_urdf(tmp_path, arm):
    import shutil

    from ikbench.runtime.record import robot_from_record

    urdf = tmp_path / "copy.urdf"
    shutil.copy(URDF, urdf)
    robot = load_robot(urdf, "tool")
    table = ikbench.run("ours-lm", robot=robot, targets=TARGETS, output=tmp_path,
                        progress=False, animation=False)
    assert len(table) == 2
    record = json.loads((tmp_path / "ours-lm" / "run.json").read_text())
    assert robot_from_record(record).joint_names == arm.joint_names
    urdf.write_text(urdf.read_text().replace('xyz="0.2 0 0"', 'xyz="0.21 0 0"'))
    from ikbench.core import robot as robot_module

    robot_module._load.cache_clear()  # load the edited file again
    with pytest.raises(InputError, match="changed since this run was written"):
        robot_from_record(record)


def test_fk_of_a_pose_of_the_wrong_length_names_the_joints(robot):
    with pytest.raises(InputError, match=r"fk: shape \(6,\) is not \(B, 7\) or \(7,\): 7 values "
                       r"per pose \(r_shoulder_z, .*; motor deg\)"):
        robot.fk([1, 2, 3, 4, 5, 6])


def test_a_lower_case_letter_is_drawn_upper_case_and_the_cli_says_so(tmp_path, capsys):
    assert main(["letters", "p", "--method", "ours-lm", "--steps", "8", "--output",
                 str(tmp_path), "--quiet"]) == 0
    assert "note: letter:p: letters are drawn upper case (P)" in capsys.readouterr().err
    assert (tmp_path / "ours-lm" / "trajectory_P.csv").exists()


def test_a_trajectory_file_may_pass_a_limit_by_a_float32_ulp_not_more(tmp_path):
    """``ours`` (Adam in float32) writes poses that may pass a limit by an ulp of float32; the
    reader takes them (FILE_RANGE_TOLERANCE_DEG), a pose beyond that is refused, and the judge
    keeps its own tolerance (the pose is not within the limits)."""
    from ikbench.core.robot import FILE_RANGE_TOLERANCE_DEG, load_robot
    from ikbench.core.trajectory import read_trajectory_poses, write_trajectory_csv

    robot = load_robot("panda")
    poses = np.tile((robot.lower + robot.upper) / 2, (3, 1))
    poses[1, -1] = robot.upper[-1] + 5e-6          # 166.003067 as ours wrote it
    write_trajectory_csv(tmp_path / "ulp.csv", robot, poses)
    read = read_trajectory_poses(tmp_path / "ulp.csv", robot)
    assert read[1, -1] > robot.upper[-1] and not robot.within_limits(read[1])
    poses[1, -1] = robot.upper[-1] + 10 * FILE_RANGE_TOLERANCE_DEG
    write_trajectory_csv(tmp_path / "far.csv", robot, poses)
    with pytest.raises(InputError, match="panda_joint7 = .* is outside its range"):
        read_trajectory_poses(tmp_path / "far.csv", robot)


def test_a_package_robot_without_end_frame_lists_the_candidates(capsys):
    """so101 (example-robot-data, not in the table of common arms): the error and
    `robots --all` name the links an end frame may be, leaf links first."""
    from ikbench.core.robot_packages import robots_folder

    if robots_folder("example-robot-data") is None:
        pytest.skip("needs example-robot-data: pip install 'ikbench[robots]'")
    assert main(["fk", "--robot", "example-robot-data:so101", "--pose=0,0,0,0,0,0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.rstrip().endswith(
        "candidates (leaf links first, then tool-like names): gripper_frame_link, "
        "moving_jaw_so101_v1_link, gripper_link")
    assert main(["robots", "--all", "--json"]) == 0
    packages = {r["name"]: r for r in json.loads(capsys.readouterr().out)["packages"]}
    assert packages["example-robot-data:so101"]["end_frame_candidates"] == [
        "gripper_frame_link", "moving_jaw_so101_v1_link", "gripper_link"]
    assert "end_frame_candidates" not in packages["example-robot-data:ur5"]  # in the table
    assert main(["robots", "--all"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("example-robot-data:so101: needs --end-frame LINK, candidates: "
                               "gripper_frame_link, moving_jaw_so101_v1_link, gripper_link; ")
               for line in lines)


@pytest.mark.parametrize("line, key", [('description = 3', "description"),
                                       ('targets = "x.json"', "targets"),
                                       ('[frame]\nzoom = 2', "zoom")])
def test_a_robot_config_with_a_wrong_type_or_key_is_refused_naming_it(tmp_path, line, key):
    config = tmp_path / "my_arm.toml"
    config.write_text(f'urdf = "{URDF}"\nend_frame = "tool"\n{line}\n')
    with pytest.raises(InputError, match=key):
        load_robot(config)
