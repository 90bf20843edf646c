"""The Panda's lines (urdf/panda_lines.targets.json): written by urdf/generate_panda_lines.py
(seeded, reproduced here), every line kept by the Panda's workspace filter and reachable; and
docs/comparison.md's Panda table generated from the committed leaderboard."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from ikbench import load_robot, load_targets
from ikbench.studies.batch import WorkspaceFilter

REPO = Path(__file__).resolve().parents[1]
FILE = REPO / "urdf" / "panda_lines.targets.json"
BOARD = REPO / "results" / "panda" / "compare" / "leaderboard.csv"
DOC = REPO / "docs" / "comparison.md"


def generator():
    spec = importlib.util.spec_from_file_location("generate_panda_lines",
                                                  REPO / "urdf" / "generate_panda_lines.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_generator_reproduces_the_committed_file():
    assert generator().panda_lines() == json.loads(FILE.read_text(encoding="utf-8"))


def test_every_line_is_in_the_workspace_near_the_start_pose_and_reachable():
    robot = load_robot("panda")
    targets = load_targets(FILE, robot)
    module = generator()
    assert len(targets.ids) == module.COUNT and targets.steps == module.STEPS
    poses = np.stack(list(targets.touch_poses.values()))
    assert robot.within_limits(poses) and robot.within_limits(targets.start_pose[None])
    assert np.abs(poses - targets.start_pose).max() <= module.REACH_DEG
    fk = robot.fk(poses)
    start_mm = robot.fk(targets.start_pose).point_mm[0]
    assert WorkspaceFilter.of(robot).accept(fk.point_mm, fk.direction, start_mm).all()
    assert all(module.reachable(robot, targets.start_pose, pose) for pose in poses)


def test_docs_panda_table_is_a_generated_block_of_the_committed_leaderboard():
    """docs/comparison.md shows the Panda leaderboard as a generated block of the committed
    results/panda/compare/leaderboard.csv (tests/test_blocks.py checks it is current)."""
    from ikbench.render.blocks import blocks

    if not BOARD.is_file():
        pytest.skip("results/panda/compare/ is not committed yet (ikbench reproduce --all "
                    "--only compare-panda)")
    kinds = [(b.renderer, b.source) for b in blocks(DOC)]
    assert ("compare-table", "results/panda/compare/leaderboard.csv") in kinds
