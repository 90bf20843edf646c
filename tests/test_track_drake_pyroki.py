"""Drake IK's tracking scheme and the two trajectory optimisers (Drake, PyRoki) under the task
contract: the paper's track (start and touch poses fixed), the joint speed limit, pointing
only where it is judged.

The Drake and PyRoki tests are skipped only when ``pydrake`` / ``pyroki`` is not installed
(``pip install -e '.[libs]'``).
"""

from __future__ import annotations

import importlib.util
from dataclasses import replace

import numpy as np
import pytest

from ikbench import load_robot, load_targets
from ikbench.baselines import pyroki_trajopt
from ikbench.baselines.drake.ik import pose_metric
from ikbench.baselines.pyroki_trajopt import pointing_weights
from ikbench.core.contract import contract_for, judge
from ikbench.core.metrics import contract_metrics
from ikbench.core.task import line_task, line_tasks
from ikbench.methods.registry import get_method
from ikbench.schemes.chain import contract_step, goals_of

needs_drake = pytest.mark.skipif(importlib.util.find_spec("pydrake") is None,
                                 reason="needs drake (pip install -e '.[libs]')")
needs_pyroki = pytest.mark.skipif(importlib.util.find_spec("pyroki") is None,
                                  reason="needs almond-pyroki (pip install -e '.[libs]')")


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def paper_tasks(robot, only: str, contract=None):
    """The paper's line tasks (n = 50) for the touch poses ``only``, with the contract."""
    return line_tasks(robot, load_targets(None, robot).select(only), contract)


def solve_all(method, robot, tasks):
    method.check_tasks(robot, tasks)
    method.prepare(robot)
    return [method.solve(robot, task) for task in tasks]


def figures(robot, task, solution):
    return contract_metrics(robot, task, solution.poses, task.required.contract)


# ----- the conversions (no library needed) ------------------------------------------------------
def test_the_contracts_step_in_urdf_units(robot):
    contract = contract_for(robot)
    pose_step = contract.max_step(50)  # 10.8 motor deg for every NICO joint
    targets = load_targets(None, robot)
    task = line_task(robot, targets.start_pose, targets.touch_poses["1"], 50, "1")
    task = replace(task, required=replace(task.required, contract=contract))
    step = contract_step(goals_of(robot, task), pyroki_trajopt.STEP_MARGIN)
    expected = 0.99 * np.radians(np.abs(np.asarray(robot.scale)) * pose_step)
    np.testing.assert_allclose(step, expected, rtol=1e-12)
    assert contract_step(goals_of(robot, replace(
        task, required=replace(task.required, contract=None)))) is None
    assert contract_step(goals_of(robot, replace(
        task, required=replace(task.required, contract=replace(contract, max_speed=None))))) \
        is None
    # the track's costs weigh a joint in motor deg: NICO's 0.222-scale motors 20.25x
    np.testing.assert_allclose(pose_metric(robot), 1 / np.asarray(robot.scale) ** 2)


def test_pointing_weights_start_where_pointing_is_judged():
    np.testing.assert_array_equal(pointing_weights(6, 2.0, 1), [0, 2, 2, 2, 2, 2])
    np.testing.assert_array_equal(pointing_weights(6, 2.0, 3), [0, 0, 0, 2, 2, 2])
    np.testing.assert_array_equal(pointing_weights(6, 2.0, None), np.zeros(6))


# ----- drake-ik: track and walk ----------------------------------------------------------------
@needs_drake
def test_drake_ik_tracks_from_the_start_pose_onto_the_touch_pose(robot):
    tasks = paper_tasks(robot, "1,7")
    method = get_method("drake-ik")()
    assert method.settings.scheme == "track"
    assert method.fixed_poses() == frozenset({"start_pose", "touch_pose"})
    for task, solution in zip(tasks, solve_all(method, robot, tasks)):
        np.testing.assert_array_equal(solution.poses[0], task.required.start_pose)
        np.testing.assert_array_equal(solution.poses[-1], task.required.end_pose)
        found = figures(robot, task, solution)
        contract = task.required.contract
        assert judge(contract, found) == dict.fromkeys(contract.criteria(), True), \
            (task.name, found)
        assert found["speed_limit_use"] <= 1.0
        assert found["line_distance_max_mm"] < 1e-2
        assert solution.converged and solution.info["scheme"] == "track"
        assert solution.info["speed_bounded"]


@needs_drake
def test_drake_ik_walk_keeps_the_authors_scheme(robot):
    tasks = paper_tasks(robot, "1")
    method = get_method("drake-ik")(scheme="walk")
    assert method.fixed_poses() == frozenset({"touch_pose"})
    (solution,) = solve_all(method, robot, tasks)
    found = figures(robot, tasks[0], solution)
    assert found["start_pose_error_deg"] > 1.0  # the walk ends wherever it ends
    np.testing.assert_array_equal(solution.poses[-1], tasks[0].required.end_pose)
    assert solution.info["scheme"] == "walk"


# ----- the trajectory optimisers under the contract ---------------------------------------------
def assert_meets_the_contract(robot, name: str) -> None:
    """``name`` on paper target 1: every criterion met, the steps bounded by the speed limit,
    pointing asked from the first judged step."""
    tasks = paper_tasks(robot, "1")
    (solution,) = solve_all(get_method(name)(), robot, tasks)
    found = figures(robot, tasks[0], solution)
    assert found["speed_limit_use"] <= 1.0
    contract = tasks[0].required.contract
    assert judge(contract, found) == dict.fromkeys(contract.criteria(), True), \
        found
    assert solution.info["speed_bounded"]
    assert solution.info["pointing_from"] == tasks[0].required.contract.judged_from(50)


@needs_drake
def test_drake_trajopt_meets_the_contract(robot):
    assert_meets_the_contract(robot, "drake-trajopt")


@needs_drake
def test_drake_trajopt_without_pointing_in_the_contract(robot):
    contract = contract_for(robot, pointing="off")
    tasks = paper_tasks(robot, "7", contract)
    (solution,) = solve_all(get_method("drake-trajopt")(), robot, tasks)
    found = figures(robot, tasks[0], solution)
    assert "pointing" not in contract.criteria()
    assert judge(contract, found) == dict.fromkeys(contract.criteria(), True), found
    assert solution.info["pointing_from"] == -1


@needs_drake
def test_drake_trajopt_without_a_contract_is_unchanged(robot):
    (task,) = paper_tasks(robot, "1")
    plain = replace(task, required=replace(task.required, contract=None))
    method = get_method("drake-trajopt")()
    (solution,) = solve_all(method, robot, [plain])
    assert solution.info["pointing_from"] == 1 and not solution.info["speed_bounded"]


@needs_pyroki
def test_pyroki_meets_the_contract(robot):
    assert_meets_the_contract(robot, "pyroki")
