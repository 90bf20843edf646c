"""``ikbench ik``: seeded targets, the protocol (one sequence of initial configurations for every
method, the budget, the attempts rule), the FK re-check of every success, stored solutions that
recompute, robots by package name (z1 included), bad input. Small counts; no timed assertions
(the budget is tested on a fake clock)."""

from __future__ import annotations

import json
import logging
import re
import subprocess
import sys
from pathlib import Path
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.robot import Robot, load_robot, shipped_robots
from ikbench.core.robot_packages import resolve_package_uri, robots_folder
from ikbench.methods.registry import MethodStatus, solver_status
from ikbench.schemes.chain import chain_of
from ikbench.schemes.single_pose import PoseOut, PoseSolver
from ikbench.studies.ik import (
    AUTO_ROWS,
    AttemptCheck,
    IKSettings,
    judge,
    recheck,
    restart,
    run_ik,
    sample_targets,
)

needs_erd = pytest.mark.skipif(robots_folder("example-robot-data") is None,
                               reason="needs example_robot_data")


def _solver(name: str) -> type[PoseSolver] | None:
    """The solver class of ``name``; None when its library is missing."""
    return solver_status()[name].cls


DETERMINISTIC = [n for n in ("ours-lm", "sequential-ik", "pink") if _solver(n) is not None]
#: Settings under which every deterministic method gives the same answers on any machine:
#: no wall-clock budget, a fixed number of attempts.
FIXED = dict(budget_ms=float("inf"), attempts=(8,))


def test_targets_are_seeded_reachable_and_within_the_limits():
    robot = load_robot("panda")
    a = sample_targets(robot, IKSettings(count=12, seed=3))
    b = sample_targets(robot, IKSettings(count=12, seed=3))
    c = sample_targets(robot, IKSettings(count=12, seed=4))
    assert np.array_equal(a.q_target, b.q_target) and np.array_equal(a.q_init, b.q_init)
    assert not np.allclose(a.q_target, c.q_target)
    assert robot.within_limits(a.q_target) and robot.within_limits(a.q_init)
    near = sample_targets(robot, IKSettings(count=12, seed=3, init="nearby", perturb_deg=5.0))
    assert np.abs(near.q_init - near.q_target).max() <= 5.0 + 1e-12


def test_each_targets_sequence_starts_at_its_initial_pose_is_seeded_and_a_prefix():
    robot = load_robot("panda")
    targets = sample_targets(robot, IKSettings(count=5, seed=3))
    long = targets.initials(2, 50)
    assert long.shape == (50, robot.dof) and np.array_equal(long[0], targets.q_init[2])
    assert np.array_equal(targets.initials(2, 7), long[:7])  # a prefix of any longer one
    other = sample_targets(robot, IKSettings(count=9, seed=3)).initials(2, 50)
    assert np.array_equal(other[1:], long[1:])  # the restarts do not depend on the count
    assert not np.allclose(targets.initials(3, 50)[1:], long[1:])  # each target its own
    assert robot.within_limits(long) and len(np.unique(long[:, 0])) == 50
    # the restarts are not the targets: no row is (near) a target configuration
    assert np.abs(long[1:, None] - targets.q_target[None]).max(axis=2).min() > 1.0


class _Recorder(PoseSolver):
    """Restarted by the study; records every initial configuration, never holds."""

    name, library = "recorder", "ikbench"
    seen: ClassVar[list] = []

    def solve(self, q_init, point_m, rotation) -> PoseOut:
        type(self).seen.append(np.array(q_init))
        return PoseOut(np.asarray(q_init) + 0.3, 2, False)


class _SelfRestarting(PoseSolver):
    """Restarts itself (pose units); records the rows and the budget it is given."""

    name, library = "self-restarting", "ikbench"
    restarts_itself, pose_units = True, True
    seen: ClassVar[list] = []

    def solve(self, q_init, point_m, rotation) -> PoseOut:
        return self.solve_within(q_init[None], point_m, rotation, float("inf"))

    def solve_within(self, initials, point_m, rotation, budget_s) -> PoseOut:
        type(self).seen.append((np.array(initials), budget_s))
        return PoseOut(initials[-1] + 10.0, 5, False, len(initials))


