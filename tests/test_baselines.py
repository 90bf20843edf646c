"""The kinematics-library baselines (baselines/*_ik.py, *_trajopt.py): each library's method
solves goals made by FK back to its tolerance, keeps the limits, walks deterministically and
runs through ``ikbench run`` on the paper's robot and on a robot it has never seen.

Each test is skipped, with the registry's reason, only when the method's library is not
installed (``pip install -e '.[libs]'`` installs all of them). Kept small (n = 4) so the
whole module runs in about two minutes on 2 cores, most of it PyRoki's one XLA compile.
"""

from __future__ import annotations

import dataclasses
import importlib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ikbench import load_robot, load_targets
from ikbench.cli import main
from ikbench.core.errors import InputError, SolverError
from ikbench.core.metrics import pointing_deviations_deg, trajectory_metrics
from ikbench.core.robot import pose_difference
from ikbench.core.task import Goal, Requirements, Task, line_tasks
from ikbench.core.trajectory import read_trajectory_poses
from ikbench.methods.registry import LIBS_EXTRA
from ikbench.schemes.chain import chain_of, poses_from_urdf, urdf_limits
from ikbench.schemes.exact_pose import delayed_seed_fraction, ramped_roll
from ikbench.schemes.geometry import (
    closest_rotation_with_axis,
    quaternion_xyzw,
    roll_between_rad,
    rotation_about,
    rotation_between,
)
from tests.conftest import method_class

DATA = Path(__file__).parent / "data"
ARM, ARM_TARGETS = DATA / "unaligned_arm.urdf", DATA / "unaligned_arm.targets.json"
#: A pointing direction the unaligned arm can hold along both its lines (the line direction
#: itself it cannot: 55-100 deg away at the touch poses).
ARM_DIRECTION = "0.9,0.3,0.2"
STEPS = 4

#: method -> (position tolerance [mm], pointing tolerance [deg] or None when the default mode
#: does not point, whole path?). The tolerances are each library's own: ikpy's scipy
#: defaults, PyRoki's augmented-Lagrangian defaults, Drake's 0.01 deg pointing cone.
LIBRARIES = {
    "ikpy": (1e-3, None, False),
    "pink": (1e-3, 1e-3, False),
    "trac-ik": (1e-3, 1e-3, False),
    "mink": (1e-3, 1e-3, False),
    "drake-ik": (1e-3, 0.011, False),
    "drake-trajopt": (1e-3, 0.1, True),
    "pyroki": (1e-2, 0.1, True),
}
FRAMES = [name for name in LIBRARIES if name != "pyroki"]
#: method -> settings that make its result independent of the machine's speed. TRAC-IK races
#: threads against a wall-clock timeout (5 ms by default) and returns what it found by then: on
#: a loaded machine a solve found nothing and the test failed (14.4 mm at load 4). Speed mode
#: returns the first solution within the tolerance, so a 2 s budget costs no time when quiet
#: and is no limit under any load a test run meets.
LOAD_PROOF: dict[str, dict] = {"trac-ik": {"timeout": 2.0, "solve_type": "Speed"}}


