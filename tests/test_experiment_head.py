"""NICO's head model (ikbench/experiment/head.py, urdf/nico_head.json): gaze solve, signs
against the authors' recorded poses, the file checks."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from ikbench.core.errors import InputError
from ikbench.core.robot import robots_dir
from ikbench.experiment.head import authors_comparison, load_head, load_head_motors


@pytest.fixture(scope="module")
def head():
    return load_head()


@pytest.fixture(scope="module")
def comparison(head):
    return authors_comparison(head)


def _random_points_mm(rng: np.random.Generator, n: int) -> np.ndarray:
    """Points in front of the robot (torso_base: x behind, y right, z up), where it looks."""
    return np.column_stack([rng.uniform(-900.0, -150.0, n), rng.uniform(-500.0, 500.0, n),
                            rng.uniform(-300.0, 700.0, n)])


def test_alignment_puts_the_head_where_complete_urdf_does(head):
    # independent transcription: torso_base = Rz(180 deg) * torso:11 + t, where t makes the
    # two r_shoulder_z joint origins coincide (urdf/nico_right_arm.urdf: (0, 0.05, 0.195) m)
    t = np.array([0.0, 0.05, 0.195]) - np.array([-0.026783, 0.049912, 0.748809])
    head_z = np.array([-0.001283, 0.000212, 0.756309]) + t
    head_y = head_z + np.array([0.0, -0.023001, 0.0745])
    np.testing.assert_allclose(head.joint_origins_mm, np.stack([head_z, head_y]) * 1000,
                               atol=1e-9)
    np.testing.assert_allclose(head.joint_axes, [[0, 0, 1], [0, -1, 0]], atol=1e-12)
    # at rest the head looks forward (-x in torso_base), from above the shoulders
    np.testing.assert_allclose(head.gaze_direction(head.rest_motor_deg), [-1, 0, 0], atol=1e-12)
    assert head.eye_point_mm(head.rest_motor_deg)[2] > head.joint_origins_mm[1, 2]


def test_gaze_at_round_trips_over_random_points(head):
    rng = np.random.default_rng(59)
    points = _random_points_mm(rng, 200)
    poses = np.array([head.gaze_at(p) for p in points])
    angles = head.angles_to_points_deg(poses, points)
    assert angles.max() < 1e-6
    assert np.all(poses >= head.lower_motor_deg) and np.all(poses <= head.upper_motor_deg)
    # the eye sees each point in front of it (the ray, not the line behind the eye)
    rays = points - head.eye_point_mm(poses)
    assert np.all(np.sum(rays * head.gaze_direction(poses), axis=1) > 0)


@pytest.mark.parametrize("eye_head_m", [(0.078, -0.003, 0.084), (0.05, -0.06, -0.02),
                                        (0.0, 0.01, 0.12)])
def test_gaze_at_round_trips_for_other_eye_offsets(head, eye_head_m):
    # the shipped eye lies in the pan axis' plane; a lateral or lower eye exercises the rest
    # of the closed form
    other = dataclasses.replace(head, eye_head_m=np.array(eye_head_m))
    points = _random_points_mm(np.random.default_rng(3), 100)
    poses = np.array([other.gaze_at(p) for p in points])
    assert other.angles_to_points_deg(poses, points).max() < 1e-6


def test_batched_eye_frames_equal_single_ones(head):
    rng = np.random.default_rng(7)
    poses = np.column_stack([rng.uniform(-90, 90, 9), rng.uniform(-60, 60, 9)])
    batch = head.eye_frame(poses)
    assert batch.shape == (9, 4, 4)
    for pose, frame in zip(poses, batch):
        np.testing.assert_allclose(head.eye_frame(pose), frame, atol=1e-12)
        rotation = frame[:3, :3]
        np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
        assert head.angle_to_point_deg(pose, frame[:3, 3] + 300.0 * frame[:3, 0]) < 1e-6


def test_head_z_turns_the_line_of_sight_about_the_vertical(head):
    pose, step_deg = np.array([17.0, -31.0]), 1e-4
    up = np.array([0.0, 0.0, 1.0])
    # the line of sight turns about +z; the eye moves on a circle about the head_z axis
    for f, centre in ((head.gaze_direction, np.zeros(3)),
                      (head.eye_point_mm, head.joint_origins_mm[0])):
        derivative = (f(pose + [step_deg, 0.0]) - f(pose - [step_deg, 0.0])) / (
            2 * np.radians(step_deg))
        # a positive head_z motor angle is a positive rotation about +z (to the robot's left)
        np.testing.assert_allclose(derivative, np.cross(up, f(pose) - centre), atol=1e-6)
    assert np.linalg.norm(head.eye_point_mm(pose)[:2] - head.joint_origins_mm[0, :2]) > 50


def test_head_y_sign_follows_the_authors(head):
    # negative head_y (motor deg) looks down, the authors' neutral [0, 23] looks up
    assert head.gaze_direction([0.0, -30.0])[2] < 0
    assert head.gaze_direction(head.neutral_motor_deg)[2] > 0
    np.testing.assert_array_equal(head.neutral_motor_deg, [0.0, 23.0])
    np.testing.assert_array_equal(head.rest_motor_deg, [0.0, 0.0])


def test_signs_at_the_touch_points_match_the_authors(head, comparison):
    by_target = comparison.set_index("target")
    # target 3 lies at the robot's left (y < 0), target 6 at its right
    assert by_target.loc[3, "point_y_mm"] < 0 < by_target.loc[6, "point_y_mm"]
    assert by_target.loc[3, "head_z_motor_deg"] > 0
    assert by_target.loc[6, "head_z_motor_deg"] < 0
    assert (comparison["head_y_motor_deg"] < 0).all()
    for kind in ("recorded", "used"):
        assert (comparison[f"authors_{kind}_head_y_motor_deg"] < 0).all()
        ours = np.sign(comparison["head_z_motor_deg"].loc[[2, 5]].to_numpy())
        theirs = np.sign(comparison[f"authors_{kind}_head_z_motor_deg"].loc[[2, 5]].to_numpy())
        np.testing.assert_array_equal(ours, theirs)


def test_authors_comparison_table(head, comparison):
    assert len(comparison) == 7
    assert comparison["target"].tolist() == list(range(1, 8))
    for column in ("head_z_motor_deg", "head_y_motor_deg", "authors_recorded_head_z_motor_deg",
                   "authors_recorded_head_y_motor_deg", "authors_used_head_z_motor_deg",
                   "authors_used_head_y_motor_deg", "authors_recorded_angle_deg",
                   "authors_used_angle_deg"):
        assert np.all(np.isfinite(comparison[column].to_numpy(dtype=float))), column
    assert comparison.loc[0, "authors_recorded_head_y_motor_deg"] == -39.0
    assert comparison.loc[6, "authors_used_head_y_motor_deg"] == -40.0
    # the table's angles are those seen from the eye of each pose
    row = comparison.iloc[2]
    point = row[["point_x_mm", "point_y_mm", "point_z_mm"]].to_numpy(dtype=float)
    theirs = row[["authors_used_head_z_motor_deg", "authors_used_head_y_motor_deg"]]
    assert head.angle_to_point_deg(theirs.to_numpy(dtype=float), point) == pytest.approx(
        row["authors_used_angle_deg"], abs=1e-12)


def test_a_point_beyond_the_limits_is_refused_with_its_value(head):
    # straight below the eye, at the table: the head would pitch down past its motor limit
    below = head.eye_point_mm(head.rest_motor_deg) * [1.0, 1.0, 0.0]
    with pytest.raises(InputError, match=r"gaze_at: point \[-52.5, 0.3, 0.0\] mm needs "
                                         r"head_y = -9\d\.\d\d motor deg, outside its limits "
                                         r"\[-89, 79\]"):
        head.gaze_at(below)
    # straight up, on the pan axis: no pan angle brings the line of sight there
    on_axis = head.joint_origins_mm[0] + [0.0, 0.0, 900.0]
    with pytest.raises(InputError,
                       match=r"point \[25.5, 0.3, 1102.5\] mm lies on the head's vertical"):
        head.gaze_at(on_axis)
    with pytest.raises(InputError, match=r"point \[1.0, 2.0\]"):
        head.gaze_at([1.0, 2.0])
    with pytest.raises(InputError, match=r"head pose"):
        head.eye_frame([[1.0, 2.0, 3.0]])


def _write(tmp_path, spec) -> str:
    path = tmp_path / "head.json"
    path.write_text(json.dumps(spec) if not isinstance(spec, str) else spec, encoding="utf-8")
    return str(path)


def _shipped() -> dict:
    return json.loads((robots_dir() / "nico_head.json").read_text(encoding="utf-8"))


def test_load_head_refuses_bad_files(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_head(tmp_path / "missing.json")
    with pytest.raises(InputError, match="not readable JSON"):
        load_head(_write(tmp_path, "{not json"))
    spec = _shipped()
    spec["eyes"] = spec.pop("eye")
    with pytest.raises(InputError, match="unknown key.*'eyes'"):
        load_head(_write(tmp_path, spec))
    spec = _shipped()
    spec["joints"][1]["scale"] = "-1"
    with pytest.raises(InputError, match=r"joints.head_y.scale = '-1'"):
        load_head(_write(tmp_path, spec))
    spec = _shipped()
    spec["complete_urdf"]["head_y"]["axis"] = [1.0, 0.0, 0.0]
    with pytest.raises(InputError, match=r"head_y.axis = \[1.0, 0.0, 0.0\]"):
        load_head(_write(tmp_path, spec))
    spec = _shipped()
    spec["eye"]["point_m"] = [0.078, -0.023]
    with pytest.raises(InputError, match=r"eye.point_m = \[0.078, -0.023\]"):
        load_head(_write(tmp_path, spec))


def test_head_motors_match_the_model(head, tmp_path):
    motors = load_head_motors(head)
    assert motors.ids == (19, 20)
    assert motors.joint_names == ("head_z", "head_y")
    np.testing.assert_array_equal(motors.lower_deg, head.lower_motor_deg)
    np.testing.assert_array_equal(motors.upper_deg, head.upper_motor_deg)
    spec = json.loads((robots_dir() / "nico_head.dynamixel.json").read_text(encoding="utf-8"))
    spec["motors"]["head_y"]["angle_limit_deg"] = [-60.0, 60.0]
    path = tmp_path / "motors.json"
    path.write_text(json.dumps(spec), encoding="utf-8")
    with pytest.raises(InputError, match="differ from"):
        load_head_motors(head, path)