@pytest.fixture
def fakes(monkeypatch):
    monkeypatch.setitem(solver_status(), "recorder", MethodStatus("recorder", _Recorder))
    monkeypatch.setitem(solver_status(), "self-restarting",
                        MethodStatus("self-restarting", _SelfRestarting))
    monkeypatch.setattr(_Recorder, "seen", [])
    monkeypatch.setattr(_SelfRestarting, "seen", [])


@pytest.mark.parametrize("attempts, budget_ms", [(4, float("inf")), (1, 5.0)])
def test_every_method_gets_the_same_initial_configurations_and_the_budget(fakes, attempts,
                                                                          budget_ms):
    robot = load_robot("panda")
    settings = IKSettings(count=3, seed=2, budget_ms=budget_ms, attempts=(attempts,))
    result = run_ik(robot, settings, ["recorder", "self-restarting"], progress=False)
    targets = result.targets
    rows = [targets.initials(k, attempts) for k in range(3)]
    # the study restarted the recorder from every row in order, in URDF units ...
    assert len(_Recorder.seen) == 3 * attempts
    np.testing.assert_allclose(np.array(_Recorder.seen), robot.to_urdf(np.concatenate(rows)),
                               rtol=0, atol=1e-12)
    # ... and the self-restarting method got the same rows (pose units) and, under a
    # fixed-count rule, no wall-clock budget whatever --budget-ms says
    assert len(_SelfRestarting.seen) == 3
    for k, (initials, budget_s) in enumerate(_SelfRestarting.seen):
        assert np.array_equal(initials, rows[k]) and budget_s == float("inf")
    assert (result.table["budget_ms"] == float("inf")).all()
    table = result.table
    assert (table["attempts"] == attempts).all() and (table["attempts_rule"] == str(attempts)).all()
    recorder = table[table["method"] == "recorder"]
    assert (recorder["iterations"] == 2 * attempts).all()  # summed over the attempts


def test_auto_restarts_until_the_answer_holds():
    """``--attempts auto`` gives a target up to AUTO_ROWS rows and stops at the first answer
    the judge accepts (a method that is right from its second row on: two attempts)."""
    robot = load_robot("panda")
    targets = sample_targets(robot, IKSettings(count=2, seed=5))
    answers = iter([targets.q_target[0] + 5.0, targets.q_target[0]])  # wrong, then right

    def solve(q_init, point_m, rotation):
        return PoseOut(robot.to_urdf(next(answers)), 1, None)

    check = AttemptCheck(robot, IKSettings())
    starts = robot.to_urdf(targets.initials(0, AUTO_ROWS))
    out, _ = restart(solve, starts, targets.T_target[0], check, float("inf"))
    assert out.attempts == 2 and check(out.q, targets.T_target[0])


def test_restart_starts_no_attempt_once_the_budget_is_spent():
    """On a fake clock: attempts of 2 ms each against a 5 ms budget start at 0, 2 and 4 ms of
    solver time; the one started at 4 ms finishes (6 ms), no fourth starts. The check of each
    attempt (1 ms here) is neither timed nor counted against the budget."""
    now = [0.0]

    def solve(q_init, point_m, rotation):
        now[0] += 0.002
        return PoseOut(np.asarray(q_init), 1, False)

    def clock():
        return now[0]

    def never(q, T):
        now[0] += 0.001  # the judge's check: untimed
        return False

    out, spent_s = restart(solve, np.zeros((10, 3)), np.eye(4), never, 0.005, clock)
    assert out.attempts == 3 and out.iterations == 3 and spent_s == pytest.approx(0.006)
    assert now[0] == pytest.approx(0.008)  # two checks ran (the third attempt spent the budget)
    out, spent_s = restart(solve, np.zeros((2, 3)), np.eye(4), never, 1.0, clock)
    assert out.attempts == 2 and spent_s == pytest.approx(0.004)  # the rows ran out
    assert restart(solve, np.zeros((9, 3)), np.eye(4), never, 0.0019, clock)[0].attempts == 1


