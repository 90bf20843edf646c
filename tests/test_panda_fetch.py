"""Panda, Fetch arm and Fetch: FK against reference poses from the makers' URDFs, the locked
torso, CppFlow's bounds for the continuous rolls, and the three backends agreeing.

The reference poses below were computed once with Pinocchio 4.1.0 from the makers' own files
(not ikbench's): frankaemika/franka_description @ b299b39 (robots/fer/fer.urdf.xacro expanded
by PyPI xacro; frames fer_link0 -> fer_hand, joints fer_joint1..7) and ZebraDevs/fetch_ros @
9c38de6 (fetch_description/robots/fetch.urdf; base_link -> gripper_link, the torso at 0 for
fetch_arm, continuous joints as (cos, sin)). On 1000 seeded poses each the largest deviation
of ikbench's FK from them was 9.4e-13 mm / 1.9e-13 deg (Panda) and 4.4e-13 mm / 2.6e-14 deg
(Fetch), for both the Pinocchio and the torch backend.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.robot import load_robot

#: robot -> (poses [joint deg, mm], end point [mm], end rotation) from the makers' URDFs
MAKER = {
    "panda": (
        [[45.472, -46.504, -152.4, -173.158, 104.008, 196.157, 35.404],
         [76.194, 8.812, 144.447, -35.673, -165.094, 184.201, -154.852]],
        [[-44.160030063, -31.603162984, 78.35974325],
         [-240.349224081, -153.239715265, 1076.998581383]],
        [[[-0.94532194387, 0.205034038407, 0.253628597624],
          [0.317083971276, 0.759771895152, 0.567630533443],
          [-0.076316299687, 0.617015162238, -0.783242051968]],
         [[0.660327312213, -0.606343944303, -0.443074330054],
          [0.521726592507, 0.794763916585, -0.310083342936],
          [0.54015664711, -0.026407160043, 0.84115008083]]]),
    "fetch_arm": (
        [[25.199, -27.62, -165.25, -124.71, 112.777, 102.164, 38.389],
         [42.225, 15.355, 156.626, 81.473, -179.014, 88.464, -167.909]],
        [[413.072884359, -73.738411472, 650.418359258],
         [592.821047015, 665.339201836, 846.61992938]],
        [[[0.198588181135, -0.864158405869, 0.462377533926],
          [-0.979219411268, -0.194745533855, 0.056599661118],
          [0.041134886763, -0.464009080309, -0.88487484679]],
         [[0.707256139799, 0.691010594436, -0.149308777682],
          [0.5979900653, -0.697401435937, -0.395017871691],
          [-0.377089690284, 0.190093649368, -0.906458917961]]]),
    "fetch": (
        [[245.963, -42.357, -63.528, -174.05, 80.807, 148.592, 26.394, 82.619],
         [209.921, 80.048, 58.076, -179.014, 92.191, -167.909, 56.844, -116.764]],
        [[-152.283892059, -6.22683312, 1783.150606267],
         [134.992620896, 843.119497301, 764.798176049]],
        [[[-0.568257984002, -0.2542152255, -0.782596628374],
          [0.090760577956, 0.925912504864, -0.366672266235],
          [0.817829677321, -0.279393365098, -0.503084452584]],
         [[-0.004871046833, 0.268248483465, -0.963337440372],
          [0.929239242777, -0.354695852289, -0.103466332939],
          [-0.369446481355, -0.895674942983, -0.247539277543]]]),
}


@pytest.mark.parametrize("name", sorted(MAKER))
@pytest.mark.parametrize("backend", ["pinocchio", "torch"])
def test_fk_matches_the_makers_urdfs(name, backend):
    poses, point_mm, rotation = (np.array(v) for v in MAKER[name])
    T = load_robot(name).fk_transform(poses, backend)
    assert np.abs(T[:, :3, 3] * 1000.0 - point_mm).max() < 1e-6        # mm (inputs rounded)
    assert np.abs(T[:, :3, :3] - rotation).max() < 1e-9


@pytest.mark.parametrize("name", ["panda", "fetch_arm", "fetch"])
def test_backends_and_the_chain_agree_on_random_poses(name):
    robot = load_robot(name)
    poses = np.random.default_rng(3).uniform(robot.validity_lower, robot.validity_upper,
                                             (50, robot.dof))
    pin_T = robot.fk_transform(poses, "pinocchio")
    torch_T = robot.fk_transform(poses, "torch")
    point_m, rotation, _, _ = robot.chain_kinematics().transforms(poses)
    assert np.abs(pin_T - torch_T).max() < 1e-12
    assert np.abs(pin_T[:, :3, 3] - point_m).max() < 1e-12
    assert np.abs(pin_T[:, :3, :3] - rotation).max() < 1e-12


def test_fetch_arm_is_fetch_with_the_torso_at_zero():
    arm, fetch = load_robot("fetch_arm"), load_robot("fetch")
    assert fetch.joint_names[0] == "torso_lift_joint" and arm.joint_names == fetch.joint_names[1:]
    assert arm.locked_urdf == {"torso_lift_joint": 0.0}
    poses = np.random.default_rng(4).uniform(arm.validity_lower, arm.validity_upper, (20, 7))
    with_torso = np.hstack([np.zeros((20, 1)), poses])
    np.testing.assert_allclose(arm.fk_transform(poses), fetch.fk_transform(with_torso), atol=0)
    lifted = fetch.fk_transform(np.hstack([np.full((20, 1), 100.0), poses]))  # torso +100 mm
    np.testing.assert_allclose(lifted[:, 2, 3] - arm.fk_transform(poses)[:, 2, 3], 0.1,
                               atol=1e-12)


def test_continuous_rolls_have_no_limits_but_cppflows_bounds_for_validity():
    arm = load_robot("fetch_arm")
    rolls = [arm.joint_names.index(n) for n in
             ("upperarm_roll_joint", "forearm_roll_joint", "wrist_roll_joint")]
    assert all(arm.joint_types[j] == "continuous" for j in rolls)
    assert np.all(np.isinf(arm.lower[rolls])) and np.all(np.isinf(arm.upper[rolls]))
    assert np.all(arm.validity_lower[rolls] == -180.0) and np.all(arm.validity_upper[rolls] == 180)
    others = [j for j in range(arm.dof) if j not in rolls]
    np.testing.assert_array_equal(arm.validity_lower[others], arm.lower[others])
    assert arm.upper[0] == pytest.approx(math.degrees(1.6056))       # shoulder_pan, maker's
    assert load_robot("fetch").upper[0] == pytest.approx(386.15)     # torso lift [mm]
    arm.check_pose([0, 0, 400.0, 0, 0, 0, 0])                       # no limit at the interface


def test_fk_cli_on_panda(capsys):
    assert main(["fk", "--robot", "panda", "--pose=0,-45,0,-135,0,90,45", "--json"]) == 0
    import json

    out = json.loads(capsys.readouterr().out)
    # the "ready" pose: hand 306.891 mm forward, 590.282 mm up, pointing down
    np.testing.assert_allclose(out["point_mm"], [306.890567, 0.0, 590.282052], atol=1e-5)
    np.testing.assert_allclose(out["direction"], [0, 0, -1], atol=1e-12)


@pytest.mark.parametrize("extra, message", [
    ('locked = { nope = 0.0 }', "locked: 'nope' is not a joint of the chain"),
    ('locked = { torso_lift_joint = 500.0 }', "torso_lift_joint = 500 is outside its URDF"),
    ('locked = { torso_lift_joint = "low" }', "'low' is not a finite number"),
    ('validity_limits = { wrist_roll_joint = [10.0, -10.0] }', "must be [lower, upper] with"),
    ('validity_limits = { torso_lift_joint = [0.0, 1.0] }', "'torso_lift_joint' is not a joint "
     "of the pose"),
])
def test_bad_locked_or_validity_limits_are_refused(tmp_path, extra, message):
    from ikbench.core.robot import robots_dir

    config = tmp_path / "arm.toml"
    config.write_text(f'urdf = "{robots_dir() / "fetch.urdf"}"\nbase_link = "base_link"\n'
                      f'end_frame = "gripper_link"\n{extra}\n'
                      + ('locked = { torso_lift_joint = 0.0 }\n' if "validity" in extra else ""))
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("(", r"\(")):
        load_robot(config)


def test_run_and_letters_work_out_of_the_box(tmp_path):
    """The shipped targets and letter pose: run on the 8-joint Fetch (prismatic torso in mm),
    a letter with the Panda."""
    import pandas as pd

    assert main(["run", "--robot", "fetch", "--method", "ours-lm", "--only", "lower,raise",
                 "--steps", "20", "--output", str(tmp_path), "--quiet"]) == 0
    table = pd.read_csv(tmp_path / "ours-lm" / "table.csv")
    assert list(table["trajectory"]) == ["lower", "raise"]
    assert (table["end_point_error_mm"] < 0.5).all() and (table["start_point_error_mm"] < 0.5).all()
    trajectory = pd.read_csv(tmp_path / "ours-lm" / "trajectory_raise.csv")
    assert trajectory["torso_lift_joint"].iloc[0] == pytest.approx(150.0, abs=1.0)   # mm
    assert trajectory["torso_lift_joint"].iloc[-1] == pytest.approx(250.0, abs=1.0)
    assert main(["letters", "P", "--robot", "panda", "--method", "ours-lm", "--output",
                 str(tmp_path / "letters"), "--quiet"]) == 0
    letter = pd.read_csv(tmp_path / "letters" / "ours-lm" / "table.csv").iloc[0]
    assert letter["curve_distance_mean_mm"] < 10.0


@pytest.mark.parametrize("orientation", ["frame", "pointing"])
def test_sequential_ik_points_the_fetch_gripper_along_its_x_axis(tmp_path, orientation):
    """The Fetch gripper points along its x-axis (not z): the baseline's goal frame and
    pointing residual follow the config's pointing axis (before, frame mode lost the line by
    ~600 mm on these targets)."""
    import pandas as pd

    assert main(["run", "--robot", "fetch_arm", "--method", "sequential-ik-walk",
                 "--orientation", orientation, "--only", "front,left", "--steps", "20",
                 "--output", str(tmp_path), "--quiet"]) == 0
    table = pd.read_csv(tmp_path / "sequential-ik-walk" / "table.csv")
    assert (table["line_distance_mean_mm"] < 0.1).all()
    assert (table["pointing_deviation_mean_deg"] < 1.0).all()


# ----- continuous joints are written unwrapped (issue 50, item 5) ------------------------------
CIRCLE = (Path(__file__).parents[1] / "results" / "cartesian" / "ours-lm"
          / "trajectory_fetch_arm__circle_seed1.csv")


def _wrapping_path():
    """fetch_arm poses (n+1, 7) [deg] whose forearm_roll crosses +-180 written wrapped (+179.9
    -> -179.7, a 359.6 deg step), the other joints moving a little; (path, forearm index)."""
    arm = load_robot("fetch_arm")
    j = arm.joint_names.index("forearm_roll_joint")
    poses = np.tile([20.0, -20.0, 30.0, -60.0, 0.0, 60.0, 10.0], (9, 1))
    poses += np.linspace(0.0, 4.0, 9)[:, None]
    poses[:, j] = [175.0, 177.0, 179.9, -179.7, -177.0, -175.0, -173.0, -171.0, -169.0]
    return arm, poses, j


def test_a_wrapped_continuous_joint_is_written_unwrapped_and_read_back(tmp_path):
    """The trajectory CSV: no step over 180 deg in a continuous joint, the same FK, bounded
    joints untouched; reading it back accepts values outside [-180, 180]."""
    from ikbench.core.trajectory import read_trajectory_poses, write_trajectory_csv

    arm, poses, j = _wrapping_path()
    assert np.abs(np.diff(poses[:, j])).max() > 359.0
    path = write_trajectory_csv(tmp_path / "t.csv", arm, poses)
    back = read_trajectory_poses(path, arm)
    assert np.abs(np.diff(back[:, arm.continuous], axis=0)).max() < 3.0
    assert back[:, j].max() > 180.0  # values leave [-180, 180]
    np.testing.assert_array_equal(back[:, ~arm.continuous], poses[:, ~arm.continuous])
    np.testing.assert_allclose(np.abs(back[:, j] - poses[:, j]) % 360.0, 0.0, atol=1e-9)
    np.testing.assert_allclose(arm.fk(back).point_mm, arm.fk(poses).point_mm, atol=1e-6)
    np.testing.assert_allclose(arm.fk_transform(back), arm.fk_transform(poses), atol=1e-9)


def test_unwrap_and_wrap_leave_bounded_joints_and_in_range_values_alone():
    from ikbench.core.robot import unwrap_continuous, wrap_continuous

    fetch = load_robot("fetch")  # the torso is prismatic [mm]
    poses = np.array([[300.0, 10.0, 0.0, 170.0, 0.0, 170.0, 0.0, -170.0],
                      [300.0, 11.0, 0.0, -170.0, 0.0, -175.0, 0.0, 170.0]])
    out = unwrap_continuous(fetch, poses)
    np.testing.assert_array_equal(out[:, ~fetch.continuous], poses[:, ~fetch.continuous])
    np.testing.assert_allclose(out[1, fetch.continuous], [190.0, 185.0, -190.0])
    np.testing.assert_array_equal(wrap_continuous(fetch, out), poses)  # back, bit for bit
    np.testing.assert_array_equal(wrap_continuous(fetch, poses), poses)
    batch = unwrap_continuous(fetch, np.stack([poses, poses[::-1]]))  # (B, n+1, dof): per path
    np.testing.assert_array_equal(batch[0], out)
    np.testing.assert_array_equal(batch[1], unwrap_continuous(fetch, poses[::-1]))
    panda = load_robot("panda")  # no continuous joint: unchanged
    q = np.array([[0.0, 0, 0, -90, 0, 90, 170], [0.0, 0, 0, -90, 0, 90, -170]])
    np.testing.assert_array_equal(unwrap_continuous(panda, q), q)


def test_validity_accepts_an_unwrapped_solution_as_written():
    """CppFlow's validity (changes wrapped, jrl's [-180, 180] for the rolls) judges the
    unwrapped poses as it judges the wrapped ones."""
    from ikbench.core.metrics import frame_metrics
    from ikbench.core.problems import load_problem
    from ikbench.core.robot import unwrap_continuous
    from ikbench.core.trajectory import read_trajectory_poses

    robot, task, _ = load_problem("fetch_arm__circle")
    poses = read_trajectory_poses(CIRCLE, robot)
    unwrapped = unwrap_continuous(robot, poses)
    assert np.abs(unwrapped).max() > 180.0  # the committed file wraps; this one does not
    wrapped, unwrapped_metrics = frame_metrics(robot, task, poses), frame_metrics(robot, task,
                                                                                 unwrapped)
    for key in ("valid", "within_limits", "max_joint_change_deg", "position_error_max_mm"):
        assert wrapped[key] == pytest.approx(unwrapped_metrics[key]), key
    assert unwrapped_metrics["valid"]
    from ikbench.viewer.design.criteria import limit_margins  # the designer's limit figure

    assert limit_margins(robot, task, unwrapped) == limit_margins(robot, task, poses)
    assert limit_margins(robot, task, unwrapped)[0] >= 0.0


@pytest.mark.skipif(not __import__("ikbench.core.timing_topp", fromlist=["x"]).toppra_available(),
                    reason="needs toppra")
def test_topp_export_of_a_wrapped_path_follows_it(tmp_path):
    """``ikbench export --timing topp`` of a path written wrapped turns forearm_roll the
    short way: the fingertip stays on the solved path and T stays short."""
    import re

    from ikbench.core.timing import retime
    from ikbench.core.timing_limits import urdf_limits
    from ikbench.viewer.export import export_trajectory

    arm, poses, j = _wrapping_path()
    csv = tmp_path / "wrapped.csv"
    header = "step,time_s," + ",".join(arm.joint_names)
    rows = [f"{k},{k / 8:g}," + ",".join(f"{v:.10g}" for v in pose)
            for k, pose in enumerate(poses)]
    csv.write_text("\n".join([header, *rows]) + "\n")  # as an older writer left it: wrapped
    timed = retime(arm, poses, "topp", limits=urdf_limits(arm))
    assert np.abs(np.diff(timed.poses[:, j])).max() < 3.0
    _, note = export_trajectory(csv, "csv-rad", tmp_path / "out.csv", arm, 2.0, timing="topp",
                                limits=urdf_limits(arm), rate_hz=250.0)
    deviation = float(re.search(r"strays up to ([\d.e+-]+) mm", note).group(1))
    duration = float(re.search(r"T = ([\d.e+-]+) s", note).group(1))
    assert deviation < 5.0 and duration < 3.0, note
