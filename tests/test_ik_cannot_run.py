"""A method that cannot take the robot is "cannot run" in the ik tables and figures, never a
0 % success rate (issue 64)."""

from __future__ import annotations

import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.robot_packages import robots_folder

pytest.importorskip("eaik")
pytestmark = pytest.mark.skipif(robots_folder("example-robot-data") is None,
                                reason="example-robot-data is not installed")


def test_eaik_on_a_7_dof_arm_cannot_run(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["ik", "--robot", "example-robot-data:panda", "--count", "5",
                 "--methods", "eaik,sequential-ik", "--output", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "eaik: cannot run: ValueError: EAIK cannot solve this 7-joint chain" in printed
    folder = out / "ik" / "panda"
    summary = pd.read_csv(folder / "summary.csv")
    eaik = summary[summary["method"] == "eaik"].iloc[0]
    assert eaik["cannot_run"].startswith("ValueError: EAIK cannot solve")
    other = summary[summary["method"] == "sequential-ik"].iloc[0]
    assert pd.isna(other["cannot_run"]) or other["cannot_run"] == ""
    board = (folder / "leaderboard.md").read_text()
    rows = [line for line in board.splitlines() if line.startswith("| eaik")]
    assert rows and all("cannot run" in line and "0.00 %" not in line for line in rows)
