"""The tracking scheme of the point-by-point baselines (sequential-ik, trac-ik, ikpy): from the
start pose onto the touch pose, judged by the task contract; their walk variants reproduce the
paper's Table 2 schemes; ikpy's success flag is checked by FK.

Each test that needs an optional library is skipped only when that library is not installed.
"""

from __future__ import annotations

import importlib.util
from dataclasses import replace

import numpy as np
import pytest

from ikbench.core.contract import contract_for, judge
from ikbench.core.errors import InputError
from ikbench.core.metrics import contract_metrics
from ikbench.core.task import line_task, line_tasks
from ikbench.methods.registry import get_method
from ikbench.schemes.chain import chain_of, goals_of

BOTH = frozenset({"start_pose", "touch_pose"})


def needs(module: str):
    """Skip when ``module`` is not installed (the library's extra is missing)."""
    return pytest.mark.skipif(importlib.util.find_spec(module) is None,
                              reason=f"{module} is not installed")


def paper_tasks(robot, paper_targets, names, steps=None):
    """The paper's line tasks ``names`` with the task contract (paper track), n = ``steps``."""
    targets = paper_targets.select(names)
    if steps is not None:
        targets = targets.with_steps(steps)
    return line_tasks(robot, targets, contract_for(robot, track="paper"))


def solve_judged(method, robot, task):
    """(solution, figures, criterion -> met) of one task."""
    method.check_tasks(robot, [task])
    method.prepare(robot)
    solution = method.solve(robot, task)
    figures = contract_metrics(robot, task, solution.poses, task.required.contract)
    return solution, figures, judge(task.required.contract, figures)


def assert_fixed_rows(solution, task):
    """Row 0 is the start pose and row n the touch pose, exactly as given."""
    np.testing.assert_array_equal(solution.poses[0], task.required.start_pose)
    np.testing.assert_array_equal(solution.poses[-1], task.required.end_pose)


# ----- sequential-ik ----------------------------------------------------------------------------
@needs("pinocchio")
def test_sequential_ik_tracks_onto_the_touch_pose_and_meets_the_contract(robot, paper_targets):
    method = get_method("sequential-ik")()
    assert method.settings.scheme == "track" and method.settings.orientation == "pointing"
    assert method.fixed_poses() == BOTH
    for task in paper_tasks(robot, paper_targets, "1,7"):
        solution, figures, met = solve_judged(method, robot, task)
        assert_fixed_rows(solution, task)
        assert all(met.values()), (task.name, met, figures)
        assert figures["speed_limit_use"] <= 0.95 + 1e-9  # the bound it keeps to
        assert figures["line_distance_max_mm"] < 0.1
        assert solution.info["scheme"] == "track"
        # deterministic
        np.testing.assert_array_equal(method.solve(robot, task).poses, solution.poses)


@needs("pinocchio")
def test_sequential_ik_track_without_speed_bounds_breaks_the_speed_limit(robot, paper_targets):
    """The speed bounds are what make trajectory 7 playable (the last segment jumps without)."""
    task = paper_tasks(robot, paper_targets, "7")[0]
    _, figures, met = solve_judged(get_method("sequential-ik")(max_speed_use=0.0), robot, task)
    assert not met["speed"] and figures["speed_limit_use"] > 1.0
    assert met["line"] and met["pointing"]


@needs("pinocchio")
def test_sequential_ik_track_refuses_tasks_without_a_start_pose(robot, paper_targets):
    task = paper_tasks(robot, paper_targets, "1")[0]
    no_start = replace(task, required=replace(task.required, start_pose=None))
    with pytest.raises(InputError, match="no start pose"):
        get_method("sequential-ik")().check_tasks(robot, [no_start])
    get_method("sequential-ik-walk")().check_tasks(robot, [no_start])  # the walk needs none
    no_end = replace(task, required=replace(task.required, end_pose=None))
    with pytest.raises(InputError, match="no end pose"):
        get_method("sequential-ik-walk")().check_tasks(robot, [no_end])


@needs("pinocchio")
def test_sequential_ik_keeps_walking_pose_paths_forward(robot):
    """A pose path (goal frames, no touch pose) is walked forward in either scheme, following
    its goal frames."""
    from ikbench.baselines.sequential_ik import walk
    from tests.test_baselines import fk_task

    task = fk_task(robot, seed=5, frames=True)
    task = replace(task, required=replace(task.required, end_pose=None))
    method = get_method("sequential-ik")()
    method.check_tasks(robot, [task])
    solution = method.solve(robot, task)
    frame = replace(method.settings, orientation="frame")  # a pose path follows its frames
    np.testing.assert_array_equal(solution.poses, walk(robot, task, frame).poses)
    assert "scheme" not in solution.info
    T = robot.fk_transform(solution.poses)
    assert np.linalg.norm(T[:, :3, 3] * 1000 - task.goal.points_mm, axis=1).max() < 1e-3
    rel = np.einsum("nji,njk->nik", T[:, :3, :3], task.goal.rotations)
    cos = (np.trace(rel, axis1=1, axis2=2) - 1) / 2
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1e-2