def test_attempts_1_is_one_descent_from_the_first_row_for_every_method():
    robot = load_robot("panda")
    names = [n for n in ("ours-lm", "sequential-ik", "rtb-lm") if _solver(n) is not None]
    settings = IKSettings(count=4, seed=6, attempts=(1,), budget_ms=float("inf"))
    result = run_ik(robot, settings, names, progress=False)
    assert (result.table["attempts"] == 1).all()
    targets = result.targets
    for name in names:
        solver = _solver(name)(robot, "pose", (1.0, 0.5), float("inf"))
        solver.prepare()
        rows = result.table[result.table["method"] == name]
        for k in range(4):
            start = targets.q_init[k] if solver.pose_units else robot.to_urdf(targets.q_init[k])
            T = targets.T_target[k]
            q = np.asarray(solver.solve(start, T[:3, 3], T[:3, :3]).q)
            q_urdf = robot.to_urdf(q) if solver.pose_units else q
            row = rows[rows["target"] == k]
            ok = judge(robot, T[None], robot.from_urdf(q_urdf)[None], settings)["success"][0]
            assert bool(row["success"].iloc[0]) == ok, (name, k)
            if ok:  # (rtb returns its next random start after a failed search)
                stored = row[[f"q{j}" for j in range(robot.dof)]].to_numpy()[0]
                np.testing.assert_allclose(stored, q_urdf, rtol=0, atol=1e-9, err_msg=name)


def test_the_attempt_check_agrees_with_the_judge():
    robot = load_robot("panda")
    settings = IKSettings(count=200, seed=7)
    targets = sample_targets(robot, settings)
    rng = np.random.default_rng(0)
    moved = targets.q_target + rng.normal(0, 1, (200, 1)) * rng.uniform(0, 0.2, (200, 7))
    moved[:5, 3] = robot.upper[3] + 0.01  # outside a limit
    moved[5] = np.nan
    verdict = judge(robot, targets.T_target, moved, settings)["success"]
    check = AttemptCheck(robot, settings)
    mine = np.array([check(robot.to_urdf(q), T) for q, T in zip(moved, targets.T_target)])
    assert np.array_equal(mine, verdict) and 20 < verdict.sum() < 190


def test_rerun_gives_the_same_targets_and_success_counts():
    robot = load_robot("panda")
    settings = IKSettings(count=10, seed=1, **FIXED)
    first = run_ik(robot, settings, DETERMINISTIC, progress=False)
    second = run_ik(robot, settings, DETERMINISTIC, progress=False)
    assert np.array_equal(first.targets.T_target, second.targets.T_target)
    counts = [r.table.groupby("method")["success"].sum() for r in (first, second)]
    assert counts[0].equals(counts[1]) and set(counts[0].index) == set(DETERMINISTIC)
    assert first.table.loc[first.table["method"] == "ours-lm", "success"].mean() >= 0.8


class _Liar(PoseSolver):
    """Claims success and returns the initial pose (a wrong answer)."""

    name, library = "liar", "ikbench"

    def solve(self, q_init, point_m, rotation) -> PoseOut:
        return PoseOut(np.asarray(q_init), 1, True)


def test_every_success_is_rechecked_by_fk_and_a_wrong_answer_is_rejected(monkeypatch):
    robot = load_robot("panda")
    settings = IKSettings(count=6, seed=2)
    targets = sample_targets(robot, settings)
    right = judge(robot, targets.T_target, targets.q_target, settings)
    assert right["success"].all() and np.nanmax(right["position_error_mm"]) < 1e-9
    wrong = judge(robot, targets.T_target, targets.q_init, settings)
    assert not wrong["success"].any()
    moved = targets.q_target.copy()
    moved[:, 0] += 1.0  # 1 deg at the base: centimetres at the tool
    assert not judge(robot, targets.T_target, moved, settings)["success"].any()
    outside = targets.q_target.copy()
    outside[:, 3] = robot.upper[3] + 1.0
    assert not judge(robot, targets.T_target, outside, settings)["within_limits"].any()

    monkeypatch.setitem(solver_status(), "liar", MethodStatus("liar", _Liar))
    table = run_ik(robot, IKSettings(count=6, seed=2, attempts=(2,)), ["liar"],
                   progress=False).table
    assert table["library_ok"].all() and not table["success"].any()
    assert (table["attempts"] == 2).all()  # its claim did not stop the restarts


