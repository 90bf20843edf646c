"""Motor config file and motor-degree <-> Dynamixel register conversions."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.hw.motors import (
    SPEED_UNIT_DEG_S,
    default_config_path,
    load_motor_config,
    parse_motor_config,
    raw_to_speed,
    speed_to_raw,
)

NICO_IDS = {"r_shoulder_z": 21, "r_shoulder_y": 1, "r_arm_x": 3, "r_elbow_y": 5,
            "r_wrist_z": 31, "r_wrist_x": 33, "r_indexfinger_x": 36}


def _spec(robot, **changes):
    """The default config as a dict, with ``changes`` = {joint: {key: value}} applied."""
    spec = json.loads(default_config_path().read_text())
    for joint, entry in changes.items():
        spec["motors"][joint].update(entry)
    return spec


def test_default_config_matches_nico(robot):
    config = load_motor_config()
    assert config.joint_names == robot.joint_names
    assert dict(zip(config.joint_names, config.ids)) == NICO_IDS
    assert config.baudrate == 1_000_000
    assert all(m.offset_deg == 0 and m.orientation == "direct" for m in config.motors)
    np.testing.assert_array_equal(config.lower_deg, robot.lower)
    np.testing.assert_array_equal(config.upper_deg, robot.upper)


@pytest.mark.parametrize("deg, raw", [(0.0, 2048), (90.0, 3072), (-90.0, 1024), (45.0, 2560),
                                      (0.1, 2049), (-180.0, 0), (179.9, 4095), (180.0, 4095)])
def test_position_formula_direct(robot, deg, raw):
    # raw = round(2048 + (deg + 0) * 4096 / 360), the encoder range ends at 4095
    motor = load_motor_config().motors[4]  # r_wrist_z, limits [-180, 180]
    assert int(motor.deg_to_raw(deg)) == raw


def test_offset_and_indirect_orientation(robot):
    spec = _spec(robot, r_wrist_z={"offset_deg": 10.0, "orientation": "indirect",
                                   "angle_limit_deg": [-170.0, 170.0]})
    motor = parse_motor_config(spec, robot, "test").motors[4]
    # raw = round(2048 - (deg + 10) * 4096 / 360)
    assert int(motor.deg_to_raw(20.0)) == round(2048 - 30 * 4096 / 360)
    assert int(motor.deg_to_raw(-10.0)) == 2048
    assert motor.raw_limits == (round(2048 - 180 * 4096 / 360), round(2048 + 160 * 4096 / 360))
    angles = np.array([-170.0, -33.3, 0.0, 101.7, 170.0])
    back = motor.raw_to_deg(motor.deg_to_raw(angles))
    assert np.abs(back - angles).max() <= 360 / 4096 / 2 + 1e-9


def test_pose_round_trip_within_half_a_step(robot):
    config = load_motor_config()
    rng = np.random.default_rng(0)
    poses = rng.uniform(config.lower_deg, config.upper_deg - 0.1, size=(200, 7))
    back = config.raw_to_poses(config.poses_to_raw(poses))
    assert np.abs(back - poses).max() <= 360 / 4096 / 2 + 1e-9


def test_speed_units_never_zero_and_clamped():
    assert SPEED_UNIT_DEG_S == pytest.approx(0.684)
    raw = speed_to_raw([0.0, 0.01, 0.684, 0.7, 106.835, 699.0, 5000.0])
    assert raw.tolist() == [1, 1, 1, 2, 157, 1022, 1023]
    # rounded up: a joint is never slower than planned (unless clamped at the register max)
    speeds = np.linspace(0.7, 690, 500)
    assert np.all(raw_to_speed(speed_to_raw(speeds)) >= speeds - 1e-9)
    assert np.all(raw_to_speed(speed_to_raw(speeds)) < speeds + SPEED_UNIT_DEG_S)


@pytest.mark.parametrize("changes, message", [
    ({"r_elbow_y": {"orientation": "reverse"}},
     "r_elbow_y.orientation = 'reverse'; allowed: direct, indirect"),
    ({"r_elbow_y": {"id": 21}}, "motor id(s) [21] are used by more than one joint"),
    ({"r_elbow_y": {"id": 300}}, "r_elbow_y.id = 300; give an integer Dynamixel id in 0..252"),
    ({"r_elbow_y": {"model": "AX-12"}}, "r_elbow_y.model = 'AX-12'; allowed: MX-28, MX-64"),
    ({"r_elbow_y": {"angle_limit_deg": [90, 60]}}, "lower must be below upper"),
    ({"r_wrist_z": {"offset_deg": 30.0}},
     "angle limit 180 deg maps to raw 4437, outside the encoder range 0..4095"),
    ({"r_elbow_y": {"max_speed_deg_s": 0}}, "r_elbow_y.max_speed_deg_s = 0; allowed: (0, 699.7]"),
    # a misspelt key must not silently drop the calibration it was meant to give
    ({"r_elbow_y": {"orientaton": "indirect"}},
     "r_elbow_y: unknown key 'orientaton' (did you mean 'orientation'?); allowed: id, model, "
     "offset_deg, orientation, angle_limit_deg, max_speed_deg_s, max_acceleration_deg_s2, "
     "description"),
    ({"r_wrist_z": {"offset": 10.0}},
     "r_wrist_z: unknown key 'offset' (did you mean 'offset_deg'?); allowed: id, model, "
     "offset_deg, orientation, angle_limit_deg, max_speed_deg_s, max_acceleration_deg_s2, "
     "description"),
    ({"r_arm_x": {"limits": [0, 60]}}, "r_arm_x: unknown key 'limits'; allowed: id, model,"),
])
def test_bad_config_names_value_through_cli(robot, tmp_path, capsys, changes, message):
    path = tmp_path / "motors.json"
    path.write_text(json.dumps(_spec(robot, **changes)))
    traj = tmp_path / "t.csv"
    traj.write_text("irrelevant")
    code = main(["plan", str(traj), "--motors", str(path)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith(f"ikbench: error: {path}: ")
    assert message in err
    assert err.count("\n") == 1


def test_missing_joint_and_missing_file(robot, tmp_path):
    spec = _spec(robot)
    del spec["motors"]["r_wrist_x"]
    with pytest.raises(InputError, match=r"missing: \['r_wrist_x'\]"):
        parse_motor_config(spec, robot, "x.json")
    with pytest.raises(InputError, match="motor config file .*nope.json' not found"):
        load_motor_config(tmp_path / "nope.json")


def test_unknown_top_level_key_is_refused(robot):
    spec = _spec(robot)
    spec["baud_rate"] = 57600
    with pytest.raises(InputError) as info:
        parse_motor_config(spec, robot, "x.json")
    assert str(info.value) == ("x.json: unknown top-level key 'baud_rate' (did you mean "
                               "'baudrate'?); allowed: description, baudrate, motors")


def test_description_keys_are_allowed(robot):
    spec = _spec(robot, r_elbow_y={"description": "replaced in 2024"})
    assert "description" in spec  # the default file has one at top level
    assert parse_motor_config(spec, robot, "x.json").motors[3].joint == "r_elbow_y"
