"""ikbench sweep: grid parsing, one batched solve per grid, Pareto flags, files, CLI errors."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.losses import PAPER_WEIGHTS, objective, parse_weights
from ikbench.core.targets import load_targets
from ikbench.core.task import line_tasks
from ikbench.methods.ours_lm import solve_batch
from ikbench.studies.sweep import grid_settings, parse_grid, summarise, sweep, write
from tests.conftest import fails_if_called, unwritable_output_error


def test_parse_grid_and_settings():
    grid = parse_grid(["c0=2,10", "L1=5,50,5"])
    assert grid == {"L0": [2.0, 10.0], "L1": [5.0, 50.0]}
    settings = grid_settings(grid)
    assert settings[0] == PAPER_WEIGHTS          # the paper's setting comes first
    assert {(s["L0"], s["L1"]) for s in settings[1:]} == {(2, 5), (2, 50), (10, 5), (10, 50)}
    assert len(settings) == 5 and all(s["L5"] == 200 for s in settings)
    # a grid that contains the paper's setting lists it once
    assert len(grid_settings(parse_grid(["c0=1,10"]))) == 2


@pytest.mark.parametrize("bad", [["c0"], ["c0="], ["c9=1"], ["c0=1,x"], ["c0=-1"],
                                 ["c0=1", "L0=2"], []])
def test_parse_grid_rejects(bad):
    with pytest.raises(InputError, match="--weight"):
        parse_grid(bad)


def test_pareto_flags():
    frame = pd.DataFrame({
        "setting": ["a", "b", "c", "d"], "trajectory": "1", "paper_weights": [True] + [False] * 3,
        **{f"c{k}": 1.0 for k in range(7)},
        "line_distance_mean_mm": [3.0, 1.0, 2.0, 0.5], "pointing_deviation_mean_deg": [
            10.0, 12.0, 13.0, 20.0],
        **{c: 0.0 for c in ("mean_sq_joint_step_deg2", "loss", "paper_loss", "iterations",
                            "line_distance_std_mm", "start_point_error_mm",
                            "end_point_error_mm", "end_pose_error_deg",
                            "max_joint_step_deg")},
        "converged": True, "within_limits": True})
    table = summarise(frame).set_index("setting")
    assert table["pareto"].to_dict() == {"a": True, "b": True, "c": False, "d": True}


def test_sweep_matches_separate_solves_and_writes(tmp_path, robot):
    result = sweep({"L0": [1.0, 100.0]}, only="1,3", steps=8, progress=False)
    table = result.settings.set_index("setting")
    assert list(table.index) == ["c0=1", "c0=100"]
    assert bool(table.loc["c0=1", "paper_weights"])
    # a larger line weight pulls the fingertip closer to the line
    assert table.loc["c0=100", "line_distance_mean_mm"] < table.loc["c0=1",
                                                                    "line_distance_mean_mm"]
    tasks = line_tasks(robot, load_targets().select("1,3").with_steps(8))
    alone = solve_batch(robot, tasks, weights=parse_weights("c0=100"))
    rows = result.trajectories[result.trajectories["setting"] == "c0=100"]
    np.testing.assert_allclose(rows["loss"], alone.loss, rtol=1e-9)
    paper_rows = result.trajectories[result.trajectories["paper_weights"]]
    for _, row in paper_rows.iterrows():
        assert row["paper_loss"] == pytest.approx(row["loss"], rel=1e-12)
    assert objective(robot, tasks[0], alone.poses[0])[0] == pytest.approx(
        rows.iloc[0]["paper_loss"], rel=1e-9)
    write(result, tmp_path)
    for name in ("sweep.csv", "sweep_trajectories.csv", "pareto.png", "sweep.json", "sweep.md"):
        assert (tmp_path / name).stat().st_size > 0
    assert "## Findings" in (tmp_path / "sweep.md").read_text()


def test_sweep_cli(tmp_path, capsys):
    code = main(["sweep", "--weight", "c0=1,10", "--weight", "c6=1,5", "--only", "2",
                 "--steps", "6", "--output", str(tmp_path), "--quiet"])
    assert code == 0
    assert "written to" in capsys.readouterr().out
    assert len(pd.read_csv(tmp_path / "sweep.csv")) == 4


@pytest.mark.parametrize("args, message", [
    (["--weight", "c0=1", "--shape", "letter:P", "--only", "1"],
     "ikbench: error: --only selects touch poses of the line shape"),
    (["--weight", "c0=1", "--shape", "letter:P", "--start-pose", "1,2"],
     "ikbench: error: --start-pose: expected 7 angles"),
    (["--weight", "c0=1", "--size", "100"], "ikbench: error: --size: only letters are scaled"),
    (["--weight", "c0=0", "--weight", "c1=0", "--weight", "c6=0", "--shape", "letter:P"],
     "ikbench: error: --weight: the setting 'c0=0,c1=0,c6=0' and the other terms (c2, c3, c4, "
     "c5) are 0: every weight is 0"),
    (["--weight", "c0=0,1", "--weight", "c1=0", "--weight", "c2=0", "--weight", "c3=0",
      "--weight", "c4=0", "--weight", "c5=0", "--weight", "c6=0"],
     "ikbench: error: --weight: the setting 'c0=0,c1=0,c2=0,c3=0,c4=0,c5=0,c6=0': every "
     "weight is 0 and the loss would be empty"),
    (["--weight", "c0=0", "--weight", "c1=0", "--weight", "c6=0", "--weight", "c2=1",
      "--shape", "letter:P"],
     "ikbench: error: --weight: the setting 'c0=0,c1=0,c6=0,c2=1' weights only the start/end "
     "pose terms c2, c3, which shape 'letter:P' does not pin"),
])
def test_sweep_cli_bad_shape_input_one_line_exit_2(tmp_path, args, message):
    exe = [sys.executable, "-m", "ikbench.cli", "sweep", "--output", str(tmp_path / "out"),
           "--quiet", *args]
    proc = subprocess.run(exe, capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith(message)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args, message", [
    (["--weight", "c0:1,10"], "ikbench: error: --weight: 'c0:1,10' is not term=v1,v2,..."),
    (["--weight", "c0=1", "--only", "x"], "ikbench: error: --only: unknown trajectory id"),
    ([], "ikbench: error: --weight: give at least one term"),
])
def test_sweep_cli_bad_input_one_line_exit_2(tmp_path, args, message):
    exe = [sys.executable, "-m", "ikbench.cli", "sweep", "--output", str(tmp_path), *args]
    proc = subprocess.run(exe, capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith(message)


def test_sweep_on_a_letter_uses_the_letter_setting_and_equals_ours_lm(tmp_path, robot):
    from ikbench.core.letters import LETTER_WEIGHTS, PAPER_START_POSE_DEG
    from ikbench.core.task import letter_task
    from ikbench.methods.ours_lm import OursLM

    result = sweep(parse_grid(["c0=1,100"]), shape="letter:P", steps=16, progress=False)
    table = result.settings.set_index("setting")
    assert list(table.index) == ["c0=1", "c0=100"]
    assert bool(table.loc["c0=1", "paper_weights"]) and not table.loc["c0=100", "paper_weights"]
    assert (table[["c2", "c3", "c4", "c5"]] == 0).all().all() and (table["c1"] == 50).all()
    assert table.loc["c0=100", "point_error_mean_mm"] < 0.2 * table.loc[
        "c0=1", "point_error_mean_mm"]
    assert result.record["start_pose_deg"] == list(PAPER_START_POSE_DEG)
    assert result.record["reference_weights"] == {f"c{k}": LETTER_WEIGHTS[f"L{k}"]
                                                  for k in range(7)}
    # each setting is what ours-lm --weights gives on the letter task
    task = letter_task(robot, "P", PAPER_START_POSE_DEG, steps=16)
    rows = result.trajectories.set_index("setting")
    for label in ("c0=1", "c0=100"):
        solution = OursLM(weights=label).solve(robot, task)
        assert rows.loc[label, "loss"] == pytest.approx(solution.loss, rel=1e-9)
        assert rows.loc[label, "paper_loss"] == pytest.approx(
            objective(robot, task, solution.poses, LETTER_WEIGHTS)[0], rel=1e-9)
    write(result, tmp_path)
    md = (tmp_path / "sweep.md").read_text()
    assert "shape `letter:P`" in md and "the paper's letter setting" in md
    assert "## Pareto-optimal settings (point error vs pointing deviation)" in md
    assert pd.read_csv(tmp_path / "sweep.csv")["point_error_max_mm"].notna().all()


def test_sweep_start_pose_moves_the_letter(robot):
    pose = [10, 50, 10, 100, 170, 170, -140]
    result = sweep(parse_grid(["c0=1"]), shape="letter:I", steps=6, size_mm=100,
                   start_pose=pose, progress=False)
    assert result.record["start_pose_deg"] == pose and result.record["size_mm"] == 100


def test_grid_settings_reject_a_setting_with_every_weight_zero():
    from ikbench.core.letters import LETTER_WEIGHTS

    grid = parse_grid(["c0=0,1", "c1=0", "c6=0"])
    with pytest.raises(InputError, match="'c0=0,c1=0,c6=0' and the other terms"):
        grid_settings(grid, LETTER_WEIGHTS)
    assert len(grid_settings(grid, PAPER_WEIGHTS)) == 3   # c2..c5 still weigh something


def test_sweep_cli_checks_the_output_before_solving(tmp_path, capsys, monkeypatch):
    import ikbench.studies.sweep

    fails_if_called(monkeypatch, ikbench.studies.sweep, "sweep")
    err = unwritable_output_error(capsys, tmp_path, ["sweep", "--weight", "c0=1", "--quiet"])
    assert "cannot write" in err