class _Unbuildable(PoseSolver):
    """A library that cannot model the robot."""

    name, library = "unbuildable", "ikbench"

    def prepare(self) -> None:
        raise ValueError("no model for this robot")

    def solve(self, q_init, point_m, rotation) -> PoseOut:  # pragma: no cover - never set up
        raise AssertionError("solved without a model")


def test_a_library_that_cannot_be_set_up_gives_failed_rows(monkeypatch):
    monkeypatch.setitem(solver_status(), "unbuildable", MethodStatus("unbuildable", _Unbuildable))
    robot = load_robot("panda")
    table = run_ik(robot, IKSettings(count=4, seed=1, **FIXED), ["unbuildable", "ours-lm"],
                   progress=False).table
    bad = table[table["method"] == "unbuildable"]
    assert len(bad) == 4 and not bad["success"].any()
    assert (bad["failure"] == "prepare: ValueError: no model for this robot").all()
    assert table[table["method"] == "ours-lm"]["success"].all()


def _fk_recomputed(robot, table: pd.DataFrame, targets: pd.DataFrame, record: dict
                   ) -> np.ndarray:
    """Success of each row from its stored solution and the targets file, computed here: the
    numpy chain FK (not Pinocchio, which judged), the tolerances and limits of run.json."""
    columns = record["solution_columns"]
    assert [columns[f"q{j}"]["joint"] for j in range(robot.dof)] == list(robot.joint_names)
    q_urdf = table[[f"q{j}" for j in range(robot.dof)]].to_numpy(dtype=float)
    goal = targets.set_index("target").loc[table["target"]]
    point_mm = goal[["x_mm", "y_mm", "z_mm"]].to_numpy()
    R_goal = goal[[f"R{i}{j}" for i in range(3) for j in range(3)]].to_numpy().reshape(-1, 3, 3)
    finite = np.all(np.isfinite(q_urdf), axis=1)
    poses = robot.from_urdf(np.where(finite[:, None], q_urdf, 0.0))
    point_m, rotation, _, _ = robot.chain_kinematics().frames(poses, jacobian=False)
    position_mm = np.linalg.norm(point_m * 1000.0 - point_mm, axis=1)
    cos = (np.einsum("kij,kij->k", rotation, R_goal) - 1.0) / 2.0
    rotation_deg = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    s = record["settings"]
    inside = np.all((poses >= robot.lower - 1e-6) & (poses <= robot.upper + 1e-6), axis=1)
    return (finite & inside & (position_mm <= s["tolerance_mm"])
            & (rotation_deg <= s["tolerance_deg"]))


def test_the_cli_writes_the_folder_and_every_row_recomputes_from_its_solution(tmp_path):
    out = tmp_path / "out"
    names = DETERMINISTIC + [n for n in ("rtb-lm",) if _solver(n) is not None]
    assert main(["ik", "--robot", "panda", "--count", "6", "--seed", "1", "--methods",
                 ",".join(names), "--attempts", "auto,1", "--output", str(out),
                 "--quiet"]) == 0
    folder = out / "ik" / "panda"
    files = {p.name for p in folder.iterdir()}
    assert {"results.csv", "summary.csv", "targets.csv", "leaderboard.md", "run.json",
            "times.png", "success_vs_tolerance.png"} <= files
    table = pd.read_csv(folder / "results.csv")
    summary = pd.read_csv(folder / "summary.csv")
    for (rule, method), rows in table.groupby([table["attempts_rule"].astype(str), "method"]):
        row = summary[(summary["attempts_rule"].astype(str) == rule)
                      & (summary["method"] == method)]
        assert len(row) == 1
        assert row["success_pct"].iloc[0] == pytest.approx(100 * rows["success"].mean(),
                                                           abs=1e-4)
    assert set(table["method"]) == set(names) and len(table) == 2 * 6 * len(names)
    assert set(table["attempts_rule"].astype(str)) == {"auto", "1"}
    assert (table.loc[table["attempts_rule"].astype(str) == "1", "attempts"] == 1).all()
    record = json.loads((folder / "run.json").read_text())
    targets = (pd.read_parquet(folder / "targets.parquet")
               if (folder / "targets.parquet").exists() else pd.read_csv(folder / "targets.csv"))
    robot = load_robot("panda")
    recomputed = _fk_recomputed(robot, table, targets, record)
    assert np.array_equal(recomputed, table["success"].to_numpy(dtype=bool))
    assert recomputed.sum() >= 6  # some rows succeed, so the comparison means something
    settings = IKSettings(**{k: v for k, v in record["settings"].items()
                             if k not in ("attempts", "max_count")})
    T = sample_targets(robot, settings).T_target
    assert np.array_equal(recheck(robot, table, T, settings), recomputed)
    assert record["settings"]["count"] == 6 and record["provenance"]["cpu"]
    board = (folder / "leaderboard.md").read_text()
    assert "1 mm and 0.5 deg" in board and "**5 ms** of wall-clock time per target" in board
    assert "initial configurations" in board and "Single descents (`--attempts 1`)" in board
    assert "Budgeted, with restarts (`--attempts auto`)" in board
    assert "Published figures" in board and "PickNik" in board  # panda has published ones


