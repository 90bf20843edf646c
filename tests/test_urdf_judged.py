"""No value of a URDF changes the judge silently, and no URDF makes unbounded work (issue 64,
items 1 and 3), through the CLI.

A chain joint whose ``<limit velocity>`` is zero or negative used to drop the speed criterion
for the whole robot ("no speed limit known") and a trajectory stepping 192 deg per segment was
judged a success; limits of +-1e300 gave every method 0 % with numpy overflow warnings; a
``<mimic>`` joint was solved as an independent joint; ``inf`` in an ``rpy`` printed trimesh's
warnings before the line; a 50 MB URDF of 223,569 links ran ``fk`` for 18 minutes. Each is now
one line on stderr and exit code 2 (the same flaws outside the chain are accepted: a gripper's
mimic joint or a wheel without a speed limit is no part of the arm judged).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ikbench.cli import main
from ikbench.core import urdf_model

ROOT = Path(__file__).resolve().parents[1]
NICO = (ROOT / "urdf" / "nico_right_arm.urdf").read_text()
END = "r_indexfinger_tip"
POSE = "--pose=0,45,-20,-90,0,0,45"
#: r_arm_x's limit element, as the shipped URDF writes it.
ARM_X_LIMIT = re.search(r'<limit lower="-1.2217304763960306"[^>]*/>', NICO)[0]
WRIST_X = re.search(r'<joint name="r_wrist_x" type="revolute">.*?</joint>', NICO, re.S)[0]
ELBOW_ORIGIN = '<origin xyz="0 0 0" rpy="0 0 3.1415926535897931"/>'


def _flawed(old: str, new: str) -> str:
    assert NICO.count(old) == 1, old
    return NICO.replace(old, new)


def _limit(lower: str = "-1", upper: str = "0", velocity: str = "5") -> str:
    return f'<limit lower="{lower}" upper="{upper}" effort="10" velocity="{velocity}"/>'


#: id -> (URDF text, what the one line must say).
CASES = {
    "zero velocity": (
        _flawed(ARM_X_LIMIT, _limit(velocity="0")),
        "joint 'r_arm_x' of the chain has <limit velocity=\"0\">; a chain joint's velocity "
        "limit must be a positive number [rad/s, m/s for prismatic]"),
    "negative velocity": (
        _flawed(ARM_X_LIMIT, _limit(velocity="-2")),
        "joint 'r_arm_x' of the chain has <limit velocity=\"-2\">; a chain joint's velocity "
        "limit must be a positive number"),
    "infinite velocity": (
        _flawed(ARM_X_LIMIT, _limit(velocity="inf")),
        "joint 'r_arm_x': <limit velocity=\"inf\"> must be a finite number"),
    "limits of 1e300": (
        _flawed(ARM_X_LIMIT, _limit("-1e300", "1e300")),
        "joint 'r_arm_x' of the chain has <limit lower=\"-1e+300\" upper=\"1e+300\">; a "
        "revolute joint's limits must lie within +-10000 rad (a joint that turns without "
        "limits is type=\"continuous\")"),
    "prismatic limits of 1e4 m": (
        _flawed(ARM_X_LIMIT, _limit("0", "1e4")).replace(
            'name="r_arm_x" type="revolute"', 'name="r_arm_x" type="prismatic"'),
        "joint 'r_arm_x' of the chain has <limit lower=\"0\" upper=\"10000\">; a prismatic "
        "joint's limits must lie within +-1000 m"),
    "mimic": (
        _flawed(WRIST_X, WRIST_X.replace(
            "</joint>", '<mimic joint="r_wrist_z" multiplier="1" offset="0"/></joint>')),
        "joint 'r_wrist_x' of the chain mimics joint 'r_wrist_z' (<mimic>): ikbench solves "
        "every chain joint independently and models no coupled joint"),
    "inf in rpy": (
        _flawed(ELBOW_ORIGIN, '<origin xyz="0 0 0" rpy="0 inf 3.1415926535897931"/>'),
        "joint 'r_elbow_y': its <origin xyz=\"0 0 0\" rpy=\"0 inf 3.1415926535897931\"> holds "
        "a number that is not finite; xyz and rpy are three finite numbers each (while "
        "parsing, trimesh warned: invalid value encountered in"),
    "nan in xyz": (
        _flawed(ELBOW_ORIGIN, '<origin xyz="0 nan 0" rpy="0 0 3.1415926535897931"/>'),
        "joint 'r_elbow_y': its <origin xyz=\"0 nan 0\""),
}

#: A link hung from the torso by joints the chain does not hold: a mimic joint and a joint
#: without a speed limit (velocity 0, limits of 1e300).
SIDE = ('<link name="side_a"/><link name="side_b"/>'
        '<joint name="side_ja" type="revolute"><parent link="torso_base"/>'
        '<child link="side_a"/><axis xyz="0 0 1"/>'
        '<limit lower="-1e300" upper="1e300" effort="1" velocity="0"/></joint>'
        '<joint name="side_jb" type="revolute"><parent link="side_a"/><child link="side_b"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'
        '<mimic joint="side_ja"/></joint></robot>')


def _one_line(capfd) -> str:
    """stderr of a command (C-level output too), checked to be one line, no traceback."""
    out, err = capfd.readouterr()
    assert err.count("\n") == 1 and err.startswith("ikbench: error: "), err
    assert "Traceback" not in out + err and "Warning" not in err
    return err.strip()


@pytest.mark.parametrize("case", CASES)
def test_a_urdf_value_that_would_change_the_judge_is_refused_in_one_line(case, tmp_path,
                                                                          capfd):
    text, message = CASES[case]
    urdf = tmp_path / "broken.urdf"
    urdf.write_text(text)
    code = main(["fk", "--robot", str(urdf), "--end-frame", END, POSE])
    err = _one_line(capfd)
    assert code == 2
    assert err.startswith("ikbench: error: --robot: broken.urdf: ") and message in err, err


@pytest.mark.parametrize("case", ["zero velocity", "mimic", "limits of 1e300"])
def test_robot_init_refuses_them_too(case, tmp_path, capfd):
    urdf = tmp_path / "broken.urdf"
    urdf.write_text(CASES[case][0])
    code = main(["robot", "init", str(urdf), "--end-frame", END,
                 "--output", str(tmp_path / "out")])
    err = _one_line(capfd)
    assert code == 2 and CASES[case][1] in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("case", ["zero velocity", "mimic"])
def test_a_judging_command_refuses_them_before_it_solves(case, tmp_path, capfd):
    urdf = tmp_path / "broken.urdf"
    urdf.write_text(CASES[case][0])
    code = main(["compare", "--robot", str(urdf), "--end-frame", END, "--only", "1",
                 "--output", str(tmp_path / "out")])
    err = _one_line(capfd)
    assert code == 2 and CASES[case][1] in err, err
    assert not (tmp_path / "out").exists()


def test_the_same_joints_outside_the_chain_are_accepted(tmp_path, capfd):
    urdf = tmp_path / "side.urdf"
    urdf.write_text(_flawed("</robot>", SIDE))
    assert main(["fk", "--robot", str(urdf), "--end-frame", END, POSE]) == 0
    out, err = capfd.readouterr()
    assert "point [mm]" in out and err == ""


def test_a_continuous_joint_without_a_limit_keeps_no_speed_limit_known(tmp_path):
    """A joint with no ``<limit>`` (continuous) gives no speed limit: the contract says the
    speed criterion is unknown, as before (a stated handling, not a refusal)."""
    from ikbench.core.contract import speed_limits
    from ikbench.core.robot import load_robot

    text = _flawed(ARM_X_LIMIT, "").replace('name="r_arm_x" type="revolute"',
                                            'name="r_arm_x" type="continuous"')
    urdf = tmp_path / "free.urdf"
    urdf.write_text(text)
    limits, source = speed_limits(load_robot(urdf, END))
    assert limits is None and source.startswith("no speed limit known")


def _no_parse(monkeypatch) -> None:
    import yourdfpy

    def refuse(*args, **kwargs):
        raise AssertionError("the file was parsed")

    monkeypatch.setattr(yourdfpy.URDF, "load", refuse)


def test_a_urdf_above_the_size_limit_is_refused_before_it_is_parsed(tmp_path, capfd,
                                                                    monkeypatch):
    """The issue's case: 50 MB (223,569 links) ran ``fk`` for 18 minutes."""
    _no_parse(monkeypatch)
    link = '<link name="l{k}"/><joint name="j{k}" type="fixed"><parent link="l{p}"/>' \
           '<child link="l{k}"/></joint>'
    body = "".join(link.format(k=k, p=k - 1) for k in range(1, 224_000))
    urdf = tmp_path / "huge.urdf"
    urdf.write_text(f'<robot name="huge"><link name="l0"/>{body}</robot>')
    size_mb = urdf.stat().st_size / 1e6
    assert size_mb > urdf_model.MAX_URDF_BYTES / 1e6
    assert main(["fk", "--robot", str(urdf), "--end-frame", "l5", "--pose=0"]) == 2
    err = _one_line(capfd)
    assert f"huge.urdf': it is {size_mb:.1f} MB; the largest URDF read is 20 MB" in err, err


def test_a_urdf_of_too_many_links_is_refused_before_it_is_parsed(tmp_path, capfd,
                                                                 monkeypatch):
    _no_parse(monkeypatch)
    links = "".join(f'<link name="l{k}"/>' for k in range(urdf_model.MAX_LINKS + 1))
    urdf = tmp_path / "many.urdf"
    urdf.write_text(f'<robot name="many">{links}</robot>')
    assert main(["fk", "--robot", str(urdf), "--end-frame", "l5", "--pose=0"]) == 2
    assert "many.urdf': it has 5,001 <link> elements; the most a URDF read may have is " \
           "5,000" in _one_line(capfd)
