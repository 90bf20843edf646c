"""A run folder is replaced whole or not at all; the harness keeps failures and Ctrl-C honest."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.errors import SolverError
from ikbench.methods.base import Method, Solution
from ikbench.methods.options import option
from tests.conftest import register_temporarily


@dataclass
class StraightSettings:
    fail_on: str = option("", help="trajectory id whose solve raises")
    interrupt_on: str = option("", help="trajectory id whose solve is interrupted (Ctrl-C)")


class Straight(Method):
    """Joint-space interpolation from start to touch pose; fails or interrupts on request."""

    name = "straight"
    description = "joint interpolation (tests)"
    Settings = StraightSettings

    def solve(self, robot, task, progress=None) -> Solution:
        if task.name == self.settings.fail_on:
            raise SolverError(f"no solution for {task.name}")
        if task.name == self.settings.interrupt_on:
            raise KeyboardInterrupt
        poses = np.linspace(task.required.start_pose, task.required.end_pose, task.goal.steps + 1)
        return Solution(poses, iterations=1, duration_s=0.0, loss=None)


@pytest.fixture
def straight(monkeypatch):
    register_temporarily(monkeypatch, Straight)


def _run(out, *args):
    return main(["run", "--method", "straight", "--steps", "4", "--output", str(out), "--quiet",
                 "--no-animation", *args])


def test_rerun_removes_only_what_the_last_run_wrote(tmp_path, straight, capsys):
    assert _run(tmp_path, "--only", "1,2") == 0
    folder = tmp_path / "straight"
    assert main(["plan", str(folder / "trajectory_1.csv")]) == 0
    (folder / "notes.txt").write_text("mine")
    assert _run(tmp_path, "--only", "2") == 0
    names = sorted(p.name for p in folder.iterdir())
    assert "trajectory_1.plan.csv" in names and "notes.txt" in names  # not written by a run
    assert "trajectory_1.csv" not in names and "trajectory_2.csv" in names
    record = json.loads((folder / "run.json").read_text())
    assert record["trajectories"] == ["2"] and "trajectory_2.csv" in record["files"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp folders


def test_a_failed_solve_is_a_row_and_the_others_are_written(tmp_path, straight, capsys):
    assert _run(tmp_path, "--only", "1,2,3", "--fail-on", "2") == 1
    err = capsys.readouterr().err
    assert "1 of 3 solves failed (2)" in err
    folder = tmp_path / "straight"
    table = pd.read_csv(folder / "table.csv", dtype={"trajectory": str})
    assert table["line_distance_mean_mm"].isna().tolist() == [False, True, False]
    details = pd.read_csv(folder / "details.csv", dtype={"trajectory": str, "failure": str})
    details = details.fillna({"failure": ""})
    assert details["failure"].tolist() == ["", "SolverError: no solution for 2", ""]
    assert sorted(p.name for p in folder.glob("trajectory_*.csv")) == [
        "trajectory_1.csv", "trajectory_3.csv"]
    assert "**Failed solves**: 2" in (folder / "report.md").read_text()


def test_ctrl_c_while_solving_keeps_the_complete_run_and_the_solved_trajectories_beside_it(
        tmp_path, straight, capsys):
    """Issue 49: an interrupted run never replaces a complete one; what it solved goes to
    ``<name>.interrupted/``, and the message says where."""
    assert _run(tmp_path, "--only", "1,2,3") == 0
    folder = tmp_path / "straight"
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert _run(tmp_path, "--only", "1,2,3", "--interrupt-on", "3") == 130
    beside = tmp_path / "straight.interrupted"
    assert (f"{folder}/ is unchanged; the 2 trajectories solved before Ctrl-C are in "
            f"{beside}/") in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before  # the complete run
    record = json.loads((beside / "run.json").read_text())
    assert record["interrupted"] is True and record["trajectories"] == ["1", "2"]
    assert sorted(p.name for p in beside.glob("trajectory_*.csv")) == [
        "trajectory_1.csv", "trajectory_2.csv"]
    assert "Interrupted (Ctrl-C)" in (beside / "report.md").read_text()


def test_a_second_interrupted_run_replaces_the_first_and_says_so(tmp_path, straight, capsys):
    """Issue 64: the second interrupt's folder replaces the first's whole, as docs/commands.md
    says, and its line says it replaced one."""
    assert _run(tmp_path, "--only", "1,2,3", "--interrupt-on", "3") == 130
    beside = tmp_path / "straight.interrupted"
    assert "(replacing" not in capsys.readouterr().err
    assert _run(tmp_path, "--only", "1,2,3", "--interrupt-on", "2") == 130
    assert (f"the 1 trajectories solved before Ctrl-C are in {beside}/ (replacing an earlier "
            "interrupted run's)") in capsys.readouterr().err
    assert json.loads((beside / "run.json").read_text())["trajectories"] == ["1"]
    assert [p.name for p in beside.glob("trajectory_*.csv")] == ["trajectory_1.csv"]


def test_ctrl_c_before_any_solve_leaves_the_folder_unchanged(tmp_path, straight, capsys):
    assert _run(tmp_path, "--only", "1,2") == 0
    folder = tmp_path / "straight"
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert _run(tmp_path, "--only", "1,2", "--interrupt-on", "1") == 130
    assert "is unchanged" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_ctrl_c_while_writing_leaves_the_old_folder_whole(tmp_path, straight, monkeypatch):
    assert _run(tmp_path, "--only", "1,2") == 0
    folder = tmp_path / "straight"
    before = {p.name: p.read_bytes() for p in folder.iterdir()}

    import ikbench.studies.run as run_module

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "method_report", interrupted)  # the last file written
    assert _run(tmp_path, "--only", "3") == 130
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_options_of_another_method_are_refused(tmp_path, straight, capsys):
    assert _run(tmp_path, "--lm-damping", "0.1") == 2
    assert capsys.readouterr().err == (
        "ikbench: error: --lm-damping is an option of --method ours-lm, not of --method "
        "straight\n")
