"""``ikbench compare``: one table for many methods, failures and missing libraries as rows."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.metrics import trajectory_metrics
from ikbench.core.task import line_tasks
from ikbench.core.trajectory import read_trajectory_poses
from ikbench.methods import registry
from ikbench.studies.compare import COLUMNS, TOLERANCES, compare
from tests.conftest import register_temporarily
from tests.test_run_folder import Straight


@pytest.fixture
def methods(monkeypatch):
    register_temporarily(monkeypatch, Straight)
    monkeypatch.setitem(registry.method_status(), "missing-lib", registry.MethodStatus(
        "missing-lib", None, "needs not_a_lib (pip install 'ikbench[libs]')"))


def test_compare_writes_one_row_per_method_and_trajectory(tmp_path, robot, paper_targets,
                                                          methods):
    result = compare(["ours-lm", "straight", "missing-lib"], only="1,3", steps=6, repeat=2,
                     output=tmp_path, progress=False)
    root = tmp_path / "compare"
    results = pd.read_csv(root / "results.csv", dtype={"trajectory": str})
    assert list(results.columns) == COLUMNS
    assert len(results) == 6 and set(results["method"]) == {"ours-lm", "straight",
                                                              "missing-lib"}
    missing = results[results["method"] == "missing-lib"]
    assert (missing["status"] == "unavailable").all() and not missing["success"].any()
    assert missing["failure"].str.contains("not_a_lib").all()
    # every figure is the metrics module's, recomputed from the CSVs written
    tasks = {t.name: t for t in line_tasks(robot, paper_targets.select("1,3").with_steps(6))}
    for _, row in results[results["status"] == "solved"].iterrows():
        poses = read_trajectory_poses(root / row["method"] / f"trajectory_{row['trajectory']}"
                                      ".csv", robot)
        metrics = trajectory_metrics(robot, tasks[row["trajectory"]], poses)
        assert row["line_distance_mean_mm"] == pytest.approx(metrics["line_distance_mean_mm"])
        assert row["repetitions"] == 2
        assert row["time_min_s"] <= row["time_median_s"] <= row["time_max_s"]
        expected = all(metrics[c] <= limit for c, limit in TOLERANCES.items())
        assert bool(row["success"]) == expected
    straight = results[results["method"] == "straight"]
    assert (straight["line_distance_mean_mm"] > 5).all() and not straight["success"].any()
    board = result.leaderboard.set_index("method")
    assert board.loc["ours-lm", "time_vs_reference"] == pytest.approx(1.0)
    assert board.loc["ours-lm", "success"] == results[results["method"] == "ours-lm"][
        "success"].mean()
    assert np.isnan(board.loc["missing-lib", "time_median_s"])
    text = (root / "leaderboard.md").read_text()
    assert "| missing-lib |" in text and "x ours-lm" in text
    record = json.loads((root / "run.json").read_text())
    assert record["repeat"] == 2 and record["libraries"] == {"ikbench": "0.2.0"}
    assert (root / "pareto.png").stat().st_size > 0


def test_a_failing_method_is_a_row_not_a_crash(tmp_path, methods):
    result = compare(["straight", "ours-lm"], only="1,2", steps=4, repeat=1, output=None,
                     progress=False, solvers={"straight": Straight(fail_on="2")})
    rows = result.results.set_index(["method", "trajectory"])
    assert rows.loc[("straight", "2"), "status"] == "failed"
    assert rows.loc[("straight", "2"), "failure"] == "SolverError: no solution for 2"
    assert rows.loc[("straight", "1"), "status"] == "solved"


@pytest.mark.parametrize("args, message", [
    (["--methods", "ours-lm,nope"], "--methods: unknown method(s) 'nope'; registered:"),
    (["--repeat", "0"], "--repeat: 0 must be an integer >= 1"),
    (["--only", "9"], "--only: unknown trajectory id(s) '9'"),
    (["--reference", "ikpy", "--only", "1", "--steps", "4", "--repeat", "1"],
     "--reference: 'ikpy' is not among --methods"),
])
def test_compare_cli_bad_input_one_line_exit_2(tmp_path, capsys, args, message):
    assert main(["compare", "--output", str(tmp_path), "--quiet", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert not (tmp_path / "compare").exists()


def test_compare_with_problems_runs_the_cartesian_benchmark(tmp_path, capsys):
    assert main(["compare", "--problems", "fetch_arm__rot_yz2", "--methods",
                 "ours-lm,sequential-ik", "--seeds", "1", "--output", str(tmp_path),
                 "--quiet"]) in (0, 1)
    table = pd.read_csv(tmp_path / "cartesian" / "table.csv")
    assert set(table["method"]) == {"ours-lm", "sequential-ik"}
    assert table.set_index("method").loc["ours-lm", "valid"]
    assert main(["compare", "--problems", "fetch_arm__rot_yz2", "--only", "1"]) == 2
    assert "do not apply to --problems" in capsys.readouterr().err
