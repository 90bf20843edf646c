"""Broken URDFs are refused in one line, through the CLI (issue 49, item 3).

Each case is ``urdf/nico_right_arm.urdf`` with one flaw written into it (a joint without
``<limit>``, a zero or non-finite ``<axis>``, duplicate names, a detached link, a loop, ...).
Every case, given to ``ikbench fk`` as a bare URDF, and one case given to every command that
loads a robot: exit code 2, exactly one line on stderr (C-level output included: urdfdom
printed its own error before), naming the joint or link, and no traceback. Before this, a
missing limit gave urdfdom's error and a traceback (exit 1), a zero axis exit 0 and NaNs.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ikbench.cli import main

ROOT = Path(__file__).resolve().parents[1]
NICO = (ROOT / "urdf" / "nico_right_arm.urdf").read_text()
END = "r_indexfinger_tip"
#: r_arm_x's limit element, as the shipped URDF writes it.
ARM_X_LIMIT = re.search(r'<limit lower="-1.2217304763960306"[^>]*/>', NICO)[0]
FIRST_AXIS = '<axis xyz="0 0 1"/>'


def _flawed(old: str, new: str, count: int = 1) -> str:
    assert old in NICO
    return NICO.replace(old, new, count)


#: id -> (URDF text, what the one line must say).
CASES = {
    "revolute without limit": (
        _flawed(ARM_X_LIMIT, ""),
        "joint 'r_arm_x' is revolute and has no <limit>; a revolute or prismatic joint needs "
        '<limit lower="..." upper="..." effort="..." velocity="..."/>'),
    "prismatic without limit": (
        _flawed(ARM_X_LIMIT, "").replace('name="r_arm_x" type="revolute"',
                                         'name="r_arm_x" type="prismatic"'),
        "joint 'r_arm_x' is prismatic and has no <limit>"),
    "limit without effort": (
        _flawed(ARM_X_LIMIT, ARM_X_LIMIT.replace(' effort="10"', "")),
        "joint 'r_arm_x': its <limit> has no effort; a <limit> needs effort and velocity"),
    "limit lower above upper": (
        _flawed(ARM_X_LIMIT, '<limit lower="1" upper="-1" effort="10" velocity="5"/>'),
        "joint 'r_arm_x': <limit lower=\"1\" upper=\"-1\">: lower must not be above upper"),
    "limit not finite": (
        _flawed(ARM_X_LIMIT, '<limit lower="-1" upper="nan" effort="10" velocity="5"/>'),
        "joint 'r_arm_x': <limit upper=\"nan\"> must be a finite number"),
    "zero axis": (
        _flawed(FIRST_AXIS, '<axis xyz="0 0 0"/>'),
        "joint 'r_shoulder_z': <axis xyz=\"0 0 0\"> is no direction; give three finite "
        "numbers, not all zero"),
    "nan axis": (
        _flawed(FIRST_AXIS, '<axis xyz="0 nan 1"/>'),
        "joint 'r_shoulder_z': <axis xyz=\"0 nan 1\"> is no direction"),
    "infinite axis": (
        _flawed(FIRST_AXIS, '<axis xyz="inf 0 1"/>'),
        "joint 'r_shoulder_z': <axis xyz=\"inf 0 1\"> is no direction"),
    "origin not finite": (
        re.sub(r'(<joint name="r_elbow_y" type="revolute">\s*<origin xyz=")[^"]*"',
               r'\1nan 0 0"', NICO, count=1),
        "joint 'r_elbow_y': its <origin xyz=\"nan 0 0\" rpy=\"0 0 3.1415926535897931\"> "
        "holds a number that is not finite; xyz and rpy are three finite numbers each"),
    "unknown joint type": (
        _flawed('name="r_wrist_z" type="revolute"', 'name="r_wrist_z" type="hinge"'),
        "joint 'r_wrist_z' has type 'hinge'; allowed: revolute, continuous, prismatic, fixed, "
        "floating, planar"),
    "duplicate link": (
        _flawed('<link name="r_elbow_y_mount"/>',
                '<link name="r_elbow_y_mount"/><link name="r_elbow_y_mount"/>'),
        "link 'r_elbow_y_mount' is defined 2 times; link names must be unique"),
    "duplicate joint": (
        _flawed('joint name="r_wrist_x_mount_joint"', 'joint name="r_shoulder_z"'),
        "joint 'r_shoulder_z' is defined 2 times; joint names must be unique"),
    "undefined link": (
        _flawed('<child link="r_hand_link"/>', '<child link="r_hand"/>'),
        "joint 'r_wrist_x' names the child link 'r_hand', which the URDF does not define"),
    "detached end link": (
        re.sub(r'<joint name="r_indexfinger_tip_joint".*?</joint>', "", NICO, flags=re.S),
        "links 'torso_base', 'r_indexfinger_tip' are all roots (no joint's child); a URDF has "
        "one root link"),
    "two parents": (
        _flawed("</robot>", '<joint name="extra" type="fixed"><parent link="torso_base"/>'
                '<child link="r_hand_link"/></joint></robot>'),
        "link 'r_hand_link' is the child of joints 'r_wrist_x' and 'extra'; a link has one "
        "parent joint"),
    "loop": (
        _flawed("</robot>", '<link name="a"/><link name="b"/>'
                '<joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>'
                '<joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint>'
                "</robot>"),
        "links 'a', 'b' form a loop of joints 'ba', 'ab' that no root reaches"),
}


def _one_line(capfd) -> str:
    """stderr of a command (C-level output too), checked to be one line, no traceback."""
    out, err = capfd.readouterr()
    assert err.count("\n") == 1 and err.startswith("ikbench: error: "), err
    assert "Traceback" not in out + err
    return err.strip()


@pytest.mark.parametrize("case", CASES)
def test_a_broken_urdf_is_refused_in_one_line(case, tmp_path, capfd):
    text, message = CASES[case]
    urdf = tmp_path / "broken.urdf"
    urdf.write_text(text)
    code = main(["fk", "--robot", str(urdf), "--end-frame", END, "--pose=0,45,-20,-90,0,0,45"])
    err = _one_line(capfd)
    assert code == 2
    assert err.startswith("ikbench: error: --robot: broken.urdf: ") and message in err, err


def test_a_broken_urdf_is_refused_before_its_end_frame_is_asked_for(tmp_path, capfd):
    urdf = tmp_path / "broken.urdf"
    urdf.write_text(CASES["zero axis"][0])
    assert main(["fk", "--robot", str(urdf)]) == 2
    assert "<axis xyz=\"0 0 0\"> is no direction" in _one_line(capfd)


#: A command line of every command that loads a robot, less ``--robot`` and ``--end-frame``.
COMMANDS = {
    "fk": ["fk", "--pose=0,45,-20,-90,0,0,45"],
    "ik": ["ik", "--count", "2"],
    "run": ["run", "--no-animation"],
    "letters": ["letters", "P", "--no-animation"],
    "compare": ["compare"],
    "sweep": ["sweep", "--weight", "c0=10"],
    "ablate": ["ablate"],
    "bench": ["bench"],
    "batch": ["batch"],
    "dataset": ["dataset", "--count", "5"],
}


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("case", ["revolute without limit", "zero axis"])
def test_every_command_that_loads_a_robot_refuses_it(command, case, tmp_path, capfd):
    text, message = CASES[case]
    urdf = tmp_path / "broken.urdf"
    urdf.write_text(text)
    output = [] if command == "fk" else ["--output", str(tmp_path / "out")]
    argv = [*COMMANDS[command], "--robot", str(urdf), "--end-frame", END, *output]
    code = main(argv)
    err = _one_line(capfd)
    assert code == 2 and message in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("case", ["revolute without limit", "zero axis"])
def test_learn_refuses_a_broken_robot_config_before_it_trains(case, tmp_path, capfd):
    """``learn --robot`` takes a name or a robot config (no ``--end-frame``): a config whose
    URDF is broken is refused in one line, the dataset (a real one) untouched, no model."""
    from ikbench.studies.dataset import build_dataset

    dataset = tmp_path / "dataset"
    build_dataset(8, seed=3, steps=4, shard_size=8, output=dataset, progress=False)
    before = sorted(p.name for p in dataset.iterdir())
    text, message = CASES[case]
    (tmp_path / "broken.urdf").write_text(text)
    config = tmp_path / "arm.toml"
    config.write_text(f'urdf = "{tmp_path / "broken.urdf"}"\nend_frame = "{END}"\n')
    capfd.readouterr()
    code = main(["learn", str(dataset), "--kind", "pose", "--output",
                 str(tmp_path / "m.pt"), "--robot", str(config)])
    err = _one_line(capfd)
    assert code == 2 and message in err and "--robot" in err, err
    assert not list(tmp_path.glob("m.pt*"))
    assert sorted(p.name for p in dataset.iterdir()) == before


def test_a_chain_that_does_not_reach_the_end_frame_names_the_candidates(tmp_path, capfd):
    config = tmp_path / "arm.toml"
    config.write_text(f'urdf = "{ROOT / "urdf" / "nico_right_arm.urdf"}"\n'
                      'base_link = "r_hand_link"\nend_frame = "r_forearm_link"\n')
    assert main(["fk", "--robot", str(config), "--pose=0"]) == 2
    assert _one_line(capfd) == (
        "ikbench: error: --end-frame: 'r_forearm_link' is not below the base link "
        "'r_hand_link' in nico_right_arm.urdf; candidates (leaf links first, then tool-like "
        "names): r_indexfinger_tip, r_indexfinger_link")
