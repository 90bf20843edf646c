"""The run folder's animation.gif: frames at the trajectory's real speed, the arm drawn,
small, linked from report.md, and skipped with --no-animation / animation=False."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import ikbench
from ikbench.cli import main
from ikbench.core.task import letter_task, line_tasks
from ikbench.render.animation import frame_steps, write_animation
from tests.conftest import register_temporarily
from tests.test_run_folder import Straight

DATA = Path(__file__).parent / "data"


@pytest.mark.parametrize("steps, max_frames, stride, shown", [
    (50, 26, 2, list(range(0, 51, 2))),
    (4, 26, 1, [0, 1, 2, 3, 4]),
    (100, 26, 4, list(range(0, 101, 4))),
    (10, 4, 4, [0, 4, 8, 10]),  # the last step is always shown
])
def test_frame_steps(steps, max_frames, stride, shown):
    got, got_stride = frame_steps(steps, max_frames)
    assert got_stride == stride and got.tolist() == shown


def _frames(path: Path) -> tuple[list[np.ndarray], list[int]]:
    frames, durations = [], []
    with Image.open(path) as im:
        for k in range(im.n_frames):
            im.seek(k)
            durations.append(im.info["duration"])
            frames.append(np.asarray(im.convert("RGB"), dtype=np.int16))
    return frames, durations


def _interpolated(robot, targets):
    tasks = line_tasks(robot, targets)
    return tasks, {t.name: np.linspace(t.required.start_pose, t.required.end_pose, t.goal.steps + 1)
                   for t in tasks}


def test_nicos_seven_trajectories_play_at_real_speed_in_a_small_gif(tmp_path):
    robot = ikbench.load_robot()
    tasks, poses = _interpolated(robot, ikbench.load_targets(None, robot))  # n = 50
    gif = write_animation(tmp_path / "a.gif", robot, tasks, poses, "seven", 2.0)
    assert gif.stat().st_size < 1.5e6
    frames, durations = _frames(gif)
    assert len(frames) == 26  # every second step of 50
    assert durations[1:-1] == [80] * 24  # 2 steps of 2 s / 50: real speed
    assert durations[0] == 580 and durations[-1] == 1080  # held at the start and the touch
    dark = [(f.max(axis=-1) < 90).sum() for f in frames]
    assert min(dark) > 1000  # seven arms, ticks and titles in every frame
    moved = np.abs(frames[0] - frames[-1]).max(axis=-1) > 60
    assert moved.sum() > 2000  # the arms moved, the fingertip paths were drawn


def test_a_robot_without_config_and_a_letter_are_animated(tmp_path):
    arm = ikbench.load_robot(DATA / "unaligned_arm.urdf", "tool")
    tasks, poses = _interpolated(arm, ikbench.load_targets(DATA / "unaligned_arm.targets.json",
                                                           arm))
    frames, durations = _frames(write_animation(tmp_path / "a.gif", arm, tasks, poses, "", 2.0))
    assert len(frames) == 21 and durations[1] == 100  # n = 20, 2 s: 0.1 s per step
    robot = ikbench.load_robot()
    start = np.array([0.0, 45.0, 0.0, 90.0, 180.0, 180.0, -145.0])
    task = letter_task(robot, "L", start, steps=8)
    frames, _ = _frames(write_animation(tmp_path / "l.gif", robot, [task],
                                        {"L": np.repeat(start[None], 9, axis=0)}, "L", 1.0))
    assert len(frames) == 9


def test_the_run_folder_links_it_and_no_animation_skips_it(tmp_path, monkeypatch):
    register_temporarily(monkeypatch, Straight)
    ikbench.run("straight", only="1", steps=4, output=tmp_path, progress=False)
    folder = tmp_path / "straight"
    assert "animation.gif" in json.loads((folder / "run.json").read_text())["files"]
    assert "![animation: the arm playing each trajectory](animation.gif)" in (
        folder / "report.md").read_text()
    assert len(_frames(folder / "animation.gif")[0]) == 5
    assert main(["run", "--method", "straight", "--only", "1", "--steps", "4", "--output",
                 str(tmp_path), "--quiet", "--no-animation"]) == 0
    assert not (folder / "animation.gif").exists()  # the rerun removed what it did not write
    assert "animation" not in (folder / "report.md").read_text()
    assert "animation.gif" not in json.loads((folder / "run.json").read_text())["files"]
    ikbench.run("straight", only="1", steps=4, output=tmp_path, progress=False,
                animation=False)
    assert not (folder / "animation.gif").exists()
