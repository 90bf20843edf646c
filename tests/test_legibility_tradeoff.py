"""ours-exact's legibility term (ikbench's extension) and the trade-off study."""

from __future__ import annotations

import numpy as np
import pytest

from ikbench.core.legibility import legibility_term, legibility_term_weights, pointing_probabilities
from ikbench.core.task import line_tasks
from ikbench.methods.ours_exact import ExactProblem, OursExact, build_problem
from ikbench.methods.ours_exact.problem import pointing_p_true
from ikbench.studies.legibility_tradeoff import LINE_BOUND_MM, legibility_tradeoff
from tests.conftest import central_differences, one_line_error


def test_legibility_term_hand_case():
    # n = 2: f = (1, 1/2, 0), sum 3/2; W = 3: w = (2, 1, 0);
    # 2 (1 - 0.5)^2 + 1 (1 - 1)^2 + 0 (1 - 0)^2 = 0.5
    assert np.allclose(legibility_term_weights(3, 3.0), [2.0, 1.0, 0.0])
    assert legibility_term([0.5, 1.0, 0.0], 3.0) == pytest.approx(0.5)
    assert legibility_term([1.0, 1.0, 1.0], 7.0) == 0.0


def _problem(goals, true):
    b, n = 1, 2
    return ExactProblem(np.zeros((b, n, 3)), np.zeros((b, n, 3)), None, np.zeros((b, n)),
                        np.zeros(b), np.zeros(b), np.zeros((b, 1)), np.zeros(b),
                        np.zeros((b, n), bool), np.ones((b, n), bool), np.zeros(1),
                        np.zeros(1), np.ones((b, n)), np.asarray(goals, float)[None],
                        np.array([true]), 10.0)


def test_ours_exact_p_true_is_the_pointing_observers_and_its_derivatives():
    goals = [[100.0, 0.0, 0.0], [80.0, 40.0, 10.0], [90.0, -30.0, 20.0]]
    problem = _problem(goals, 1)
    points = np.array([[[0.0, 0.0, 0.0], [10.0, 5.0, -3.0]]])
    direction = np.array([[[1.0, 0.2, 0.1], [0.9, 0.5, 0.0]]])
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    p, dp_dv, dp_dp, _ = pointing_p_true(problem, points, direction)
    expected = pointing_probabilities(points[0], direction[0], goals)[:, 1]
    assert np.allclose(p[0], expected, atol=1e-12)
    by_v = central_differences(lambda d: pointing_p_true(problem, points, d)[0], direction,
                               1e-6)
    by_p = central_differences(lambda q: pointing_p_true(problem, q, direction)[0], points,
                               1e-5)
    # moving the direction off the unit sphere: only its tangent part is meaningful
    tangent = by_v - np.sum(by_v * direction, axis=-1, keepdims=True) * direction
    mine = dp_dv - np.sum(dp_dv * direction, axis=-1, keepdims=True) * direction
    assert np.allclose(mine, tangent, atol=1e-6)
    assert np.allclose(dp_dp, by_p, atol=1e-6)


def test_weight_zero_is_the_papers_method(robot, paper_targets):
    task = line_tasks(robot, paper_targets)[0]
    goals = robot.fk(np.stack(list(paper_targets.touch_poses.values()))).point_mm
    with_goals = OursExact(legibility_weight=0.0, legibility_goals_mm=goals)
    assert build_problem(robot, [task], with_goals.settings).legibility is None
    assert np.array_equal(OursExact().solve(robot, task).poses,
                          with_goals.solve(robot, task).poses)


def test_weight_raises_legibility_within_the_line_bound(robot, paper_targets):
    curve = legibility_tradeoff(robot, paper_targets, weights=[0.0, 300.0])
    assert curve["pointing_legibility"].iloc[1] > curve["pointing_legibility"].iloc[0] + 0.005
    assert (curve["line_distance_max_mm"] <= LINE_BOUND_MM).all()


def test_the_option_needs_a_goal_set(capsys, tmp_path, robot, paper_targets):
    from ikbench.core.errors import InputError

    with pytest.raises(InputError, match="needs a goal set"):
        OursExact(legibility_weight=1.0)
    task = line_tasks(robot, paper_targets)[0]
    alone = OursExact(legibility_weight=1.0, legibility_goals_mm=task.goal.end_point_mm[None])
    with pytest.raises(InputError, match="needs a goal set with a goal other than"):
        alone.solve(robot, task)
    err = one_line_error(capsys, ["run", "--method", "ours-exact", "--exact-legibility-weight",
                                  "1", "--output", str(tmp_path / "out")])
    assert "needs a goal set" in err


@pytest.mark.parametrize("argv", [
    ["legibility", "--weights", "0,-1"],
    ["legibility", "--weights", "nan"],
    ["run", "--method", "ours-exact", "--exact-legibility-weight", "-1"],
    ["run", "--method", "ours-exact", "--exact-legibility-weight", "nan"],
])
def test_bad_weight_exits_2_with_one_line(capsys, tmp_path, argv):
    err = one_line_error(capsys, [*argv, "--output", str(tmp_path / "out")])
    assert "weight" in err