def _cli_results(out: Path, *args: str) -> tuple[pd.DataFrame, str]:
    """``ikbench ik --robot panda ... --output out --quiet``: results.csv and leaderboard.md."""
    assert main(["ik", "--robot", "panda", "--seed", "1", *args, "--output", str(out),
                 "--quiet"]) == 0
    folder = out / "ik" / "panda"
    return (pd.read_csv(folder / "results.csv", dtype={"attempts_rule": str}),
            (folder / "leaderboard.md").read_text())


def test_the_same_deterministic_command_twice_gives_the_same_success_columns(tmp_path):
    names = DETERMINISTIC + [n for n in ("rtb-lm", "trac-ik") if _solver(n) is not None]
    args = ("--count", "30", "--attempts", "4", "--budget-ms", "5", "--methods", ",".join(names))
    first, board = _cli_results(tmp_path / "a", *args)
    second, _ = _cli_results(tmp_path / "b", *args)
    assert set(first["method"]) == set(names) and (first["run"] == 1).all()
    for method in names:
        if not _solver(method).deterministic:  # TRAC-IK keeps its timeout: not compared
            assert (first.loc[first["method"] == method, "budget_ms"] == 5.0).all()
            continue
        one, two = (t.loc[t["method"] == method, "success"].to_numpy(dtype=bool)
                    for t in (first, second))
        assert np.array_equal(one, two), method
        assert (first.loc[first["method"] == method, "budget_ms"] == float("inf")).all()
    assert first["success"].sum() >= 30  # rows succeed: the comparison means something
    assert "Deterministic, at most 4 attempts (`--attempts 4`)" in board
    assert "K = 4" in board and "no wall-clock budget" in board
    assert "## Ground truth\n\n**Silent failures**" in board  # the heading on its own line


def test_repeat_runs_the_auto_table_only_and_the_cells_show_the_spread(tmp_path):
    table, board = _cli_results(tmp_path, "--count", "4", "--attempts", "2,auto", "--repeat",
                                "2", "--methods", "ours-lm,sequential-ik")
    runs = table.groupby("attempts_rule")["run"].unique()
    assert sorted(runs["auto"]) == [1, 2] and list(runs["2"]) == [1]
    assert len(table) == 2 * 4 * (1 + 2) and table.columns[-1] == "run"
    auto = board.split("(`--attempts auto`)")[1]
    assert "median of 2 runs" in auto
    for method in ("ours-lm", "sequential-ik"):
        row = next(line for line in auto.splitlines() if line.startswith(f"| {method}"))
        assert re.search(r"\d+\.\d\d % \(\d+\.\d\d-\d+\.\d\d\)", row), row
    summary = pd.read_csv(tmp_path / "ik" / "panda" / "summary.csv",
                          dtype={"attempts_rule": str})
    assert list(summary.columns[-5:]) == ["runs", "success_pct_min", "success_pct_max",
                                          "time_median_ms_min", "time_median_ms_max"]
    assert set(summary.loc[summary["attempts_rule"] == "auto", "runs"]) == {2}


