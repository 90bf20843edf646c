"""ikbench batch: reproducible sampling in the front workspace, batched solve, report, CLI."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.studies.batch import WorkspaceFilter, run_batch, sample_touch_poses, write
from tests.conftest import PAPER_START, fails_if_called, unwritable_output_error


def test_sampling_is_seeded_within_ranges_and_in_the_workspace(robot):
    poses, draws = sample_touch_poses(robot, PAPER_START, 25, seed=3)
    again, _ = sample_touch_poses(robot, PAPER_START, 25, seed=3)
    other, _ = sample_touch_poses(robot, PAPER_START, 25, seed=4)
    np.testing.assert_array_equal(poses, again)
    assert not np.allclose(poses, other)
    assert poses.shape == (25, 7) and draws >= 25 and robot.within_limits(poses)
    fk = robot.fk(poses)
    start = robot.fk(PAPER_START).point_mm[0]
    f = WorkspaceFilter.of(robot)
    assert (f.max_x_mm, f.min_z_mm, f.min_drop_below_start_mm, f.max_pointing_angle_deg) == (
        -250.0, 0.0, 100.0, 20.0)  # the front workspace of NICO's config
    assert np.all(fk.point_mm[:, 0] <= f.max_x_mm)
    assert np.all(fk.point_mm[:, 2] >= f.min_z_mm)
    assert np.all(fk.point_mm[:, 2] <= start[2] - f.min_drop_below_start_mm)
    line = fk.point_mm - start
    cos = np.sum(line * fk.direction, axis=1) / np.linalg.norm(line, axis=1)
    assert np.all(np.degrees(np.arccos(cos)) <= f.max_pointing_angle_deg + 1e-9)
    # the paper's touch poses pass the filter
    touch = np.array([[33, 39, 25, 134, 102, 77, -168], [34, 17, 39, 107, 106, 78, -180]])
    paper = robot.fk(touch)
    assert f.accept(paper.point_mm, paper.direction, start).all()


def test_run_batch_report_and_files(tmp_path):
    report = run_batch(6, seed=1, steps=8, weights=["paper", "c0=100"], progress=False)
    s = report.summary.set_index("setting")
    assert list(s.index) == ["paper", "c0=100"]
    assert s.loc["paper", "c1"] == 50 and s.loc["c0=100", "c0"] == 100
    assert (s["trajectories_per_s"] > 0).all() and (s["share_within_limits"] == 1).all()
    assert s.loc["c0=100", "line_distance_mean_mm_median"] < s.loc[
        "paper", "line_distance_mean_mm_median"]
    rows = report.trajectories
    assert len(rows) == 12
    within = (rows["line_distance_mean_mm"] < 1.0) & (rows["end_point_error_mm"] < 0.5)
    assert s.loc["paper", "share_within_tol"] == pytest.approx(
        within[rows["setting"] == "paper"].mean())
    write(report, tmp_path)
    for name in ("batch.csv", "batch_trajectories.csv", "touch_poses.csv", "batch.json",
                 "batch.md"):
        assert (tmp_path / name).stat().st_size > 0
    assert len(pd.read_csv(tmp_path / "touch_poses.csv")) == 6


def test_batch_cli(tmp_path, capsys):
    assert main(["batch", "--count", "4", "--steps", "6", "--weights", "paper",
                 "--output", str(tmp_path), "--quiet"]) == 0
    assert "written to" in capsys.readouterr().out
    assert pd.read_csv(tmp_path / "batch.csv")["trajectories"].tolist() == [4]


@pytest.mark.parametrize("args, message", [
    (["--count", "0"], "ikbench: error: argument --count: 0 is out of range; give a "
     "number of touch poses from 1 to 100,000"),
    (["--weights", "c0=abc"], "ikbench: error: --weights: 'c0=abc' is not term=value"),
    (["--line-tolerance-mm", "-1"], "ikbench: error: argument --line-tolerance-mm: -1 is "
     "out of range; give a tolerance [mm] more than 0 to 10,000"),
    (["--seed", "-1"], "ikbench: error: argument --seed: -1 is out of range; give a seed "
     "in [0, 2^63)"),
    (["--seed", str(2**63)], f"ikbench: error: argument --seed: {2**63} is out of range; "
     "give a seed in [0, 2^63)"),
])
def test_batch_cli_bad_input_one_line_exit_2(tmp_path, args, message):
    exe = [sys.executable, "-m", "ikbench.cli", "batch", "--count", "3", "--steps", "4",
           "--output", str(tmp_path), "--quiet", *args]
    proc = subprocess.run(exe, capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith(message)


def test_sampling_rejects_bad_count(robot):
    with pytest.raises(InputError, match="--count"):
        sample_touch_poses(robot, PAPER_START, 0)


@pytest.mark.parametrize("seed", [-1, 2**63, 1.5, True])
def test_bad_seeds_rejected_before_sampling(robot, seed):
    with pytest.raises(InputError, match=r"--seed: .* must be an integer in \[0, 2\^63\)"):
        sample_touch_poses(robot, PAPER_START, 2, seed=seed)
    with pytest.raises(InputError, match="--seed"):
        run_batch(2, seed=seed, steps=4, progress=False)


def test_batch_cli_checks_the_output_before_sampling(tmp_path, capsys, monkeypatch):
    import ikbench.studies.batch

    fails_if_called(monkeypatch, ikbench.studies.batch, "run_batch")
    err = unwritable_output_error(capsys, tmp_path, ["batch", "--count", "2", "--quiet"])
    assert "cannot write" in err