def fk_task(robot, seed: int, frames: bool = False) -> Task:
    """Goals made by FK of a seeded random path between two in-range poses [pose units]."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.sample_lower, robot.sample_upper
    start = lo + (0.2 + 0.6 * rng.random(robot.dof)) * (hi - lo)
    end = np.clip(start + 0.08 * (hi - lo) * rng.uniform(-1, 1, robot.dof), lo, hi)
    poses = np.linspace(start, end, STEPS + 1)
    T = robot.fk_transform(poses)
    return Task("fk", Goal(T[:, :3, 3] * 1000.0, T[:, :3, :3] @ robot.pointing_axis,
                           T[:, :3, :3] if frames else None), Requirements(start, end))


def goal_errors(robot, task, poses):
    """Per pose: position error [mm], pointing error [deg], rotation error [deg] (6-D)."""
    T = robot.fk_transform(poses)
    position = np.linalg.norm(T[:, :3, 3] * 1000.0 - task.goal.points_mm, axis=1)
    pointing = pointing_deviations_deg(T[:, :3, :3] @ robot.pointing_axis,
                                       task.goal.directions)
    rotations = task.goal.rotations
    angle = None
    if rotations is not None:
        rel = np.einsum("nji,njk->nik", T[:, :3, :3], rotations)
        angle = np.degrees(np.arccos(np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    return position, pointing, angle


def solved_rows(name: str) -> slice:
    """Rows a method solves: 0..n-1 for walks (n is the touch pose), 1..n-1 for whole paths."""
    return slice(1, -1) if LIBRARIES[name][2] else slice(0, -1)


@pytest.fixture(scope="module")
def robot():
    return load_robot()


@pytest.fixture(scope="module")
def arm():
    return load_robot(ARM, "tool")


# ----- (a) FK goals solved back, (b) limits, (c) determinism ------------------------------------
@pytest.mark.parametrize("name", list(LIBRARIES))
def test_fk_goals_are_solved_back_within_limits_and_deterministically(robot, name):
    cls = method_class(name)
    position_tol, pointing_tol, whole = LIBRARIES[name]
    task = fk_task(robot, seed=5)
    method = cls(**LOAD_PROOF.get(name, {}))
    method.check_tasks(robot, [task])
    method.prepare(robot)
    first, second = method.solve(robot, task), method.solve(robot, task)
    for solution in (first, second):
        poses = solution.poses
        assert poses.shape == (STEPS + 1, robot.dof)
        assert robot.within_limits(poses, tol_deg=0.0)  # (b): not even round-off outside
        position, pointing, _ = goal_errors(robot, task, poses)
        rows = solved_rows(name)
        assert position[rows].max() < position_tol, (name, position)
        if pointing_tol is not None:
            assert pointing[rows].max() < pointing_tol, (name, pointing)
        if whole:
            assert np.abs(poses[0] - task.required.start_pose).max() < 0.5
            assert np.abs(poses[-1] - task.required.end_pose).max() < 0.5
        else:
            np.testing.assert_array_equal(poses[-1], task.required.end_pose)
    if name != "trac-ik":  # (c); TRAC-IK races threads against a timeout: both runs solve
        np.testing.assert_array_equal(first.poses, second.poses)


def test_ikpy_pointing_mode_points(robot):
    cls = method_class("ikpy")
    task = fk_task(robot, seed=9)
    poses = cls(orientation="pointing", scheme="walk").solve(robot, task).poses
    position, pointing, _ = goal_errors(robot, task, poses)
    assert position[:-1].max() < 0.1 and pointing[:-1].max() < 0.1  # scipy's ftol stops early
    assert robot.within_limits(poses, tol_deg=0.0)


@pytest.mark.parametrize("name", FRAMES)
def test_six_d_goal_frames_are_reached(robot, name):
    cls = method_class(name)
    task = fk_task(robot, seed=3, frames=True)
    poses = cls(**LOAD_PROOF.get(name, {})).solve(robot, task).poses
    position, _, angle = goal_errors(robot, task, poses)
    rows = solved_rows(name)
    assert position[rows].max() < 1e-2 and angle[rows].max() < 0.1, (position, angle)
    assert cls.capabilities.frames


def test_a_library_without_frames_refuses_them_before_solving(robot):
    cls = method_class("pyroki")
    with pytest.raises(InputError, match="pyroki takes goal points and pointing directions, "
                       "not 6-D goal frames"):
        cls().check_tasks(robot, [fk_task(robot, seed=3, frames=True)])


# ----- (d) through the CLI: the paper's targets and an unseen robot ------------------------------
def _run_and_check(tmp_path, robot, name, targets, touch, *extra) -> pd.DataFrame:
    """Run through the CLI; check the touch pose, the ranges and table.csv against the CSVs."""
    assert main(["run", "--method", name, "--steps", str(STEPS), "--output", str(tmp_path),
                 "--quiet", *extra]) == 0
    folder = tmp_path / name
    table = pd.read_csv(folder / "table.csv", dtype={"trajectory": str})
    tasks = {t.name: t for t in line_tasks(robot, targets)}
    for _, row in table.iterrows():
        task = tasks[row["trajectory"]]
        poses = read_trajectory_poses(folder / f"trajectory_{row['trajectory']}.csv", robot)
        assert np.abs(pose_difference(robot, poses[-1], touch[row["trajectory"]])).max() < 0.5
        assert robot.within_limits(poses)
        metrics = trajectory_metrics(robot, task, poses)
        for column in ("line_distance_mean_mm", "pointing_deviation_mean_deg",
                       "end_pose_error_deg", "start_point_error_mm"):
            assert row[column] == pytest.approx(metrics[column], rel=1e-9, abs=1e-12), column
    return table


@pytest.mark.parametrize("name", list(LIBRARIES))
def test_cli_run_on_the_papers_targets(tmp_path, robot, name):
    method_class(name)
    targets = load_targets(None, robot).select("1,7").with_steps(STEPS)
    table = _run_and_check(tmp_path, robot, name, targets, targets.touch_poses,
                           "--only", "1,7")
    # ikpy's points are FK-checked to its --ikpy-position-tolerance 0.1 mm; others to 1 um
    assert (table["line_distance_mean_mm"] < (0.1 if name == "ikpy" else 1e-2)).all()
    if name == "ikpy":  # the paper's own baseline (the authors' walk): beside Table 2
        assert main(["run", "--method", "ikpy-walk", "--only", "1", "--steps", str(STEPS),
                     "--output", str(tmp_path), "--quiet", "--no-animation"]) == 0
        report = (tmp_path / "ikpy-walk" / "report.md").read_text()
        assert "## Beside the paper's Table 2" in report
        assert "their library (ikpy) and their call" in report


@pytest.mark.parametrize("name", [n for n in LIBRARIES if n != "pyroki"] + [
    pytest.param("pyroki", marks=pytest.mark.slow)])  # a second 20-40 s XLA compile
def test_cli_run_on_an_unseen_robot(tmp_path, arm, name):
    """Unaligned and prismatic joints, a continuous joint, a sensor joint off the chain."""
    method_class(name)
    targets = load_targets(ARM_TARGETS, arm).with_steps(STEPS)
    from ikbench.core.task import build_tasks

    extra = ("--robot", str(ARM), "--end-frame", "tool", "--targets", str(ARM_TARGETS))
    if name == "ikpy":
        table = _run_and_check(tmp_path, arm, name, targets, targets.touch_poses, *extra)
        assert (table["line_distance_mean_mm"] < 1e-2).all()  # position only
        return
    tasks = build_tasks(arm, targets, "line", STEPS, None, ARM_DIRECTION)
    assert main(["run", "--method", name, "--steps", str(STEPS), "--output", str(tmp_path),
                 "--quiet", "--direction", ARM_DIRECTION, *extra]) == 0
    for task in tasks:
        poses = read_trajectory_poses(tmp_path / name / f"trajectory_{task.name}.csv", arm)
        # a continuous joint may end a whole turn away (the file is unwrapped): the same arm
        assert np.abs(pose_difference(arm, poses[-1], task.required.end_pose)).max() < 0.5
        assert arm.within_limits(poses)
        position, pointing, _ = goal_errors(arm, task, poses)
        assert position[solved_rows(name)].max() < 0.2  # b's last goal: 1.3 deg out of reach


# ----- refusals and the registry --------------------------------------------------------------
@pytest.mark.parametrize("args, message", [
    (["--method", "ikpy", "--ikpy-orientation", "frame"],
     "--ikpy-orientation: 'frame' is not one of position, pointing"),
    (["--method", "pink", "--pink-qp-solver", "nope"],
     "--pink-qp-solver: 'nope' is not an installed qpsolvers backend"),
    (["--method", "trac-ik", "--tracik-roll-max", "200"],
     "--tracik-roll-max: 200.0 must be in [0, 180] deg"),
    (["--method", "drake-trajopt", "--shape", "letter:P"],
     "drake-trajopt optimises the path between the fixed start and touch poses"),
    (["--method", "drake-trajopt", "--drake-control-points", "2"],
     "--drake-control-points: 2 control points are fewer than the spline order 4"),
    (["--method", "mink", "--shape", "letter:P"],
     "mink (scheme track) starts at the start pose and lands on the touch pose"),
    (["--method", "mink", "--scheme", "walk", "--shape", "letter:P"],
     "mink starts at the touch pose"),
])
def test_bad_input_is_one_line_exit_2(tmp_path, capsys, args, message):
    method_class(args[1])
    assert main(["run", *args, "--steps", "4", "--output", str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err


def test_ikpy_pointing_needs_a_coordinate_axis(robot):
    cls = method_class("ikpy")
    tilted = dataclasses.replace(robot, pointing_axis=np.array([0.0, 0.6, 0.8]))
    with pytest.raises(InputError, match="ikpy points a coordinate axis"):
        cls(orientation="pointing").check_tasks(tilted, [fk_task(robot, 1)])
    cls(orientation="position").check_tasks(tilted, [fk_task(robot, 1)])  # does not point
    method_class("ikpy-walk")().check_tasks(tilted, [fk_task(robot, 1)])  # the authors' call


def test_a_missing_library_makes_only_its_method_unavailable(monkeypatch):
    from ikbench.methods import registry

    real = importlib.util.find_spec
    monkeypatch.setattr(registry, "_STATUS", None)
    monkeypatch.setattr(registry.importlib.util, "find_spec",
                        lambda name, *a: None if name == "pytracik" else real(name, *a))
    status = registry.method_status()
    assert status["trac-ik"].reason == f"needs pytracik ({LIBS_EXTRA})"
    assert status["sequential-ik"].available
    monkeypatch.setattr(registry, "_STATUS", None)


# ----- the shared conversions ------------------------------------------------------------------
def test_urdf_limits_are_min_max_of_the_mapped_motor_limits(robot, arm):
    lower, upper = urdf_limits(robot)
    model = robot.pinocchio_fk().model
    np.testing.assert_allclose(lower, model.lowerPositionLimit, atol=1e-12)
    np.testing.assert_allclose(upper, model.upperPositionLimit, atol=1e-12)
    assert (robot.scale < 0).any()  # NICO's negative scales swap the mapped limits
    lower, upper = urdf_limits(arm)
    roll = arm.joint_names.index("roll")
    assert lower[roll] == -np.inf and upper[roll] == np.inf
    assert upper[arm.joint_names.index("slide")] == pytest.approx(0.25)  # m


def test_chain_urdf_fixes_joints_off_the_chain_and_normalises_axes(arm):
    import xml.etree.ElementTree as ET

    root = ET.fromstring(chain_of(arm).urdf_text)
    joints = {j.get("name"): j for j in root.iter("joint")}
    assert joints["sensor_joint"].get("type") == "fixed"
    axis = np.array([float(v) for v in joints["j1"].find("axis").get("xyz").split()])
    assert np.linalg.norm(axis) == pytest.approx(1.0, abs=1e-15)
    assert not list(root.iter("visual"))


def test_back_conversion_clips_only_round_off(robot):
    lower, upper = urdf_limits(robot)
    poses = poses_from_urdf(robot, np.stack([lower, upper]) * (1 + 1e-15))
    assert robot.within_limits(poses, tol_deg=0.0)
    with pytest.raises(SolverError, match="leaves the motor ranges"):
        poses_from_urdf(robot, upper[None] + 0.01)


def test_quaternion_and_rotation_helpers():
    rng = np.random.default_rng(0)
    for _ in range(20):
        a, b = rng.normal(size=3), rng.normal(size=3)
        R = rotation_between(a, b)
        np.testing.assert_allclose(R @ (a / np.linalg.norm(a)), b / np.linalg.norm(b),
                                   atol=1e-12)
        x, y, z, w = quaternion_xyzw(R)
        # the quaternion's rotation, written out independently
        Q = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        np.testing.assert_allclose(Q, R, atol=1e-12)
    np.testing.assert_allclose(rotation_between([0, 0, 1], [0, 0, -1]) @ [0, 0, 1], [0, 0, -1],
                               atol=1e-12)


def test_the_roll_free_track_pulls_toward_the_posture_after_the_turn():
    """delayed_seed_fraction: 0 over the unjudged steps (where the pointing turns), then
    linear up to the top over twice as many steps, then the top."""
    fractions = [delayed_seed_fraction(i, 10, 0.8) for i in range(51)]
    assert fractions[:11] == [0.0] * 11
    assert fractions[20] == pytest.approx(0.4) and fractions[30:] == [0.8] * 21
    assert np.all(np.diff(fractions) >= 0)
    assert delayed_seed_fraction(1, 0, 0.5) == pytest.approx(0.25)  # judged from step 0


def test_the_track_ramps_the_roll_onto_the_touch_poses():
    """roll_between_rad is the signed turn about the local axis between two rotations sharing
    that axis' direction; ramped_roll turns by 1 / steps_left of it, the whole of it with one
    step left (the exact-pose track's goal rotation: docs/baselines.md)."""
    rng = np.random.default_rng(5)
    for axis in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]),
                 rng.normal(size=3)):
        axis = axis / np.linalg.norm(axis)
        for _ in range(10):
            a = rotation_between([0, 0, 1], rng.normal(size=3)) @ rotation_about(
                rng.normal(size=3), rng.uniform(-np.pi, np.pi))
            angle = rng.uniform(-np.pi + 1e-6, np.pi)
            b = a @ rotation_about(axis, angle)
            assert roll_between_rad(a, b, axis) == pytest.approx(angle, abs=1e-9)
            np.testing.assert_allclose(ramped_roll(a, b, axis, 1), b, atol=1e-9)
            quarter = ramped_roll(a, b, axis, 4)
            np.testing.assert_allclose(quarter @ axis, a @ axis, atol=1e-12)  # same direction
            assert roll_between_rad(a, quarter, axis) == pytest.approx(angle / 4, abs=1e-9)
            # a rotation tilted onto another direction first: the roll is about the new one
            d = rng.normal(size=3)
            tilted = closest_rotation_with_axis(a, axis, d)
            target = closest_rotation_with_axis(b, axis, d)
            half = ramped_roll(tilted, target, axis, 2)
            np.testing.assert_allclose(half @ axis, d / np.linalg.norm(d), atol=1e-9)
            assert roll_between_rad(half, target, axis) == pytest.approx(
                roll_between_rad(tilted, target, axis) / 2, abs=1e-9)


