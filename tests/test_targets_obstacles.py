"""Obstacles in targets files and ``ikbench compare --obstacles``: parsed, put on every task,
judged as the contract's "collisions" criterion; without obstacles nothing changes."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.contract import Contract, contract_for, judge
from ikbench.core.errors import TargetsError
from ikbench.core.metrics import contract_metrics
from ikbench.core.robot import Robot
from ikbench.core.targets import Targets, load_targets
from ikbench.core.task import Goal, Requirements, Task, build_tasks, line_tasks
from ikbench.schemes.chain import goals_of
from ikbench.studies.compare import COLUMNS, OBSTACLE_COLUMNS
from tests.conftest import PAPER_START

NAMES = ["r_shoulder_z", "r_shoulder_y", "r_arm_x", "r_elbow_y", "r_wrist_z", "r_wrist_x",
         "r_indexfinger_x"]
#: Two of the paper's touch poses (1 and 2).
TOUCH = {"1": [33, 39, 25, 134, 102, 77, -168], "2": [37, 31, 23, 119, 107, 113, -177]}
BOX = {"type": "box", "name": "crate", "center_mm": [300, 0, 100], "size_mm": [50, 60, 70]}


def _write(folder: Path, name: str = "targets.json", **extra: object) -> Path:
    doc = {"joint_names": NAMES, "start_pose": PAPER_START, "targets": TOUCH, "steps": 6,
           **extra}
    path = folder / name
    path.write_text(json.dumps(doc))
    return path


def _hand_box(robot: Robot) -> dict:
    """A 60 mm box centred on the fingertip at the start pose (every trajectory that starts
    there collides at its first waypoint)."""
    tip = robot.fk(np.asarray(PAPER_START, dtype=float)).point_mm[0]
    return {"type": "box", "name": "on_hand", "center_mm": [float(v) for v in tip],
            "size_mm": [60, 60, 60]}


def test_default_targets_have_no_obstacles(robot: Robot, paper_targets: Targets) -> None:
    assert paper_targets.obstacles == () and paper_targets.obstacles_source == ""
    tasks = line_tasks(robot, paper_targets)
    assert all(t.required.obstacles == () for t in tasks)
    contract = tasks[0].required.contract
    assert not contract.obstacles and "collisions" not in contract.criteria()
    figures = contract_metrics(robot, tasks[0], np.repeat(paper_targets.start_pose[None],
                                                           tasks[0].goal.steps + 1, axis=0),
                               tasks[0].required.contract)
    assert not {"self_collisions", "env_collisions", "min_clearance_mm"} & set(figures)


def test_a_list_of_obstacles_goes_on_every_task(robot: Robot, tmp_path: Path) -> None:
    targets = load_targets(_write(tmp_path, obstacles=[BOX]), robot)
    assert len(targets.obstacles) == 1 and targets.obstacles_source == "list"
    crate = targets.obstacles[0]
    assert crate.kind == "box" and crate.name == "crate"
    assert np.allclose(crate.center_mm, [300, 0, 100]) and np.allclose(crate.size_mm, [50, 60, 70])
    tasks = line_tasks(robot, targets)
    assert [t.name for t in tasks] == ["1", "2"]
    assert all(t.required.obstacles == targets.obstacles for t in tasks)
    contract = tasks[0].required.contract
    assert contract.obstacles and contract.criteria()[-1] == "collisions"
    assert all(t.required.obstacles == targets.obstacles for t in build_tasks(robot, targets))
    letters = build_tasks(robot, targets, "letter:L", steps=8)
    assert letters[0].required.obstacles == targets.obstacles


def test_a_task_holds_its_obstacles_as_a_tuple_and_hands_them_to_the_adapters(
        robot: Robot, tmp_path: Path) -> None:
    crate = load_targets(_write(tmp_path, obstacles=[BOX]), robot).obstacles[0]
    task = Task("t", Goal(np.zeros((3, 3)), np.tile([1.0, 0.0, 0.0], (3, 1))),
                Requirements(obstacles=[crate]))  # a list, as a user may give it
    assert task.required.obstacles == (crate,) and task.goal.pen_down.tolist() == [True] * 3
    assert goals_of(robot, task).obstacles == (crate,)
    free = replace(task, required=replace(task.required, obstacles=()))
    assert goals_of(robot, free).obstacles == ()


def test_a_named_set_and_a_relative_file(robot: Robot, tmp_path: Path) -> None:
    named = load_targets(_write(tmp_path, obstacles="touchscreen"), robot)
    assert [o.name for o in named.obstacles] == ["touchscreen"]
    assert named.obstacles[0].kind == "halfspace" and named.obstacles_source == "touchscreen"
    folder = tmp_path / "sub"
    folder.mkdir()
    (folder / "box.json").write_text(json.dumps({"obstacles": [BOX]}))
    # relative to the targets file's folder, not to the working directory
    relative = load_targets(_write(folder, obstacles="box.json"), robot)
    assert [o.name for o in relative.obstacles] == ["crate"]
    assert relative.obstacles_source == "box.json"
    none = load_targets(_write(tmp_path, "none.json", obstacles="none"), robot)
    assert none.obstacles == () and not line_tasks(robot, none)[0].required.contract.obstacles


@pytest.mark.parametrize("value, message", [
    (5, "obstacles: 5 must be a list of obstacles"),
    ("", "obstacles: '' must be a list of obstacles"),
    ("nosuchset", "obstacles: 'nosuchset' is neither a named set of nico_right_arm "
                  "(touchscreen)"),
    ("missing.json", "obstacles: file"),
    ([{"type": "cone"}], "obstacle 0: type = 'cone' is not one of box, sphere"),
    ([{"type": "box", "center_mm": [0, 0], "size_mm": [1, 1, 1]}],
     "center_mm = [0, 0] must be three finite numbers"),
    ([BOX, BOX], "obstacle name(s) crate used twice"),
])
def test_bad_obstacles_fail_in_one_line(robot: Robot, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str], value: object,
                                        message: str) -> None:
    path = _write(tmp_path, obstacles=value)
    with pytest.raises(TargetsError) as caught:
        load_targets(path, robot)
    assert message in str(caught.value) and "\n" not in str(caught.value)
    assert main(["compare", "--targets", str(path), "--methods", "ours-lm", "--repeat", "1",
                 "--output", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    assert not (tmp_path / "out" / "compare").exists()


def test_bad_obstacles_option_fails_in_one_line(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path)
    assert main(["compare", "--targets", str(path), "--obstacles", "nosuchset", "--output",
                 str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--obstacles: 'nosuchset' is neither" in err
    assert main(["compare", "--problems", "fetch_arm__rot_yz2", "--obstacles",
                 "touchscreen"]) == 2
    assert "do not apply to --problems" in capsys.readouterr().err


def test_contract_round_trip_and_judge() -> None:
    plain = Contract()
    assert "obstacles" not in plain.to_dict() and "collisions" not in plain.criteria()
    assert Contract.from_dict(plain.to_dict()).to_dict() == plain.to_dict()
    judged = Contract(obstacles=True)
    spec = judged.to_dict()
    assert spec["obstacles"] is True and spec["criteria"][-1] == "collisions"
    again = Contract.from_dict(json.loads(json.dumps(spec)))
    assert again.obstacles and again.to_dict() == spec
    assert judged.with_track("touch").criteria()[-1] == "collisions"
    assert "collision" in judged.describe(50) and "collision" not in plain.describe(50)
    base = {"within_limits": True, "start_pose_error_deg": 0, "end_pose_error_deg": 0,
            "line_distance_max_mm": 0, "pointing_deviation_judged_mean_deg": 0}
    assert judge(judged, {**base, "self_collisions": 0, "env_collisions": 0})["collisions"]
    assert not judge(judged, {**base, "self_collisions": 0, "env_collisions": 3})["collisions"]
    assert not judge(judged, {**base, "self_collisions": 1, "env_collisions": 0})["collisions"]
    assert not judge(judged, {**base, "self_collisions": float("nan"),
                              "env_collisions": 0})["collisions"]
    assert "collisions" not in judge(plain, base)


def test_contract_metrics_count_the_collisions(robot: Robot, tmp_path: Path) -> None:
    targets = load_targets(_write(tmp_path, obstacles=[_hand_box(robot)]), robot)
    task = line_tasks(robot, targets, contract_for(robot))[0]
    held = np.repeat(targets.start_pose[None], task.goal.steps + 1, axis=0)
    figures = contract_metrics(robot, task, held, task.required.contract)
    assert figures["env_collisions"] == task.goal.steps + 1 and figures["self_collisions"] == 0
    assert figures["min_clearance_mm"] < 0 and figures["first_collision_waypoint"] == 0
    assert "on_hand" in figures["first_collision_pair"]
    assert judge(task.required.contract, figures)["collisions"] is False


def _compare(tmp_path: Path, name: str, *args: str) -> tuple[int, Path]:
    out = tmp_path / name
    code = main(["compare", "--methods", "ours-lm", "--repeat", "1", "--output", str(out),
                 "--quiet", *args])
    return code, out / "compare"


def test_compare_judges_collisions_and_leaves_obstacle_free_tables_alone(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plain_file = _write(tmp_path, "plain.json")
    code, plain = _compare(tmp_path, "plain", "--targets", str(plain_file))
    assert code == 0
    plain_board = pd.read_csv(plain / "leaderboard.csv")
    plain_results = pd.read_csv(plain / "results.csv")
    assert list(plain_results.columns) == COLUMNS
    assert "collisions_count" not in plain_board and "ok_collisions" not in plain_results
    plain_record = json.loads((plain / "run.json").read_text())
    assert "obstacles" not in plain_record and "obstacles" not in plain_record["contract"]
    assert "no collision" not in (plain / "leaderboard.md").read_text()

    # the touchscreen: the criterion is judged and shown
    code, screen = _compare(tmp_path, "screen", "--targets", str(plain_file), "--obstacles",
                            "touchscreen")
    assert code == 0
    board = pd.read_csv(screen / "leaderboard.csv")
    results = pd.read_csv(screen / "results.csv")
    assert list(results.columns) == [*COLUMNS, *OBSTACLE_COLUMNS]
    assert list(board.columns) == [*plain_board.columns[:list(plain_board.columns).index(
        "pointing_count") + 1], "collisions_count",
        *plain_board.columns[list(plain_board.columns).index("pointing_count") + 1:],
        "min_clearance_mm", "avoids_obstacles", "collision_check_ms", "collision_geometry",
        "collision_check_own_ms"]
    record = json.loads((screen / "run.json").read_text())
    assert record["obstacles"]["source"] == "touchscreen"
    assert record["obstacles"]["items"][0]["type"] == "halfspace"
    assert record["contract"]["obstacles"] is True
    assert "collisions" in record["contract"]["criteria"]
    text = (screen / "leaderboard.md").read_text()
    assert "no collision" in text and "Obstacles (touchscreen)" in text
    assert "half-space touchscreen" in text and "avoids obstacles" in text
    assert (results["obstacles"] == 1).all() and not results["avoids_obstacles"].any()
    success = results["ok_collisions"].astype(bool) & results["success"].astype(bool)
    assert (results["success"].astype(bool) == success).all()  # success needs no collision

    # the judge's check: timed by itself, one figure for every method, its geometry said
    assert (results["collision_geometry"] == "capsules").all()
    assert (results["collision_check_ms"] > 0).all()
    assert board["collision_check_ms"].nunique() == 1
    assert "collision check [ms]" in text and "outside every method's clock" in text
    assert "ours-lm avoids self-collision (capsules" in text

    # a box across the start pose's hand: every row fails "collisions"
    (tmp_path / "hand.json").write_text(json.dumps({"obstacles": [_hand_box(robot)]}))
    boxed = _write(tmp_path, "boxed.json", obstacles="hand.json")
    code, hand = _compare(tmp_path, "hand", "--targets", str(boxed))
    assert code == 0  # a collision is a failed criterion, not a failed solve
    results = pd.read_csv(hand / "results.csv")
    assert len(results) == 2 and (results["status"] == "solved").all()
    assert (results["ok_collisions"] == False).all()  # noqa: E712
    assert not results["success"].any() and not results["success_touch"].any()
    assert (results["env_collisions"] >= 1).all() and (results["first_collision_waypoint"]
                                                       == 0).all()
    assert (results["failure"] == "does not avoid obstacles").all()
    board = pd.read_csv(hand / "leaderboard.csv")
    assert (board["collisions_count"] == 0).all() and (board["success_count"] == 0).all()
    assert (board["min_clearance_mm"] < 0).all()
    assert json.loads((hand / "run.json").read_text())["obstacles"]["source"] == "hand.json"
    capsys.readouterr()

    # --obstacles none overrides the targets file's: the obstacle-free columns again
    code, cleared = _compare(tmp_path, "cleared", "--targets", str(boxed), "--obstacles",
                             "none")
    assert code == 0
    assert list(pd.read_csv(cleared / "leaderboard.csv").columns) == list(plain_board.columns)
    assert list(pd.read_csv(cleared / "results.csv").columns) == COLUMNS


def test_the_judges_collision_check_is_the_same_column_for_every_method(
        robot: Robot, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two methods on the touchscreen: each row has the judge's check time and geometry; the
    leaderboard shows one check time for both, and only ours-lm is labelled as avoiding."""
    code = main(["compare", "--methods", "ours-lm,sequential-ik", "--repeat", "1",
                 "--targets", str(_write(tmp_path)), "--obstacles", "touchscreen",
                 "--output", str(tmp_path / "two"), "--quiet"])
    assert code == 0
    folder = tmp_path / "two" / "compare"
    results = pd.read_csv(folder / "results.csv")
    assert set(results["method"]) == {"ours-lm", "sequential-ik"}
    assert results["collision_check_ms"].notna().all()
    assert set(results["collision_geometry"]) == {"capsules"}
    board = pd.read_csv(folder / "leaderboard.csv")
    assert board["collision_check_ms"].nunique() == 1
    assert board["collision_check_ms"].iloc[0] == pytest.approx(
        results["collision_check_ms"].median(), rel=1e-5)
    own = results.groupby("method")["collision_check_ms"].median()
    for _, row in board.iterrows():
        assert row["collision_check_own_ms"] == pytest.approx(own[row["method"]], rel=1e-5)
    record = json.loads((folder / "run.json").read_text())
    assert set(record["collision_avoidance"]) == {"ours-lm"}
    capsys.readouterr()
