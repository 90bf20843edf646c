"""Targets files: the shipped paper targets, and every kind of bad file rejected clearly."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.core.errors import TargetsError
from ikbench.core.targets import load_targets, parse_pose
from tests.conftest import PAPER_START

NAMES = ["r_shoulder_z", "r_shoulder_y", "r_arm_x", "r_elbow_y", "r_wrist_z", "r_wrist_x",
         "r_indexfinger_x"]


def test_paper_targets_shipped(paper_targets):
    assert paper_targets.is_paper and paper_targets.steps == 50
    assert paper_targets.ids == [str(i) for i in range(1, 8)]
    assert np.allclose(paper_targets.start_pose, PAPER_START)
    assert list(paper_targets.touch_poses["4"]) == [51, 54, 37, 161, 92, 38, -174]


def test_select_and_steps(paper_targets):
    sub = paper_targets.select("3,1")
    assert sub.ids == ["3", "1"] and sub.is_paper
    assert paper_targets.with_steps(10).steps == 10
    with pytest.raises(TargetsError, match=r"only: '' names an empty trajectory id"):
        paper_targets.select("")
    with pytest.raises(TargetsError, match=r"unknown trajectory id.*'9'.*available: 1, 2"):
        paper_targets.select("1,9")


def _doc(**overrides):
    doc = {"joint_names": NAMES, "start_pose": PAPER_START,
           "targets": {"a": [33, 39, 25, 134, 102, 77, -168]}, "steps": 20}
    doc.update(overrides)
    return doc


def _write(tmp_path, doc, raw=None):
    path = tmp_path / "targets.json"
    path.write_text(raw if raw is not None else json.dumps(doc))
    return path


def test_changed_start_pose_is_not_the_paper_task(paper_targets):
    from dataclasses import replace

    moved = replace(paper_targets, start_pose=np.array([0, 45, 0, 90, 0, 0, 0], float))
    assert paper_targets.is_paper and not moved.is_paper


def test_user_file_loads(tmp_path):
    targets = load_targets(_write(tmp_path, _doc()))
    assert not targets.is_paper and targets.ids == ["a"] and targets.steps == 20


BAD_FILES = [
    ("unparseable", None, "{not json", r"not valid JSON"),
    ("wrong length", _doc(start_pose=[1, 2, 3]), None, r"start_pose: expected 7 angles"),
    ("non-numeric", _doc(targets={"a": [1, 2, 3, "x", 5, 6, 7]}), None, r"target 'a'.*not a list"),
    ("nan", None, json.dumps(_doc()).replace("-168", "NaN"),
     r"target 'a': r_indexfinger_x = nan is not a finite number"),
    ("inf", None, json.dumps(_doc()).replace("-168", "Infinity"),
     r"target 'a': r_indexfinger_x = inf is not a finite"),
    ("out of range", _doc(targets={"a": [33, 39, 25, 20, 102, 77, -168]}), None,
     r"r_elbow_y = 20 motor deg is outside its range \[50, 180\]"),
    ("unknown joint", _doc(joint_names=NAMES[:6] + ["r_thumb"]), None, r"joint_names .* must be"),
    ("reordered", _doc(joint_names=NAMES[::-1]), None, r"joint_names .* must be exactly"),
    ("duplicate id", None,
     f'{{"joint_names": {json.dumps(NAMES)}, "start_pose": {PAPER_START}, '
     f'"targets": {{"a": {PAPER_START}, "a": {PAPER_START}}}}}', r"duplicate key 'a'"),
    ("empty id", _doc(targets={"": PAPER_START}), None, r"target id '' is not allowed"),
    ("path in id", _doc(targets={"../x": PAPER_START}), None, r"target id '../x' is not allowed"),
    ("comma in id", _doc(targets={"1,2": PAPER_START}), None, r"target id '1,2' is not allowed"),
    ("unknown key", _doc(stpes=3), None, r"unknown key\(s\) 'stpes'; allowed: joint_names"),
    ("no targets", _doc(targets={}), None, r"targets must be a non-empty object"),
    ("steps < 2", _doc(steps=1), None, r"steps = 1 must be an integer in \[2, 5000\]"),
    ("missing key", {"joint_names": NAMES}, None, r"missing key\(s\) start_pose, targets"),
]


@pytest.mark.parametrize("label, doc, raw, message", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_files_rejected(tmp_path, label, doc, raw, message):
    path = _write(tmp_path, doc, raw)
    with pytest.raises(TargetsError, match=message):
        load_targets(path)


def test_missing_file():
    with pytest.raises(TargetsError, match="cannot read targets file"):
        load_targets("/nonexistent/targets.json")


@pytest.mark.parametrize("text, message", [
    ("1,2,3", r"expected 7 angles"),
    ("0,0,0,90,0,0,x", r"'x' is not a number"),
    ("0,0,0,90,0,0,inf", r"'inf' is not a finite number"),
    ("0,0,0,10,0,0,0", r"r_elbow_y = 10 motor deg is outside its range \[50, 180\]"),
])
def test_parse_pose_errors(text, message):
    with pytest.raises(TargetsError, match=message):
        parse_pose(text)


def test_cli_bad_pose_one_line_exit_2(capsys):
    assert main(["fk", "--pose=0,0,0,10,0,0,0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "r_elbow_y = 10 motor deg is outside its range [50, 180]" in err


def test_a_robot_without_default_targets_names_the_field_and_the_cli_the_flag(tmp_path, capsys):
    """core names the field (``targets``), the command line the option that sets it."""
    import ikbench
    from tests.conftest import REPO

    urdf = REPO / "urdf" / "panda.urdf"
    bare = ikbench.load_robot(urdf, end_frame="panda_link8")
    with pytest.raises(TargetsError, match="^targets: robot panda ships no default targets; "
                       "give a targets file"):
        load_targets(None, bare)
    code = main(["run", "--robot", str(urdf), "--end-frame", "panda_link8", "--method",
                 "ours-lm", "--output", str(tmp_path), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("ikbench: error: --targets: robot panda ships no "
                                        "default targets; give a targets file (start and "
                                        "touch poses in joint deg")
    assert not list(tmp_path.iterdir())
