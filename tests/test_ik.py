"""``ikbench ik``: seeded targets, the FK re-check of every success, robots by package name,
bad input. Small counts; no timed assertions."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from ikbench.baselines._common.chain import chain_of
from ikbench.baselines._common.single_pose import SOLVERS, PoseOut, PoseSolver
from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.robot import load_robot
from ikbench.core.robot_packages import resolve_package_uri, robots_folder
from ikbench.studies.ik import IKSettings, judge, run_ik, sample_targets

needs_erd = pytest.mark.skipif(robots_folder("example-robot-data") is None,
                               reason="needs example_robot_data")
DETERMINISTIC = [n for n in ("ours-lm", "sequential-ik", "pink")
                 if n in SOLVERS and SOLVERS[n].available()]


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


def test_rerun_gives_the_same_targets_and_success_counts():
    robot = load_robot("panda")
    settings = IKSettings(count=10, seed=1)
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

    monkeypatch.setitem(SOLVERS, "liar", _Liar)
    table = run_ik(robot, settings, ["liar"], progress=False).table
    assert table["library_ok"].all() and not table["success"].any()


class _Unbuildable(PoseSolver):
    """A library that cannot model the robot."""

    name, library = "unbuildable", "ikbench"

    def prepare(self) -> None:
        raise ValueError("no model for this robot")


def test_a_library_that_cannot_be_set_up_gives_failed_rows(monkeypatch):
    monkeypatch.setitem(SOLVERS, "unbuildable", _Unbuildable)
    robot = load_robot("panda")
    table = run_ik(robot, IKSettings(count=4, seed=1), ["unbuildable", "ours-lm"],
                   progress=False).table
    bad = table[table["method"] == "unbuildable"]
    assert len(bad) == 4 and not bad["success"].any()
    assert (bad["failure"] == "prepare: ValueError: no model for this robot").all()
    assert table[table["method"] == "ours-lm"]["success"].all()


def test_the_cli_writes_the_folder_and_every_success_holds_by_fk(tmp_path):
    out = tmp_path / "out"
    assert main(["ik", "--robot", "panda", "--count", "6", "--seed", "1", "--methods",
                 ",".join(DETERMINISTIC), "--output", str(out), "--quiet"]) == 0
    folder = out / "ik" / "panda"
    names = {p.name for p in folder.iterdir()}
    assert {"results.csv", "targets.csv", "leaderboard.md", "run.json", "times.png",
            "success_vs_tolerance.png"} <= names
    table = pd.read_csv(folder / "results.csv")
    assert set(table["method"]) == set(DETERMINISTIC) and len(table) == 6 * len(DETERMINISTIC)
    ok = table[table["success"]]
    assert (ok["position_error_mm"] <= 1.0).all() and (ok["rotation_error_deg"] <= 0.5).all()
    record = json.loads((folder / "run.json").read_text())
    assert record["settings"]["count"] == 6 and record["provenance"]["cpu"]
    assert "1 mm and 0.5 deg" in (folder / "leaderboard.md").read_text()


@pytest.mark.parametrize("args, message", [
    (["--count", "0"], "--count: 0 must be an integer >= 1"),
    (["--count", "1000000000000"], "--count: 1000000000000 targets need about"),
    (["--tolerance-mm", "-1"], "--tolerance-mm: -1.0 must be a finite number > 0"),
    (["--seed", "-2"], "--seed: -2 must be an integer in [0, 2^63)"),
    (["--methods", "nope"], "--methods: 'nope' is not a single-pose IK method; known: ours-lm"),
    (["--max-count-per-method", "ikpy"], "--max-count-per-method: 'ikpy' is not METHOD=N"),
    (["--robot", "example-robot-data:nope"], "example-robot-data:nope"),
])
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, args, message):
    code = main(["ik", "--robot", "panda", "--output", str(tmp_path), "--quiet", *args])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "ik").exists()


@pytest.mark.skipif("trac-ik" not in SOLVERS, reason="no trac-ik solver")
def test_a_method_that_cannot_take_the_kind_is_refused():
    from ikbench.studies.ik import parse_methods

    if not SOLVERS["trac-ik"].available():
        pytest.skip("needs pytracik")
    with pytest.raises(InputError, match="trac-ik takes pose targets, not --kind position"):
        parse_methods("trac-ik", "position")


@needs_erd
@pytest.mark.parametrize("name, dof, end", [("ur5", 6, "tool0"), ("panda", 7, "panda_link8"),
                                            ("xarm7", 7, "link_eef")])
def test_robots_by_package_name(name, dof, end):
    robot = load_robot(f"example-robot-data:{name}")
    assert robot.name == name and robot.dof == dof and robot.end_frame == end
    text = chain_of(robot).urdf_text  # what the libraries parse: kinematics only
    assert "<transmission" not in text and "<gazebo" not in text and "<visual" not in text
    assert robot.config["source"] == f"example-robot-data:{name}"
    q = np.random.default_rng(0).uniform(robot.sample_lower, robot.sample_upper, (5, dof))
    point, rotation, _, _ = robot.chain_kinematics().frames(q)
    T = robot.fk_transform(q)  # Pinocchio
    assert np.abs(T[:, :3, 3] - point).max() < 1e-12
    assert np.abs(T[:, :3, :3] - rotation).max() < 1e-12


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
    result = run_ik(robot, IKSettings(count=5, seed=1), ["ours-lm"], progress=False)
    assert result.table["success"].all()


def test_a_missing_description_package_is_one_line_naming_the_extra(monkeypatch):
    from ikbench.core import robot_packages

    monkeypatch.setattr(robot_packages, "robots_folder", lambda package: None)
    with pytest.raises(InputError, match=r"not installed \(pip install 'ikbench\[robots\]'\)"):
        robot_packages.resolve("example-robot-data:ur5", None)
