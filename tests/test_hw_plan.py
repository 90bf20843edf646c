"""Motion plan: segment speeds [motor deg/s], register values and flags; ``ikbench plan``."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.trajectory import write_trajectory_csv
from ikbench.hw.motors import default_config_path, load_motor_config, parse_motor_config
from ikbench.hw.plan import make_plan
from tests.conftest import blocked_output, exit_code

START = np.array([-24.92, 81.45, 46.55, 94.37, -59.03, 28.0, 45.67])
TOUCH_1 = np.array([33, 39, 25, 134, 102, 77, -168.0])


def line_poses(n: int = 50) -> np.ndarray:
    """Joint-space interpolation start -> touch pose 1, (n+1, 7)."""
    return START + np.linspace(0.0, 1.0, n + 1)[:, None] * (TOUCH_1 - START)


@pytest.fixture()
def traj(tmp_path, robot):
    return write_trajectory_csv(tmp_path / "line.csv", robot, line_poses())


def test_speeds_and_registers_hand_computed():
    poses = np.array([START, START + [4, 0, -2, 0, 0, 0, 0.01], START + [4, 0, -2, 0, 0, 0, 0.01]])
    plan = make_plan(poses, load_motor_config(), duration_s=0.2)
    assert plan.n_segments == 2 and plan.segment_s == pytest.approx(0.1)
    # 4 deg in 0.1 s = 40 deg/s -> ceil(40 / 0.684) = 59; 0.01 deg -> 0.1 deg/s -> 1, never 0
    np.testing.assert_allclose(plan.speed_deg_s[0], [40, 0, 20, 0, 0, 0, 0.1], atol=1e-9)
    assert plan.speed_raw[0].tolist() == [59, 1, 30, 1, 1, 1, 1]
    assert plan.speed_raw[1].tolist() == [1] * 7
    expected_goal = [round(2048 + q * 4096 / 360) for q in poses[1]]
    assert plan.goal_raw[0].tolist() == expected_goal
    assert not plan.flagged.any()


def test_line_speed_is_constant_and_matches_delta_over_segment():
    plan = make_plan(line_poses(), load_motor_config(), duration_s=2.0)
    expected = np.abs(TOUCH_1 - START) / 2.0  # the whole delta over T, as 50 equal pieces
    np.testing.assert_allclose(plan.speed_deg_s, np.tile(expected, (50, 1)), rtol=1e-9)
    assert plan.goal_raw[-1].tolist() == [round(2048 + q * 4096 / 360) for q in TOUCH_1]


def test_over_speed_flag_at_short_duration():
    plan = make_plan(line_poses(), load_motor_config(), duration_s=0.5)
    # finger: 213.67 deg in 0.5 s = 427 deg/s, wrist_z 322 deg/s > 270; shoulder_z 116 is fine
    flagged_joints = set(np.array(plan.config.joint_names)[plan.over_speed.any(axis=0)])
    assert flagged_joints == {"r_wrist_z", "r_indexfinger_x"}
    assert plan.flagged.all()
    with pytest.raises(InputError, match="50 of 50 segments are flagged; r_wrist_z: 50 "):
        plan.check_executable()


def test_out_of_limits_flag_with_narrower_config(robot):
    spec = json.loads(default_config_path().read_text())
    spec["motors"]["r_elbow_y"]["angle_limit_deg"] = [50.0, 120.0]
    config = parse_motor_config(spec, robot, "narrow.json")
    plan = make_plan(line_poses(), config, duration_s=2.0)
    elbow = np.linspace(94.37, 134, 51)
    # a segment is flagged when either end leaves the limits
    expected = (elbow[:-1] > 120) | (elbow[1:] > 120)
    np.testing.assert_array_equal(plan.out_of_limits[:, 3], expected)
    assert not np.delete(plan.out_of_limits, 3, axis=1).any()
    assert plan.table()["out_of_limits"].tolist() == ["r_elbow_y" if e else "" for e in expected]


def test_plan_cli_writes_pandas_readable_table(traj, capsys):
    assert main(["plan", str(traj), "--duration", "2"]) == 0
    out = capsys.readouterr().out
    table = pd.read_csv(traj.with_name("line.plan.csv"))
    assert len(table) == 50
    assert table["segment"].tolist() == list(range(50))
    assert table["t_end_s"].iloc[-1] == pytest.approx(2.0)
    assert table["r_indexfinger_x_speed_deg_s"].to_numpy() == pytest.approx(213.67 / 2)
    assert table["r_indexfinger_x_speed_raw"].eq(157).all()
    assert not table["flagged"].any()
    assert table["over_speed"].isna().all()  # empty text: no flag
    assert "50 segments of 40 ms (T = 2 s)" in out
    assert "no segment flagged" in out
    assert "indexfinger_x 106.8/270" in out


def test_plan_cli_flags_and_out_option(traj, tmp_path, capsys):
    out_csv = tmp_path / "sub" / "fast.csv"
    assert main(["plan", str(traj), "--duration", "0.5", "--out", str(out_csv)]) == 0
    out = capsys.readouterr().out
    table = pd.read_csv(out_csv)
    assert table["flagged"].all()
    assert set(table["over_speed"]) == {"r_wrist_z;r_indexfinger_x"}
    assert "FLAGGED: 50 of 50 segments" in out
    assert "r_indexfinger_x: 50 segment(s) above its speed limit 270 deg/s" in out
    assert "time_s column ends at 2 s; playing it in 0.5 s" in out


def test_plan_cli_flags_poses_outside_robot_ranges(tmp_path, robot, capsys):
    # the executor refuses such a file; the plan shows where it goes wrong instead
    poses = line_poses()
    poses[30:, 2] = 75.0  # r_arm_x range is [0, 70]
    frame = pd.read_csv(write_trajectory_csv(tmp_path / "ok.csv", robot, line_poses()))
    frame["r_arm_x"] = poses[:, 2]
    frame.to_csv(tmp_path / "bad.csv", index=False)
    assert main(["plan", str(tmp_path / "bad.csv")]) == 0
    table = pd.read_csv(tmp_path / "bad.plan.csv")
    assert table.index[table["flagged"]].tolist() == list(range(29, 50))
    assert "r_arm_x: 21 segment(s) outside its limits [0, 70] deg" in capsys.readouterr().out


@pytest.mark.parametrize("duration, message", [
    ("0.1", "--duration 0.1 s gives segments of 2 ms; give at least 0.25 s for 50 segments"),
    ("-2", "argument --duration: -2 is out of range; give a duration [s] from 0.001 to 3600"),
    ("nan", "argument --duration: nan is not a finite number"),
])
def test_plan_cli_bad_duration(traj, capsys, duration, message):
    assert exit_code(["plan", str(traj), f"--duration={duration}"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_plan_cli_missing_file(tmp_path, capsys):
    assert exit_code(["plan", str(tmp_path / "none.csv")]) == 2
    assert "none.csv' not found; give a trajectory CSV" in capsys.readouterr().err


@pytest.mark.parametrize("blocked_by", ["file", "directory"])
def test_plan_cli_unwritable_out_is_one_line(traj, tmp_path, capsys, blocked_by):
    out_csv, reason = blocked_output(tmp_path, blocked_by, "plan.csv")
    assert main(["plan", str(traj), "--out", str(out_csv)]) == 2
    out, err = capsys.readouterr()
    assert out == ""  # refused before the table is printed
    assert err == f"ikbench: error: --out: cannot write {out_csv}: {reason}\n"
