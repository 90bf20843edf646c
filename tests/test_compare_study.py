"""``ikbench compare``: one table for many methods, failures and missing libraries as rows."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

import ikbench
from ikbench.cli import main
from ikbench.core.contract import contract_for, judge
from ikbench.core.metrics import contract_metrics
from ikbench.core.task import line_tasks
from ikbench.core.trajectory import read_trajectory_poses
from ikbench.methods import registry
from ikbench.methods.base import Solution
from ikbench.methods.options import option
from ikbench.render.leaderboard import fmt
from ikbench.studies.compare import COLUMNS, CONTRACT_METRICS, compare
from tests.conftest import exit_code, interrupt_while, register_temporarily
from tests.test_run_folder import Straight


class Walker(Straight):
    """Starts anywhere (here: the touch pose held), like the authors' walk: keeps only the
    touch pose fixed."""

    name = "walker"
    description = "touch pose held (tests)"

    def fixed_poses(self):
        return frozenset({"touch_pose"})

    def solve(self, robot, task, progress=None) -> Solution:
        poses = np.repeat(task.required.end_pose[None], task.goal.steps + 1, axis=0)
        return Solution(poses, iterations=1, duration_s=0.0, loss=None)


def straight_variant(name: str, fail_on: str = "", interrupt_on: str = "") -> type:
    """A :class:`Straight` registered as ``name`` whose defaults fail or interrupt a
    trajectory (compare takes no method options on its command line)."""
    settings = dataclasses.make_dataclass(f"{name}Settings", [
        ("fail_on", str, option(fail_on, help="trajectory id whose solve raises")),
        ("interrupt_on", str, option(interrupt_on, help="trajectory id interrupted"))])
    return type(name, (Straight,), {"name": name, "Settings": settings})


FailsOn2 = straight_variant("fails-on-2", fail_on="2")
Interrupts = straight_variant("interrupts", interrupt_on="2")


@pytest.fixture
def methods(monkeypatch):
    for cls in (Straight, Walker, FailsOn2, Interrupts):
        register_temporarily(monkeypatch, cls)
    monkeypatch.setitem(registry.method_status(), "missing-lib", registry.MethodStatus(
        "missing-lib", None, "needs not_a_lib (pip install 'ikbench[libs]')"))


def test_compare_judges_every_method_by_the_contract_from_the_csvs(tmp_path, robot,
                                                                    paper_targets, methods):
    result = compare(["ours-lm", "straight", "walker", "missing-lib"], only="1,3", steps=6,
                     repeat=2, output=tmp_path, progress=False)
    root = tmp_path / "compare"
    results = pd.read_csv(root / "results.csv", dtype={"trajectory": str})
    assert list(results.columns) == COLUMNS
    assert len(results) == 8 and set(results["method"]) == {"ours-lm", "straight", "walker",
                                                              "missing-lib"}
    missing = results[results["method"] == "missing-lib"]
    assert (missing["status"] == "not installed").all() and not missing["success"].any()
    assert missing["failure"].str.contains("not_a_lib").all()
    contract = contract_for(robot)
    touch = contract.with_track("touch")
    tasks = {t.name: t for t in line_tasks(robot, paper_targets.select("1,3").with_steps(6),
                                           contract)}
    measured = results[results["status"] != "not installed"]
    assert len(measured) == 6
    for _, row in measured.iterrows():
        poses = read_trajectory_poses(root / row["method"] / f"trajectory_{row['trajectory']}"
                                      ".csv", robot)
        figures = contract_metrics(robot, tasks[row["trajectory"]], poses, contract)
        for column in [*CONTRACT_METRICS, "line_distance_mean_mm", "start_pose_error_deg",
                       "end_pose_error_deg", "max_joint_step_deg"]:
            assert row[column] == pytest.approx(figures[column], nan_ok=True), column
        assert row["repetitions"] == 2
        assert row["time_min_s"] <= row["time_median_s"] <= row["time_max_s"]
        # success, recomputed here: honours the fixed poses and every criterion holds
        honours = row["method"] != "walker"
        expected = honours and all(judge(contract, figures).values())
        assert bool(row["success"]) == expected
        assert bool(row["success_touch"]) == all(judge(touch, figures).values())
        assert (row["start_pose_error_deg"] <= 0.5 and row["end_pose_error_deg"] <= 0.5
                and row["speed_limit_use"] <= 1) or not row["success"]
    walker = results[results["method"] == "walker"]
    assert (walker["status"] == "does not honour: start pose").all()
    assert not walker["success"].any() and (walker["fixed_poses"] == "touch_pose").all()
    straight = results[results["method"] == "straight"]
    assert (straight["line_distance_max_mm"] > 5).all() and not straight["success"].any()
    assert (straight["ok_line"] == False).all()  # noqa: E712 - a column per criterion
    ours = results[results["method"] == "ours-lm"]
    assert ours["time_batched_s"].notna().all() and straight["time_batched_s"].isna().all()
    board = result.leaderboard.set_index(["track", "method"])
    assert set(result.leaderboard["track"]) == {"paper", "touch"}
    assert board.loc[("paper", "ours-lm"), "time_vs_reference"] == pytest.approx(1.0)
    assert board.loc[("paper", "ours-lm"), "success_count"] == ours["success"].sum()
    assert board.loc[("touch", "walker"), "success_count"] == walker["success_touch"].sum()
    assert np.isnan(board.loc[("paper", "missing-lib"), "time_median_s"])
    text = (root / "leaderboard.md").read_text()
    assert "| missing-lib |" in text and "x ours-lm" in text
    assert "Track `paper`" in text and "Track `touch`" in text
    assert contract.describe(6, "motor deg") in text  # the contract above its table
    assert "does not honour: start pose" in text
    record = json.loads((root / "run.json").read_text())
    assert record["repeat"] == 2 and record["libraries"] == {"ikbench": ikbench.__version__}
    assert record["contract"]["tolerances"] == contract.to_dict()["tolerances"]
    assert (root / "pareto.png").stat().st_size > 0
    sweep = pd.read_csv(root / "pareto_sweep.csv")
    assert len(sweep) >= 5 and sweep["line_distance_max_median_mm"].is_monotonic_decreasing
    # the median of the per-trajectory maxima, and the largest of them (the leaderboard's)
    assert (sweep["line_distance_max_worst_mm"] >= sweep["line_distance_max_median_mm"]).all()
    ours_max = ours["line_distance_max_mm"].max()
    assert sweep.loc[sweep["c0"] == 1.0, "line_distance_max_worst_mm"].iloc[0] == \
        pytest.approx(ours_max, rel=1e-6)


def test_small_numbers_keep_their_digits():
    assert fmt(5.6e-05) == "5.60e-05" and fmt(0.0) == "0" and fmt(146.6) == "147"
    assert fmt(float("nan")) == "" and fmt(3.14159) == "3.14"


def test_a_failing_method_is_a_row_not_a_crash(tmp_path, methods):
    result = compare(["straight", "ours-lm"], only="1,2", steps=4, repeat=1, output=None,
                     progress=False, solvers={"straight": Straight(fail_on="2")})
    rows = result.results.set_index(["method", "trajectory"])
    assert rows.loc[("straight", "2"), "status"] == "failed"
    assert rows.loc[("straight", "2"), "failure"] == "SolverError: no solution for 2"
    assert rows.loc[("straight", "1"), "status"] == "solved"


@pytest.mark.parametrize("args, message", [
    (["--methods", "ours-lm,nope"], "--methods: unknown method 'nope'; registered:"),
    (["--repeat", "0"], "--repeat: 0 is out of range; give a number of solves from 1 to 1000"),
    (["--only", "9"], "--only: unknown trajectory id(s) '9'"),
    (["--reference", "ikpy", "--only", "1", "--steps", "4", "--repeat", "1"],
     "--reference: 'ikpy' is not among --methods"),
])
def test_compare_cli_bad_input_one_line_exit_2(tmp_path, capsys, args, message):
    assert exit_code(["compare", "--output", str(tmp_path), "--quiet", *args]) == 2
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


def _cli(tmp_path, *args) -> int:
    return main(["compare", "--only", "1,2", "--steps", "4", "--repeat", "1", "--output",
                 str(tmp_path), "--quiet", *args])


def test_compare_exits_1_when_a_solve_fails(tmp_path, methods, capsys):
    assert _cli(tmp_path, "--methods", "straight") == 0
    assert _cli(tmp_path, "--methods", "straight,fails-on-2") == 1
    assert "fails-on-2" in capsys.readouterr().err
    results = pd.read_csv(tmp_path / "compare" / "results.csv", dtype={"trajectory": str})
    assert set(results.loc[results["method"] == "fails-on-2", "status"]) == {"solved", "failed"}


def test_compare_exits_1_when_a_method_does_not_honour_the_contract(tmp_path, methods, capsys):
    assert _cli(tmp_path, "--methods", "walker") == 1
    assert "contract is not honoured" in capsys.readouterr().err


def test_ctrl_c_is_one_line_exit_130_and_leaves_the_folder_unchanged(tmp_path, methods, capsys):
    assert _cli(tmp_path, "--methods", "straight") == 0
    before = (tmp_path / "compare" / "results.csv").read_bytes()
    capsys.readouterr()
    assert _cli(tmp_path, "--methods", "straight,interrupts") == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "interrupted" in err and "Traceback" not in err
    assert (tmp_path / "compare" / "results.csv").read_bytes() == before


def test_sigint_through_the_cli_process(tmp_path):
    """A real Ctrl-C (SIGINT) to ``ikbench compare`` while it solves: exit 130, one line."""
    code, err = interrupt_while(["compare", "--methods", "ours-lm", "--repeat", "1000",
                                 "--output", str(tmp_path)], tmp_path, "solving")
    assert code == 130
    assert err.strip().splitlines() == [
        f"ikbench: interrupted; {tmp_path / 'compare'}/ left unchanged"]
    assert not (tmp_path / "compare").exists()


class Broken(Straight):
    """A method with a bug in check_tasks (not a refusal of the input)."""

    name = "broken"

    def check_tasks(self, robot, tasks) -> None:
        raise RuntimeError("a bug")


def test_a_bug_is_a_failed_row_not_refused_nor_unavailable(tmp_path, monkeypatch):
    register_temporarily(monkeypatch, Broken)
    result = compare(["broken"], only="1", steps=4, repeat=1, output=None, progress=False)
    row = result.results.iloc[0]
    assert row["status"] == "failed" and row["failure"] == "RuntimeError: a bug"
    assert result.failed and not row["success"]


def test_first_call_is_a_leaderboard_column_of_every_method_only_when_asked(tmp_path):
    """--first-call: leaderboard.csv's first_call_s (a fresh process: import, set-up, the
    first trajectory solved once) is finite and positive for each method, leaderboard.md
    says what it measures and `ikbench render`-style re-rendering keeps it; without the option
    the column is absent."""
    from ikbench.render.leaderboard import render

    common = ["compare", "--only", "1", "--steps", "4", "--repeat", "1", "--methods",
              "ours-lm,sequential-ik", "--quiet"]
    assert main([*common, "--output", str(tmp_path / "on"), "--first-call"]) == 0
    folder = tmp_path / "on" / "compare"
    board = pd.read_csv(folder / "leaderboard.csv")
    assert set(board["method"]) == {"ours-lm", "sequential-ik"}
    assert np.isfinite(board["first_call_s"]).all() and (board["first_call_s"] > 0).all()
    text = (folder / "leaderboard.md").read_text()
    assert "first call [s]" in text and "fresh Python process" in text and "set-up" in text
    render(folder)
    assert pd.read_csv(folder / "leaderboard.csv")["first_call_s"].equals(board["first_call_s"])
    assert main([*common, "--output", str(tmp_path / "off")]) == 0
    off = tmp_path / "off" / "compare"
    assert "first_call_s" not in pd.read_csv(off / "leaderboard.csv")
    assert "first call [s]" not in (off / "leaderboard.md").read_text()