@pytest.mark.parametrize("args, message", [
    (["--count", "0"], "--count: 0 must be an integer >= 1"),
    (["--count", "1000000000000"], "--count: 1000000000000 targets need about"),
    (["--tolerance-mm", "-1"], "--tolerance-mm: -1.0 must be a finite number > 0"),
    (["--seed", "-2"], "--seed: -2 must be an integer in [0, 2^63)"),
    (["--methods", "nope"],
     "--methods: unknown single-pose IK method 'nope'; available: eaik, ours-lm"),
    (["--max-count-per-method", "ikpy"], "--max-count-per-method: 'ikpy' is not METHOD=N"),
    (["--robot", "example-robot-data:nope"], "example-robot-data:nope"),
    (["--budget-ms", "0"], "argument --budget-ms: 0 is out of range; give a budget [ms] more "
                           "than 0 to 3,600,000 (or inf: no budget)"),
    (["--attempts", "0"], "--attempts: 0 must be auto or an integer in [1, 1000]"),
    (["--attempts", "many"], "--attempts: 'many' is neither auto nor an integer"),
    (["--threads", "0"], "--threads: 0 must be an integer >= 1"),
    (["--repeat", "0"], "--repeat: 0 must be an integer in [1, 100]"),
])
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, args, message):
    try:  # the parser refuses some values itself (cli/values.py), the study the others
        code = main(["ik", "--robot", "panda", "--output", str(tmp_path), "--quiet", *args])
    except SystemExit as exit_info:
        code = exit_info.code
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "ik").exists()