def test_locked_joints_are_folded_into_the_urdf_the_libraries_load(tmp_path):
    """A chain joint the config locks at a non-zero value becomes a fixed joint whose origin
    holds that motion: Pinocchio on the text agrees with the robot's own FK."""
    import pinocchio as pin

    from ikbench.core.robot import load_robot
    from ikbench.schemes.chain import chain_urdf_text

    config = tmp_path / "locked.toml"
    config.write_text(f'urdf = "{DATA / "unaligned_arm.urdf"}"\nend_frame = "tool"\n'
                      "[locked]\nslide = 120.0\nj3 = 25.0\n")
    robot = load_robot(config)
    assert robot.joint_names == ("j1", "j4", "roll", "j6")
    model = pin.buildModelFromXML(chain_urdf_text(robot))
    data, frame = model.createData(), model.getFrameId("tool")
    rng = np.random.default_rng(0)
    for pose in rng.uniform(robot.sample_lower, robot.sample_upper, (20, robot.dof)):
        q = pin.neutral(model)
        for name, value in zip(robot.joint_names, robot.to_urdf(pose)):
            j = model.getJointId(name)
            i = model.idx_qs[j]
            q[i:i + model.nqs[j]] = [np.cos(value), np.sin(value)] if model.nqs[j] == 2 \
                else [value]
        pin.framesForwardKinematics(model, data, q)
        np.testing.assert_allclose(data.oMf[frame].translation * 1000.0,
                                   robot.fk(pose).point_mm[0], atol=1e-9)


def test_mink_takes_a_urdf_whose_inertias_mujoco_would_refuse():
    """PR2's sensor_mount_link breaks the inertia triangle inequality; MuJoCo refused to
    compile it, so mink could not run on PR2. Mass plays no part in IK: the inertias are
    balanced (``balanceinertia``) and mink solves."""
    pytest.importorskip("mink")
    from ikbench.core.robot import load_robot
    from ikbench.core.robot_packages import robots_folder

    if robots_folder("example-robot-data") is None:
        pytest.skip("needs example-robot-data")
    from ikbench.methods.registry import available_solvers

    robot = load_robot("example-robot-data:pr2", "r_gripper_tool_frame")
    solver = available_solvers()["mink"](robot)
    solver.prepare()  # compiles the MuJoCo model
    q = np.clip(np.zeros(robot.dof), robot.sample_lower, robot.sample_upper)
    T = robot.fk_transform(q[None])[0]
    out = solver.solve(q, T[:3, 3], T[:3, :3])
    assert np.all(np.isfinite(out.q))
