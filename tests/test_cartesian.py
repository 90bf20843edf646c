"""Cartesian path problems end to end: ``ikbench run --problem`` on problem files it has never
seen, the trajectory file's quaternions, methods that cannot follow goal frames, and the
``ikbench cartesian`` benchmark command."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.problems import load_problem
from ikbench.core.rotations import matrix_to_quat_wxyz, quat_wxyz_to_matrix
from ikbench.core.trajectory import QUATERNION_COLUMNS, read_trajectory_poses
from ikbench.methods.base import Method, Solution
from tests.conftest import one_line_error, register_temporarily


def _quat(axis: int, angle):
    q = np.zeros((len(angle), 4))
    q[:, 0], q[:, 1 + axis] = np.cos(angle / 2), np.sin(angle / 2)
    return q


def write_problem(folder: Path, kind: str) -> Path:
    """A problem file and its path CSV, made up here (not one of CppFlow's)."""
    if kind == "panda":   # a vertical circle, hand down, yawing +-20 deg
        t = np.linspace(0, 2 * np.pi, 120)
        rows = np.column_stack([t, 0 * t, 0.1 * np.cos(t), 0.1 * np.sin(t),
                                _quat(2, np.radians(20) * np.sin(t))])
        yaml = ('robot: "panda"\npath_name: "circle"\npath_offset_frame: "world"\n'
                "path_xyz_offset: [0.5, 0.0, 0.45]\n"
                "path_R_offset: [[1, 0, 0], [0, -1, 0], [0, 0, -1]]\n")
        name = "circle"
    else:                 # a sideways sweep in front of the Fetch, tilting +-15 deg
        s = np.linspace(0, 1, 150)
        rows = np.column_stack([s, 0 * s, -0.15 + 0.3 * s, 0.05 * np.sin(np.pi * s),
                                _quat(1, np.radians(15) * np.sin(np.pi * s))])
        yaml = ('robot: "fetch_arm"\npath_name: "tilt"\npath_offset_frame: "world"\n'
                "path_xyz_offset: [0.8, 0.0, 0.75]\n"
                "path_R_offset: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\n")
        name = "tilt"
    np.savetxt(folder / f"{name}.csv", rows, delimiter=",", fmt="%.9f", comments="",
               header="time,x,y,z,qw,qx,qy,qz")
    path = folder / f"{kind}__unseen.yaml"
    path.write_text(yaml)
    return path


@pytest.mark.parametrize("kind", ["panda", "fetch_arm"])
def test_an_unseen_problem_file_is_solved_validly(tmp_path, kind):
    path = write_problem(tmp_path, kind)
    assert main(["run", "--method", "ours-lm", "--problem", str(path), "--output",
                 str(tmp_path / "out"), "--quiet"]) == 0
    folder = tmp_path / "out" / "ours-lm"
    table = pd.read_csv(folder / "table.csv")
    row = table.iloc[0]
    assert row["trajectory"] == f"{kind}__unseen" and bool(row["valid"])
    assert row["position_error_max_mm"] < 0.1 and row["rotation_error_max_deg"] < 0.1
    assert row["max_joint_change_deg"] < 7 and row["time_to_valid_s"] == row["duration_s"]
    robot, task, _ = load_problem(path)
    trajectory = pd.read_csv(folder / f"trajectory_{kind}__unseen.csv")
    assert list(trajectory.columns[2:2 + robot.dof]) == list(robot.joint_names)
    assert list(trajectory.columns[-4:]) == QUATERNION_COLUMNS
    poses = read_trajectory_poses(folder / f"trajectory_{kind}__unseen.csv", robot)
    T = robot.fk_transform(poses, "torch")  # the other backend than the one that wrote it
    np.testing.assert_allclose(quat_wxyz_to_matrix(trajectory[QUATERNION_COLUMNS].to_numpy()),
                               T[:, :3, :3], atol=1e-8)  # 10 significant digits written
    np.testing.assert_allclose(trajectory[["x_mm", "y_mm", "z_mm"]], T[:, :3, 3] * 1000,
                               atol=1e-6)
    assert (trajectory["qw"] >= 0).all()
    record = json.loads((folder / "run.json").read_text())
    assert record["problem"] == str(path) and record["robot"]["name"] == kind
    assert (folder / f"pose_path_{kind}__unseen.png").stat().st_size > 10_000


class PointsOnly(Method):
    name = "points-only"
    description = "a method without goal frames"

    def solve(self, robot, task, progress=None):  # pragma: no cover - never called
        return Solution(np.zeros((task.goal.steps + 1, robot.dof)), 0, 0.0, None)


def test_methods_without_goal_frames_say_they_cannot(tmp_path, capsys, monkeypatch):
    register_temporarily(monkeypatch, PointsOnly)
    code = main(["run", "--method", "points-only", "--problem", "fetch_arm__rot_yz2",
                 "--output", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert ("--method points-only cannot follow goal frames (a 6-D pose path); methods that "
            "can: ours, ours-lm, ours-exact, sequential-ik") in err
    code = main(["cartesian", "--methods", "ours-lm,points-only", "--output", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "--methods: points-only cannot follow goal frames" in err
    assert not list(tmp_path.iterdir())


def test_other_methods_follow_a_short_path(tmp_path):
    """sequential-ik (walked forward from the home pose) and ours (Adam, stopping at the first
    valid iterate) on a made-up sweep; both write the same columns."""
    path = write_problem(tmp_path, "fetch_arm")
    for method, extra in (("sequential-ik", []), ("ours", ["--max-iterations", "30"])):
        assert main(["run", "--method", method, "--problem", str(path), "--output",
                     str(tmp_path / "out"), "--quiet", *extra]) == 0
    seq = pd.read_csv(tmp_path / "out" / "sequential-ik" / "table.csv").iloc[0]
    adam = pd.read_csv(tmp_path / "out" / "ours" / "table.csv").iloc[0]
    assert bool(seq["valid"]) and seq["position_error_max_mm"] < 1e-3
    details = pd.read_csv(tmp_path / "out" / "ours" / "details.csv").iloc[0]
    assert bool(adam["valid"]) == bool(details["converged"])        # stops only when valid
    assert adam["iterations"] == (adam["iterations"] if adam["valid"] else 30)


def test_the_benchmark_command_writes_its_folder(tmp_path, capsys):
    path = write_problem(tmp_path, "panda")
    assert main(["cartesian", "--problems", str(path), "--methods", "ours-lm,sequential-ik",
                 "--seeds", "4,7", "--output", str(tmp_path / "out"), "--quiet",
                 "--trajectories", "all"]) == 0
    folder = tmp_path / "out" / "cartesian"
    table = pd.read_csv(folder / "table.csv")
    assert len(table) == 4 and set(table["seed"]) == {4, 7}
    assert set(table["method"]) == {"ours-lm", "sequential-ik"} and table["valid"].all()
    assert table["time_to_valid_s"].equals(table["duration_s"])
    robot, task, _ = load_problem(path)
    for _, row in table.iterrows():   # the table is the trajectories' own figures
        poses = read_trajectory_poses(folder / row["trajectory"], robot)
        from ikbench.core.metrics import frame_metrics

        metrics = frame_metrics(robot, task, poses)
        assert metrics["position_error_max_mm"] == pytest.approx(row["position_error_max_mm"],
                                                                 rel=1e-6, abs=1e-6)
    summary = pd.read_csv(folder / "summary.csv")
    assert list(summary["valid_runs"]) == [2, 2]
    published = pd.read_csv(folder / "published.csv")
    assert published.iloc[0, -1] == "no"  # a problem file of one's own
    report = (folder / "report.md").read_text()
    assert "ikbench cartesian --problems" in report and "not found" in report
    record = json.loads((folder / "run.json").read_text())
    assert record["seeds"] == [4, 7] and "pose_path_panda__unseen.png" in record["files"]
    seeds = {s: read_trajectory_poses(folder / f"ours-lm/trajectory_panda__unseen_seed{s}.csv",
                                      robot) for s in (4, 7)}
    assert not np.array_equal(seeds[4], seeds[7])    # the seed is passed on


def test_the_summary_sets_the_length_beside_torms_published_one():
    from ikbench.render.cartesian_report import TORM_LENGTH, summarise

    table = pd.DataFrame({
        "problem": ["fetch_arm__s", "fetch_arm__s", "panda__flappy_bird"],
        "method": ["ours-lm"] * 3, "seed": [1, 2, 1], "valid": [True, False, True],
        "time_to_valid_s": [0.5, np.nan, 0.7], "duration_s": [0.5, 0.9, 0.7],
        "joint_path_length_deg": np.degrees([10.0, 12.0, 20.0]),
        **{c: [0.0] * 3 for c in ("position_error_max_mm", "rotation_error_max_deg",
                                  "max_joint_change_deg", "max_joint_change_mm",
                                  "env_collisions", "self_collisions", "min_clearance_mm")},
        "avoids_obstacles": [True] * 3, "failed_criteria": ["", "joint_change", ""]})
    summary = summarise(table).set_index("problem")
    assert "published" in TORM_LENGTH and "TORM_TL_RESULTS" in TORM_LENGTH
    s = summary.loc["fetch_arm__s"]
    assert s["valid_runs"] == 1 and s["duration_median_s"] == pytest.approx(0.7)
    assert s["joint_path_length_median_rad"] == pytest.approx(11.0)
    assert s[TORM_LENGTH] == 10.856                       # as jstmn/cppflow records it
    assert s["joint_path_length_over_torm"] == pytest.approx(11.0 / 10.856)
    assert np.isnan(summary.loc["panda__flappy_bird", TORM_LENGTH])     # none published


def test_published_figures_are_labelled_and_never_estimated():
    from ikbench.render.cartesian_report import published_table

    table = published_table(["fetch_arm__hello", "fetch__hello", "panda__square"])
    row = table.set_index("problem")
    cppflow_time = [c for c in table.columns if c.startswith("CppFlow time to valid")][0]
    torm_length = [c for c in table.columns if c.startswith("TORM joint path length")][0]
    assert "Morgan et al., ICRA 2024" in cppflow_time and "TORM_TL_RESULTS" in torm_length
    assert set(row[cppflow_time]) == {"not found"}
    assert row.loc["fetch_arm__hello", torm_length] == "61.029"
    assert row.loc["fetch__hello", torm_length] == "not found"
    assert row.loc["panda__square"].iloc[-1] == "no"        # not in CppFlow's benchmark set
    # CppFlow's own list decides, not whether a published figure was found: fetch__s and
    # panda__flappy_bird are in it (they read "not a CppFlow problem")
    from ikbench.core.problems import BENCHMARK_PROBLEMS

    listed = published_table(list(BENCHMARK_PROBLEMS))
    assert (listed.iloc[:, -1] == "yes").all() and len(listed) == 13


def test_seeds_are_lists_ranges_or_both():
    from ikbench.studies.cartesian import parse_seeds

    assert parse_seeds("1-5") == (1, 2, 3, 4, 5)
    assert parse_seeds("1-3,7, 9-9") == (1, 2, 3, 7, 9)
    assert parse_seeds([4, "6"]) == (4, 6)


@pytest.mark.parametrize("args, message", [
    (["--seeds", "1,x"], "--seeds: '1,x' must be distinct integers"),
    (["--seeds", "2,2"], "must be distinct integers"),
    (["--seeds", "5-1"], "--seeds: '5-1' must be distinct integers"),
    (["--seeds", "1-3,2"], "must be distinct integers"),
    (["--problems", "nope"], "--problems: 'nope' is neither a shipped problem"),
    (["--methods", "nope"], "--methods: unknown method 'nope'"),
    (["--seed", "3"], "--seed: the benchmark runs every seed of --seeds"),
    (["--lm-seed", "3"], "--lm-seed: the benchmark runs every seed of --seeds"),
    (["--methods", "sequential-ik", "--lr", "0.5"], "--lr is not an option of the methods "
     "chosen (sequential-ik)"),
])
def test_bad_benchmark_input_one_line_exit_2(tmp_path, capsys, args, message):
    assert message in one_line_error(capsys, ["cartesian", *args, "--output",
                                              str(tmp_path / "out")])
    assert not (tmp_path / "out").exists()


def test_the_study_is_a_plain_function(tmp_path):
    from ikbench.studies.cartesian import cartesian, write

    result = cartesian("fetch__rot_yz2", ["sequential-ik"], [0, 1], progress=False)
    row = result.table.iloc[0]
    assert row["problem"] == "fetch__rot_yz2" and row["waypoints"] == 249
    assert row["max_joint_change_mm"] >= 0            # fetch has the prismatic torso
    assert not row["valid"] and "joint_change" in row["failed_criteria"]
    folder = write(result, tmp_path)                  # trajectories of the first seed only
    table = pd.read_csv(folder / "table.csv", keep_default_na=False)
    assert list(table["trajectory"]) == ["sequential-ik/trajectory_fetch__rot_yz2_seed0.csv", ""]
    assert sorted(p.name for p in (folder / "sequential-ik").iterdir()) == [
        "trajectory_fetch__rot_yz2_seed0.csv"]
    # no valid run: the report says whether the waypoints can be reached at all
    assert ("**fetch__rot_yz2**: every waypoint is reachable on its own within the limits"
            in (folder / "report.md").read_text())
    assert matrix_to_quat_wxyz(np.eye(3)).tolist() == [1.0, 0.0, 0.0, 0.0]


RESULTS = Path(__file__).resolve().parents[1] / "results"


def _recomputed(folder: Path) -> pd.DataFrame:
    """table.csv of a committed cartesian folder, each written row's figures and verdict
    recomputed from its trajectory CSV (the collision checker included)."""
    from ikbench.core.metrics import frame_metrics

    table = pd.read_csv(folder / "table.csv", keep_default_na=False, na_values=[""])
    loaded = {}
    for _, row in table[table["trajectory"].fillna("") != ""].iterrows():
        if row["problem"] not in loaded:
            loaded[row["problem"]] = load_problem(row["problem"])
        robot, task, _ = loaded[row["problem"]]
        metrics = frame_metrics(robot, task, read_trajectory_poses(folder / row["trajectory"],
                                                                   robot))
        for column in ("position_error_max_mm", "rotation_error_max_deg",
                       "max_joint_change_deg", "joint_path_length_deg", "self_collisions",
                       "env_collisions"):
            # abs 1e-6 [mm, deg]: a continuous joint is written unwrapped (a value a whole
            # turn away keeps fewer digits after the point in the file's 10 significant
            # digits), so FK of the file differs from the solver's poses by 1e-7 mm, 1e-8
            # deg; the criteria's thresholds are 0.1 mm and 0.1 deg
            assert metrics[column] == pytest.approx(row[column], rel=1e-6, abs=1e-6), (
                row["problem"], row["method"], row["seed"], column)
        assert metrics["valid"] == bool(row["valid"]), (row["problem"], row["method"])
        written_criteria = "" if pd.isna(row["failed_criteria"]) else row["failed_criteria"]
        assert metrics["failed_criteria"] == written_criteria, (row["problem"], row["method"])
    return table


def test_ours_lm_is_valid_on_every_cppflow_problem_from_every_seed():
    """results/cartesian (issue 34): ours-lm on CppFlow's 13 problems from seeds 1-5, every run
    valid by CppFlow's criteria and collision-free, recomputed from the committed trajectories;
    the median joint path length within 1.1x TORM's published one wherever there is one."""
    from ikbench.core.problems import BENCHMARK_PROBLEMS

    folder = RESULTS / "cartesian"
    table = _recomputed(folder)
    assert set(table["method"]) == {"ours-lm"} and set(table["seed"]) == {1, 2, 3, 4, 5}
    assert set(table["problem"]) == set(BENCHMARK_PROBLEMS) and len(table) == 13 * 5
    assert table["trajectory"].fillna("").str.len().gt(0).all()     # every seed written
    assert table["valid"].astype(bool).all(), table.loc[~table["valid"].astype(bool),
                                                        ["problem", "seed", "failed_criteria"]]
    assert (table["self_collisions"] == 0).all() and (table["env_collisions"] == 0).all()
    summary = pd.read_csv(folder / "summary.csv")
    ratio = summary["joint_path_length_over_torm"].dropna()
    assert len(ratio) >= 5 and (ratio <= 1.1).all(), summary[["problem",
                                                              "joint_path_length_over_torm"]]


def test_every_method_once_is_reproduced_from_its_trajectories():
    """results/cartesian_methods: every frame method once (seed 1) on the 13 problems; each
    written row's verdict recomputes from its CSV; drake-trajopt refuses every pose path."""
    table = _recomputed(RESULTS / "cartesian_methods" / "cartesian")
    assert set(table["seed"]) == {1}
    assert {"ours-lm", "sequential-ik", "pink", "trac-ik", "mink", "drake-ik"} <= \
        set(table["method"])
    per_method = table.groupby("method")["problem"].nunique()
    assert (per_method == 13).all(), per_method
    trajopt = table[table["method"] == "drake-trajopt"]
    assert not trajopt["valid"].astype(bool).any()


def test_first_call_is_a_column_of_every_method_only_when_asked(tmp_path):
    """--first-call: summary.csv's first_call_s (a fresh process: import, set-up, first solve)
    is finite and positive for each method, the report's summary and its section name it;
    without the option the column is absent."""
    path = write_problem(tmp_path, "panda")
    common = ["cartesian", "--problems", str(path), "--methods", "ours-lm,sequential-ik",
              "--seeds", "1", "--quiet"]
    assert main([*common, "--output", str(tmp_path / "on"), "--first-call"]) == 0
    folder = tmp_path / "on" / "cartesian"
    summary = pd.read_csv(folder / "summary.csv")
    assert set(summary["method"]) == {"ours-lm", "sequential-ik"}
    assert np.isfinite(summary["first_call_s"]).all() and (summary["first_call_s"] > 0).all()
    record = json.loads((folder / "run.json").read_text())
    assert set(record["first_calls"]) == {"ours-lm", "sequential-ik"}
    for split in record["first_calls"].values():
        assert split["first_call_s"] == pytest.approx(
            split["import_s"] + split["setup_s"] + split["solve_s"])
    report = (folder / "report.md").read_text()
    assert "first call [s]" in report and "fresh Python process" in report
    assert "--first-call" in report
    assert main([*common, "--output", str(tmp_path / "off")]) == 0
    off = tmp_path / "off" / "cartesian"
    assert "first_call_s" not in pd.read_csv(off / "summary.csv")
    assert "first call [s]" not in (off / "report.md").read_text()