@needs("pinocchio")
def test_sequential_ik_walk_is_the_papers_table_2_scheme(robot, paper_targets):
    from ikbench.baselines.sequential_ik import DLSSettings, walk

    method = get_method("sequential-ik-walk")()
    assert method.settings.scheme == "walk" and method.settings.orientation == "frame"
    assert method.fixed_poses() == frozenset({"touch_pose"})
    assert get_method("sequential-ik")(scheme="walk").fixed_poses() == frozenset({"touch_pose"})
    for task in paper_tasks(robot, paper_targets, "1,7"):
        solution, figures, met = solve_judged(method, robot, task)
        np.testing.assert_array_equal(solution.poses[-1], task.required.end_pose)
        assert figures["start_pose_error_deg"] > 1.0 and not met["start_pose"]
        # the walk as it always was: frame mode, the touch pose's roll
        same = walk(robot, task, DLSSettings(orientation="frame"))
        np.testing.assert_array_equal(solution.poses, same.poses)
        assert solution.info == same.info


# ----- trac-ik ----------------------------------------------------------------------------------
@needs("pytracik")
def test_trac_ik_tracks_from_the_start_pose_onto_the_touch_pose(robot, paper_targets):
    """TRAC-IK holds every point exactly (FK-checked) but, with no bound on a step's joint
    change, the contract's speed criterion is not met (the landing segment jumps): asserted
    here is what it does reach."""
    method = get_method("trac-ik")()
    assert method.settings.scheme == "track" and method.settings.solve_type == "Distance"
    assert method.fixed_poses() == BOTH
    task = paper_tasks(robot, paper_targets, "7")[0]
    solution, figures, met = solve_judged(method, robot, task)
    assert_fixed_rows(solution, task)
    assert solution.converged, solution.info  # every point solved, checked by pytracik.fk
    assert solution.info["points_fk_off"] == 0
    for criterion in ("start_pose", "end_pose", "limits", "line", "pointing"):
        assert met[criterion], (criterion, figures)
    assert figures["line_distance_max_mm"] < 0.01


@needs("pytracik")
def test_trac_ik_walk_keeps_the_touch_pose_only(robot, paper_targets):
    method = get_method("trac-ik")(scheme="walk")
    assert method.fixed_poses() == frozenset({"touch_pose"})
    task = paper_tasks(robot, paper_targets, "7", steps=10)[0]
    solution, figures, _ = solve_judged(method, robot, task)
    np.testing.assert_array_equal(solution.poses[-1], task.required.end_pose)
    assert figures["start_pose_error_deg"] > 1.0


# ----- ikpy -------------------------------------------------------------------------------------
@needs("ikpy")
def test_ikpy_tracks_onto_the_touch_pose_and_meets_the_contract(robot, paper_targets):
    method = get_method("ikpy")()
    assert method.settings.scheme == "track" and method.settings.orientation == "pointing"
    assert method.fixed_poses() == BOTH
    task = paper_tasks(robot, paper_targets, "7", steps=20)[0]  # n = 20: ikpy is slow
    solution, figures, met = solve_judged(method, robot, task)
    assert_fixed_rows(solution, task)
    assert all(met.values()), (met, figures)
    assert figures["speed_limit_use"] <= 0.95 + 1e-9


@needs("ikpy")
def test_ikpy_walk_is_the_authors_call(robot, paper_targets):
    from ikbench.baselines.ikpy_ik import IkpyIK

    method = get_method("ikpy-walk")()
    assert method.settings.scheme == "walk" and method.settings.orientation == "position"
    assert method.fixed_poses() == frozenset({"touch_pose"})
    task = paper_tasks(robot, paper_targets, "1", steps=10)[0]
    solution, figures, _ = solve_judged(method, robot, task)
    np.testing.assert_array_equal(solution.poses[-1], task.required.end_pose)
    assert figures["start_pose_error_deg"] > 1.0
    assert solution.converged  # every point within 0.1 mm, by FK
    same = IkpyIK(scheme="walk", orientation="position").solve(robot, task)
    np.testing.assert_array_equal(solution.poses, same.poses)


@needs("ikpy")
@pytest.mark.parametrize("orientation", ["position", "pointing"])
def test_ikpy_flags_a_point_it_cannot_reach(robot, orientation):
    """ikpy reports no success: the adapter checks FK, so a goal 5 m away is not solved."""
    from ikbench.baselines.ikpy_ik import IkpySettings, solve_chain

    task = line_task(robot, [-24.92, 81.45, 46.55, 94.37, -59.03, 28.0, 45.67],
                     [34, 17, 39, 107, 106, 78, -180], 2, "far")
    goals = goals_of(robot, task)
    points = goals.points_m.copy()
    points[0] = [5.0, 0.0, 0.0]
    result = solve_chain(chain_of(robot), replace(goals, points_m=points),
                         IkpySettings(scheme="walk", orientation=orientation))
    assert not result.converged
    assert result.info["failed_points"] == "0"  # point 1 (reachable) solved
    assert result.info["points_not_converged"] == 1