def test_a_robot_whose_kinematics_cannot_be_built_is_one_line_exit_2(capsys, tmp_path,
                                                                     monkeypatch):
    def broken(self):
        raise RuntimeError("Several frames match the filter\n(more)")

    monkeypatch.setattr(Robot, "pinocchio_fk", broken)
    code = main(["ik", "--robot", "panda", "--count", "2", "--methods", "sequential-ik",
                 "--output", str(tmp_path), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert ("--robot: panda's kinematics cannot be built (RuntimeError: Several frames "
            "match the filter (more))") in err
    assert not (tmp_path / "ik").exists()


def test_a_method_that_cannot_take_the_kind_is_refused():
    from ikbench.studies.ik import parse_methods

    if _solver("trac-ik") is None:
        pytest.skip("needs pytracik")
    with pytest.raises(InputError, match="trac-ik takes pose targets, not --kind position"):
        parse_methods("trac-ik", "position")


def test_the_solver_list_imports_no_library():
    """Each solver sits in its library's module of baselines/, found by the registry's scan;
    the scan imports those modules, never the libraries (they are imported inside functions)."""
    code = ("import sys; from ikbench.methods.registry import solver_status; s = solver_status(); "
            "print(s['pink'].cls.__module__, s['sequential-ik'].cls.__module__); "
            "print(sorted(m for m in ('roboticstoolbox', 'pytracik', 'pink', 'placo', 'pydrake', "
            "'jax', 'mink', 'ikpy', 'relaxed_ik_lib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.splitlines()
    assert out[0] == "ikbench.baselines.pink_ik ikbench.baselines.sequential_ik"
    assert out[1] == "[]"


@needs_erd
@pytest.mark.parametrize("name, dof, end", [("ur5", 6, "tool0"), ("panda", 7, "panda_link8"),
                                            ("xarm7", 7, "link_eef")])
def test_robots_by_package_name(name, dof, end):
    robot = load_robot(f"example-robot-data:{name}")
    assert robot.name == name and robot.dof == dof and robot.end_frame == end
    text = chain_of(robot).urdf_text  # what the libraries parse: kinematics only
    assert "<transmission" not in text and "<gazebo" not in text and "<visual" not in text
    assert robot.config.source == f"example-robot-data:{name}"
    q = np.random.default_rng(0).uniform(robot.sample_lower, robot.sample_upper, (5, dof))
    point, rotation, _, _ = robot.chain_kinematics().frames(q)
    T = robot.fk_transform(q)  # Pinocchio
    assert np.abs(T[:, :3, 3] - point).max() < 1e-12
    assert np.abs(T[:, :3, :3] - rotation).max() < 1e-12


@needs_erd
def test_an_end_frame_named_like_a_joint_is_the_link_and_z1_runs(tmp_path):
    """z1's URDF has a fixed joint and a link both named gripperStator: the end frame is the
    link's (Pinocchio's BODY frame), and ``ikbench ik`` runs on it."""
    robot = load_robot("example-robot-data:z1", "gripperStator")
    robot.check_loads()
    q = np.random.default_rng(1).uniform(robot.sample_lower, robot.sample_upper, (5, robot.dof))
    point, rotation, _, _ = robot.chain_kinematics().frames(q, jacobian=False)
    T = robot.fk_transform(q)
    assert np.abs(T[:, :3, 3] - point).max() < 1e-12
    assert np.abs(T[:, :3, :3] - rotation).max() < 1e-12
    names = ["ours-lm", "sequential-ik"] + [n for n in ("rtb-lm", "pink")
                                            if _solver(n) is not None]
    assert main(["ik", "--robot", "example-robot-data:z1", "--end-frame", "gripperStator",
                 "--count", "3", "--methods", ",".join(names), "--budget-ms", "inf",
                 "--attempts", "8", "--output", str(tmp_path), "--quiet"]) == 0
    table = pd.read_csv(tmp_path / "ik" / "z1" / "results.csv")
    assert set(table["method"]) == set(names) and (table["failure"].isna()).all()
    assert table.loc[table["method"] == "ours-lm", "success"].all()


def test_drakes_friction_warnings_become_one_line(caplog):
    pytest.importorskip("pydrake")
    from pydrake.multibody.plant import MultibodyPlant

    from ikbench.baselines.drake.common import add_urdf

    joints = "".join(
        f'<joint name="j{k}" type="revolute"><parent link="l{k}"/><child link="l{k + 1}"/>'
        f'<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'
        f'<dynamics damping="0.1" friction="0.2"/></joint>' for k in range(3))
    links = "".join(f'<link name="l{k}"/>' for k in range(4))
    with caplog.at_level(logging.WARNING, logger="drake"):
        add_urdf(MultibodyPlant(time_step=0.0), f'<robot name="r">{links}{joints}</robot>')
    drake = [r.getMessage() for r in caplog.records if r.name == "drake"]
    assert drake == ["3 joint(s) of the URDF have a friction in <dynamics>; Drake's "
                     "MultibodyPlant ignores joint friction (kinematics unaffected)"]


@needs_erd
def test_package_robot_outside_the_table_needs_an_end_frame_and_lists_are_complete(capsys):
    with pytest.raises(InputError, match="give its end frame, a link"):
        load_robot("example-robot-data:so101")
    with pytest.raises(InputError, match="neither a common arm"):
        load_robot("example-robot-data:no_such_arm")
    assert main(["robots", "--all", "--json"]) == 0
    names = {r["name"] for r in json.loads(capsys.readouterr().out)["packages"]}
    assert {"example-robot-data:ur5", "example-robot-data:panda",
            "example-robot-data:tiago_arm", "example-robot-data:so101"} <= names
    uri = "package://example-robot-data/robots/panda_description/meshes/visual/link0.dae"
    assert resolve_package_uri(uri).is_file()
    assert resolve_package_uri("package://example-robot-data/robots/none.stl") is None


@needs_erd
def test_ik_runs_on_a_package_robot(tmp_path):
    robot = load_robot("example-robot-data:ur5")
    result = run_ik(robot, IKSettings(count=5, seed=1, **FIXED), ["ours-lm"], progress=False)
    assert result.table["success"].all()


def test_a_missing_description_package_is_one_line_naming_the_extra(monkeypatch):
    from ikbench.core import robot_packages

    monkeypatch.setattr(robot_packages, "robots_folder", lambda package: None)
    with pytest.raises(InputError, match=r"not installed \(pip install 'ikbench\[robots\]'\)"):
        robot_packages.resolve("example-robot-data:ur5", None)


COMMITTED_IK = sorted((Path(__file__).resolve().parents[1] / "results" / "ik").glob("*/run.json"))


@pytest.mark.parametrize("record_path", COMMITTED_IK, ids=lambda p: p.parent.name)
def test_committed_ik_results_recompute_from_their_solutions(record_path):
    """results/ik/<robot>: every row's success recomputes from its stored joint values and the
    targets file (numpy FK here, Pinocchio judged), and summary.csv's success rates are the
    rows' shares; ours-lm succeeds at least as often as rtb-lm and trac-ik within the budget."""
    folder = record_path.parent
    record = json.loads(record_path.read_text())
    source = folder / ("results.parquet" if (folder / "results.parquet").exists()
                       else "results.csv")
    table = (pd.read_parquet(source) if source.suffix == ".parquet"
             else pd.read_csv(source, dtype={"attempts_rule": str}))
    targets = (pd.read_parquet(folder / "targets.parquet")
               if (folder / "targets.parquet").exists() else pd.read_csv(folder / "targets.csv"))
    shipped = record["robot"]["name"] in shipped_robots()
    robot = load_robot(record["robot"]["name"] if shipped else record["robot"]["source"],
                       end_frame=record["robot"]["end_frame"])
    assert np.array_equal(_fk_recomputed(robot, table, targets, record),
                          table["success"].to_numpy(dtype=bool))
    summary = pd.read_csv(folder / "summary.csv", dtype={"attempts_rule": str})
    rule = table["attempts_rule"].astype(str)
    for (name, method), rows in table.groupby([rule, "method"]):
        row = summary[(summary["attempts_rule"] == name) & (summary["method"] == method)]
        # a rule run several times (the budget table's repeats): the median of the runs'
        runs = rows.groupby("run")["success"].mean() if "run" in rows else rows["success"]
        share = float(runs.median()) if "run" in rows else float(runs.mean())
        assert row["success_pct"].iloc[0] == pytest.approx(100 * share, abs=1e-4)
    auto = summary[summary["attempts_rule"] == "auto"].set_index("method")["success_pct"]
    for other in ("rtb-lm", "trac-ik"):
        if other in auto.index:
            assert auto["ours-lm"] >= auto[other], (other, auto.to_dict())


class _WithBareCall(PoseSolver):
    """Restarted by the study; logs its solves and its bare calls in the order they run."""

    name, library = "with-bare-call", "ikbench"
    log: ClassVar[list] = []

    def solve(self, q_init, point_m, rotation) -> PoseOut:
        type(self).log.append(("solve", point_m.flags.c_contiguous, rotation.flags.c_contiguous))
        return PoseOut(np.asarray(q_init), 1, False)

    def bare_call(self, q_init, point_m, rotation):
        return lambda: type(self).log.append(("bare", tuple(point_m)))


def test_the_bare_call_is_timed_beside_the_first_run_alternating_on_reachable_targets(
        monkeypatch):
    monkeypatch.setitem(solver_status(), "with-bare-call",
                        MethodStatus("with-bare-call", _WithBareCall))
    monkeypatch.setattr(_WithBareCall, "log", [])
    robot = load_robot("panda")
    settings = IKSettings(count=8, seed=2, attempts=(1, 2), unreachable=0.25)
    result = run_ik(robot, settings, ["with-bare-call"], progress=False)
    reachable = result.targets.reachable
    assert reachable is not None and 0 < reachable.sum() < 8
    log = _WithBareCall.log
    first = log[:8 + int(reachable.sum())]  # the first rule's run: the bare calls beside it
    assert all(entry[0] == "solve" for entry in log[len(first):])  # none in the second
    # each solve is given C-ordered copies of the target, as its bare call
    assert all(entry[1] and entry[2] for entry in log if entry[0] == "solve")
    solves = [i for i, entry in enumerate(first) if entry[0] == "solve"]
    assert len(solves) == 8
    for target, at in enumerate(solves):
        point = tuple(result.targets.T_target[target][:3, 3])
        # even targets: solve then bare call; odd ones: bare call then solve
        neighbour = first[at - 1] if target % 2 else first[at + 1] if at + 1 < len(first) \
            else None
        assert (neighbour == ("bare", point)) == bool(reachable[target]), target
    facts = result.methods["with-bare-call"]
    assert facts["bare_call_median_ms"] > 0 and facts["bare_call"]
