"""roboticstoolbox-python (baselines/rtb.py): its ETS of the chain agrees with
Pinocchio's FK, its single-pose solvers solve FK targets under ``ikbench ik``'s interface, and
rtb-lm's track in ``compare`` meets the task contract on NICO's paper targets and the Panda
lines (roll left free by ik_LM's mask), judged again from the CSVs it wrote.

Skipped only when roboticstoolbox is not installed (``pip install -e '.[libs]'``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ikbench import load_robot
from ikbench.cli import main
from ikbench.core.contract import contract_for, judge
from ikbench.core.metrics import contract_metrics
from ikbench.core.robot_packages import robots_folder
from ikbench.core.targets import load_targets
from ikbench.core.task import line_tasks
from ikbench.core.trajectory import read_trajectory_poses
from ikbench.methods.registry import method_status
from ikbench.schemes.chain import chain_of
from tests.test_rangedik_placo import PANDA_LINES, assert_judged_from_csvs

pytest.importorskip("roboticstoolbox")

from ikbench.baselines.rtb import (  # noqa: E402 (after the skip)
    TOL,
    RtbLMSolver,
    RtbNRSolver,
    RtbSettings,
    check_fk,
    goal_frame,
    pointing_ets,
    rtb_ets,
)

ROBOTS = ["nico_right_arm", "panda", "fetch", "fetch_arm"]
if robots_folder("example-robot-data") is not None:
    ROBOTS += ["example-robot-data:ur5", "example-robot-data:panda"]


@pytest.mark.parametrize("name", ROBOTS)
def test_the_ets_is_the_chain_pinocchio_loads(name):
    """Same base, same end frame, same joint order: the end frame's transform agrees with
    Pinocchio's to 1e-9 over seeded configurations (continuous joints included: Fetch)."""
    robot = load_robot(name)
    ets = rtb_ets(chain_of(robot))
    assert ets.n == robot.dof
    assert check_fk(robot, ets) <= 1e-9
    q = np.random.default_rng(11).uniform(robot.sample_lower, robot.sample_upper,
                                          (20, robot.dof))
    mine = np.stack([np.asarray(ets.fkine(x).A) for x in robot.to_urdf(q)])
    assert np.abs(mine - robot.fk_transform(q)).max() < 1e-9
    chain = chain_of(robot)
    finite = np.isfinite(chain.lower)
    np.testing.assert_allclose(ets.qlim[0][finite], chain.lower[finite], atol=1e-12)
    np.testing.assert_allclose(ets.qlim[1][finite], chain.upper[finite], atol=1e-12)


def test_a_chain_rtb_cannot_walk_is_an_error():
    robot = load_robot("panda")
    chain = chain_of(robot)
    from dataclasses import replace

    with pytest.raises(ValueError, match="no path from panda_hand to panda_link0"):
        rtb_ets(replace(chain, base_link="panda_hand", end_frame="panda_link0"))


@pytest.mark.parametrize("cls", [RtbLMSolver, RtbNRSolver])
def test_one_search_from_near_the_answer_solves_it_to_the_library_tolerance(cls):
    robot = load_robot("panda")
    solver = cls(robot, "pose")
    solver.prepare()
    rng = np.random.default_rng(3)
    q = rng.uniform(robot.sample_lower, robot.sample_upper, (5, robot.dof))
    T = robot.fk_transform(q)
    start = robot.to_urdf(np.clip(q + rng.uniform(-3, 3, q.shape), robot.lower, robot.upper))
    for k in range(5):
        out = solver.solve(start[k], T[k, :3, 3], T[k, :3, :3])
        assert out.ok and out.attempts == 1 and 0 < out.iterations <= 30
        error = np.asarray(solver.ets.fkine(out.q).A) - T[k]
        assert np.abs(error).max() < 10 * np.sqrt(2 * TOL)  # |e| < 1e-6 m, rad
        assert robot.within_limits(robot.from_urdf(out.q)[None], tol_deg=1e-9)


def test_position_only_frees_the_rotation():
    robot = load_robot("panda")
    solver = RtbLMSolver(robot, "position")
    solver.prepare()
    q = np.radians([10.0, -20, 30, -90, 10, 80, 20])
    T = robot.fk_transform(robot.from_urdf(q)[None])[0]
    twisted = T[:3, :3] @ np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])  # 90 deg off
    out = solver.solve(q + 0.05, T[:3, 3], twisted)
    reached = robot.fk_transform(robot.from_urdf(out.q)[None])[0]
    assert out.ok and np.linalg.norm(reached[:3, 3] - T[:3, 3]) < 1e-6


def test_the_settings_are_checked():
    from ikbench.core.errors import InputError

    with pytest.raises(InputError, match="--rtb-slimit: 0 must be an integer >= 1"):
        RtbSettings(slimit=0)
    with pytest.raises(InputError, match=r"--rtb-posture-seed: 2.0 must be in \[0, 1\]"):
        RtbSettings(posture_seed=2.0)
    with pytest.raises(InputError, match=r"--rtb-pointing-seed: -0.1 must be in \[0, 1\]"):
        RtbSettings(pointing_seed=-0.1)
    with pytest.raises(InputError, match="--rtb-orientation"):
        RtbSettings(orientation="frame")


