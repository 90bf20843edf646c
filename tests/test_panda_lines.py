"""The Panda's lines (urdf/panda_lines.targets.json): written by urdf/generate_panda_lines.py
(seeded, reproduced here), every line kept by the Panda's workspace filter and reachable; and
docs/comparison.md's Panda table generated from the committed leaderboard."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ikbench import load_robot, load_targets
from ikbench.render.leaderboard import PANDA_MARKERS, readme_table, write_readme_table
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
    poses = np.stack(list(targets.touch_poses_deg.values()))
    assert robot.within_limits(poses) and robot.within_limits(targets.start_pose_deg[None])
    assert np.abs(poses - targets.start_pose_deg).max() <= module.REACH_DEG
    fk = robot.fk(poses)
    start_mm = robot.fk(targets.start_pose_deg).point_mm[0]
    assert WorkspaceFilter.of(robot).accept(fk.point_mm, fk.direction, start_mm).all()
    assert all(module.reachable(robot, targets.start_pose_deg, pose) for pose in poses)


def test_docs_panda_table_is_generated_from_the_committed_leaderboard(tmp_path):
    """docs/comparison.md's Panda table equals :func:`readme_table` of the committed
    results/panda/compare/leaderboard.csv, and its documented command writes it."""
    if not BOARD.is_file():
        pytest.skip("results/panda/compare/ is not committed yet (ikbench compare --robot "
                    "panda --targets urdf/panda_lines.targets.json --output results/panda)")
    text = DOC.read_text(encoding="utf-8")
    start, end = PANDA_MARKERS
    block = text[text.index(start) + len(start):text.index(end)].strip()
    assert block == readme_table(pd.read_csv(BOARD))
    stale = re.sub(f"{re.escape(start)}.*{re.escape(end)}", f"{start}\n| stale |\n{end}", text,
                   flags=re.S)
    (tmp_path / "comparison.md").write_text(stale, encoding="utf-8")
    write_readme_table(tmp_path / "comparison.md", BOARD, PANDA_MARKERS)
    assert (tmp_path / "comparison.md").read_text(encoding="utf-8") == text
