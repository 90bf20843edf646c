"""The names the pose fields had (``*_pose_deg``, ``poses_deg``, ``*_motor_deg``) still read
the renamed fields and are still taken as keywords, each with a DeprecationWarning, while the
file formats keep their keys."""

from __future__ import annotations

import json
import warnings
from dataclasses import replace

import numpy as np
import pytest

import ikbench
from ikbench.core.deprecation import renamed_fields, renamed_keywords
from ikbench.core.task import Task, file_task, letter_task, line_task
from ikbench.methods.base import Solution
from tests.conftest import PAPER_START


@pytest.fixture(scope="module")
def line(robot, paper_targets):
    return ikbench.build_tasks(robot, paper_targets.select("1"))[0]


@pytest.mark.parametrize("old, new", [("start_pose_deg", "start_pose"),
                                      ("end_pose_deg", "end_pose"),
                                      ("reference_pose_deg", "reference_pose"),
                                      ("initial_pose_deg", "initial_pose")])
def test_an_old_task_field_reads_the_new_one(line, old, new):
    with pytest.warns(DeprecationWarning, match=f"Task: {old} is deprecated .*; use {new}"):
        value = getattr(line, old)
    assert value is getattr(line, new)


def test_the_other_classes_keep_their_old_names(robot, paper_targets):
    with pytest.warns(DeprecationWarning, match="Robot: lower_motor_deg"):
        assert robot.lower_motor_deg is robot.lower
    with pytest.warns(DeprecationWarning, match="Robot: upper_motor_deg"):
        assert robot.upper_motor_deg is robot.upper
    with pytest.warns(DeprecationWarning, match="Targets: start_pose_deg"):
        assert paper_targets.start_pose_deg is paper_targets.start_pose
    with pytest.warns(DeprecationWarning, match="Targets: touch_poses_deg"):
        assert paper_targets.touch_poses_deg is paper_targets.touch_poses
    solution = Solution(np.zeros((3, 7)), 1, 0.0, None)
    with pytest.warns(DeprecationWarning, match="Solution: poses_deg .*; use poses"):
        assert solution.poses_deg is solution.poses


def test_old_keywords_build_the_same_objects(robot, paper_targets, line):
    touch = paper_targets.touch_poses["1"]
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        old = line_task(robot, start_pose_deg=paper_targets.start_pose, end_pose_deg=touch,
                        steps=line.steps)
    assert [str(w.message).split(" is ")[0] for w in said] == [
        "line_task: start_pose_deg", "line_task: end_pose_deg"]
    np.testing.assert_array_equal(old.goal_points_mm, line.goal_points_mm)
    np.testing.assert_array_equal(old.end_pose, touch)
    with pytest.warns(DeprecationWarning, match="Task: reference_pose_deg"):
        task = Task("t", line.goal_points_mm, line.goal_directions, None, None,
                    reference_pose_deg=np.asarray(PAPER_START))
    np.testing.assert_array_equal(task.reference_pose, PAPER_START)
    with pytest.warns(DeprecationWarning, match="Task: start_pose_deg"):
        moved = replace(line, start_pose_deg=np.zeros(7))  # the caller's value wins
    assert not moved.start_pose.any() and moved.end_pose is line.end_pose
    with pytest.warns(DeprecationWarning, match="Solution: poses_deg"):
        assert Solution(poses_deg=np.ones((2, 7)), iterations=0, duration_s=0.0,
                        loss=None).poses.sum() == 14
    with pytest.warns(DeprecationWarning, match="letter_task: start_pose_deg"):
        letter = letter_task(robot, "L", start_pose_deg=PAPER_START, steps=8)
    np.testing.assert_array_equal(letter.reference_pose, PAPER_START)


def test_new_names_warn_nothing_and_unknown_keywords_still_fail(robot, paper_targets, tmp_path):
    path = tmp_path / "points.csv"
    path.write_text("x_mm,y_mm,z_mm\n300,0,100\n300,50,100\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        task = file_task("polyline", path, 4, reference_pose=np.asarray(PAPER_START))
        assert task.reference_pose is not None and task.start_pose is None
    with pytest.raises(TypeError, match="start_pose_degrees"):
        line_task(robot, start_pose_degrees=paper_targets.start_pose)  # type: ignore[call-arg]


def test_a_renamed_field_keeps_its_file_key(robot, tmp_path):
    ikbench.run("ours-lm", robot=robot, only="1", steps=6, output=tmp_path, progress=False)
    record = json.loads((tmp_path / "ours-lm" / "run.json").read_text())
    assert record["start_pose_deg"] == PAPER_START and "start_pose" not in record


def test_the_helpers_on_a_class_of_their_own():
    from dataclasses import dataclass

    @renamed_fields({"old": "new"})
    @dataclass
    class Thing:
        new: int

    @renamed_keywords({"before": "after"})
    def twice(after: int) -> int:
        return 2 * after

    with pytest.warns(DeprecationWarning, match="Thing: old is deprecated"):
        assert Thing(old=3).new == 3
    with pytest.warns(DeprecationWarning, match="twice: before is deprecated"):
        assert twice(before=4) == 8
    assert twice(5) == 10 and twice.__name__ == "twice"
