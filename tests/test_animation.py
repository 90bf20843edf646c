"""The run folder's animation.gif: frames at the trajectory's real speed, the arm drawn,
linked from report.md, small, and skipped with --no-animation / animation=False."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import ikbench
from ikbench.cli import main
from ikbench.studies.animation import frame_steps
from tests.conftest import register_temporarily
from tests.test_run_folder import Straight

DATA = Path(__file__).parent / "data"


@pytest.fixture
def straight(monkeypatch):
    register_temporarily(monkeypatch, Straight)


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


def test_nico_run_folder_gets_one_small_animation_linked_from_the_report(tmp_path, straight):
    ikbench.run("straight", output=tmp_path, progress=False)  # all seven targets, n = 50
    folder = tmp_path / "straight"
    gif = folder / "animation.gif"
    assert gif.stat().st_size < 1.5e6
    record = json.loads((folder / "run.json").read_text())
    assert "animation.gif" in record["files"]
    assert "![animation: the arm playing each trajectory](animation.gif)" in (
        folder / "report.md").read_text()
    frames, durations = _frames(gif)
    assert len(frames) == 26  # every second step of 50
    assert durations[1:-1] == [80] * 24  # 2 steps of 2 s / 50: real speed
    assert durations[0] == 580 and durations[-1] == 1080  # held at the start and the touch
    dark = [(f.max(axis=-1) < 90).sum() for f in frames]
    assert min(dark) > 1000  # seven arms, ticks and titles in every frame
    moved = np.abs(frames[0] - frames[-1]).max(axis=-1) > 60
    assert moved.sum() > 2000  # the arms moved, the fingertip paths were drawn


def test_a_robot_without_config_and_a_letter_run_are_animated(tmp_path):
    arm = ikbench.load_robot(DATA / "unaligned_arm.urdf", "tool")
    ikbench.run("ours-lm", robot=arm, targets=DATA / "unaligned_arm.targets.json",
                output=tmp_path, progress=False)
    frames, durations = _frames(tmp_path / "ours-lm" / "animation.gif")
    assert len(frames) == 21 and durations[1] == 100  # n = 20, 2 s: 0.1 s per step
    ikbench.run("ours-lm", shape="letter:L", steps=8, output=tmp_path, name="letter",
                progress=False)
    frames, _ = _frames(tmp_path / "letter" / "animation.gif")
    assert len(frames) == 9


def test_no_animation_on_the_command_line_and_in_the_api(tmp_path, straight):
    assert main(["run", "--method", "straight", "--only", "1", "--steps", "4", "--output",
                 str(tmp_path), "--quiet", "--no-animation"]) == 0
    folder = tmp_path / "straight"
    assert not (folder / "animation.gif").exists()
    assert "animation" not in (folder / "report.md").read_text()
    assert "animation.gif" not in json.loads((folder / "run.json").read_text())["files"]
    ikbench.run("straight", only="1", steps=4, output=tmp_path, progress=False)
    assert (folder / "animation.gif").exists()
    ikbench.run("straight", only="1", steps=4, output=tmp_path, progress=False,
                animation=False)
    assert not (folder / "animation.gif").exists()  # the rerun removed what it did not write