def test_the_mask_frees_the_roll_about_the_pointing_direction_only():
    """ik_LM's error is in its base frame: behind the rotation that turns the pointing
    direction onto z, mask [1, 1, 1, 1, 1, 0] accepts a pose whose roll about that direction
    is 40 deg off the goal's (and stays near the start), but not a 40 deg tilt."""
    robot = load_robot("panda")
    chain = chain_of(robot)
    ets = rtb_ets(chain)
    q = np.radians([10.0, -20, 30, -90, 10, 80, 20])
    T = np.asarray(ets.fkine(q).A)
    direction = T[:3, :3] @ chain.pointing_axis
    turned, turn = pointing_ets(ets, direction)
    np.testing.assert_allclose(turn[:3, :3] @ direction, [0, 0, 1], atol=1e-12)
    mask = np.array([1.0, 1, 1, 1, 1, 0])
    tilt_axis = np.cross(direction, [1.0, 0, 0])
    for axis, solvable in ((direction, True), (tilt_axis, False)):
        rotation = _rotation_about(axis, np.radians(40)) @ T[:3, :3]
        out = turned.ik_LM(turn @ goal_frame(T[:3, 3], rotation), q0=q + 0.02, ilimit=30,
                           slimit=1, tol=TOL, mask=mask, joint_limits=True)
        reached = np.asarray(ets.fkine(out.q).A)
        if solvable:
            assert out.success and np.abs(reached[:3, 3] - T[:3, 3]).max() < 1e-6
            np.testing.assert_allclose(reached[:3, :3] @ chain.pointing_axis, direction,
                                       atol=1e-6)
            assert np.abs(out.q - q).max() < 0.05  # not turned onto the goal's roll
        else:
            assert not out.success or np.abs(reached[:3, :3] @ chain.pointing_axis
                                             - direction).max() > 0.1


def _rotation_about(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    from ikbench.schemes.geometry import rotation_about

    return rotation_about(axis, angle_rad)


def test_rtb_lm_meets_the_contract_on_nico_paper_targets(tmp_path):
    """The paper's task on NICO's seven targets (start and touch poses fixed, n = 50): rtb-lm's
    track (orientation pointing, the default) meets every criterion, success recomputed from
    the CSVs. With exact rotations (the roll ramped onto the touch pose's) its largest step
    was 1.8 to 4.0 times the allowed one; with the roll free but the seed pulled toward the
    posture from step 1, up to 1.07 times (the wrist's turn in steps 1 to 9; docs/baselines.md).
    """
    assert method_status()["rtb-lm"].available
    robot = load_robot()
    contract = contract_for(robot)
    tasks = {t.name: t for t in line_tasks(robot, load_targets(None, robot), contract)}
    assert main(["compare", "--methods", "rtb-lm", "--repeat", "1", "--output", str(tmp_path),
                 "--quiet"]) == 0
    table = pd.read_csv(tmp_path / "compare" / "results.csv", dtype={"trajectory": str})
    results = table[table["task"] == "paper"]
    assert sorted(results["trajectory"]) == [str(k) for k in range(1, 8)]
    assert (results["scheme"].str.startswith("track")).all()
    assert_judged_from_csvs(tmp_path / "compare", results, robot, tasks, contract)
    assert results["success"].all(), results.to_dict("records")
    assert (results["line_distance_max_mm"] < 0.01).all()


def test_exact_rotations_fail_nico_on_speed_only(tmp_path):
    """``--rtb-orientation pose`` (an exact rotation per point) on NICO's target 1: every
    criterion but the speed limit, judged from the CSV ``ikbench run`` wrote."""
    robot = load_robot()
    contract = contract_for(robot)
    task = line_tasks(robot, load_targets(None, robot).select("1"), contract)[0]
    assert main(["run", "--method", "rtb-lm", "--rtb-orientation", "pose", "--only", "1",
                 "--output", str(tmp_path), "--quiet"]) == 0
    poses = read_trajectory_poses(tmp_path / "rtb-lm" / "trajectory_1.csv", robot)
    figures = contract_metrics(robot, task, poses, contract)
    failed = [c for c, ok in judge(contract, figures).items() if not ok]
    assert failed == ["speed"], figures
    assert figures["speed_limit_use"] > 1.2


def test_rtb_lm_meets_the_contract_on_the_panda_lines(tmp_path):
    """On the Panda's lines rtb-lm's track meets every criterion, success recomputed from the
    CSVs. (In orientation pose, before the roll was ramped onto the touch pose's, the last
    segment turned the flange joint onto it: 1.4 to 6.3 times the allowed step on six of the
    seven lines.)"""
    robot = load_robot("panda")
    contract = contract_for(robot)
    only = "3,4"
    tasks = {t.name: t for t in line_tasks(robot, load_targets(PANDA_LINES, robot).select(only),
                                           contract)}
    assert main(["compare", "--robot", "panda", "--targets", str(PANDA_LINES), "--only", only,
                 "--methods", "rtb-lm", "--repeat", "1", "--output", str(tmp_path),
                 "--quiet"]) == 0
    results = pd.read_csv(tmp_path / "compare" / "results.csv", dtype={"trajectory": str})
    assert sorted(results["trajectory"]) == only.split(",")
    assert_judged_from_csvs(tmp_path / "compare", results, robot, tasks, contract)
    assert results["success"].all(), results.to_dict("records")
    assert (results["line_distance_max_mm"] < 0.01).all()
