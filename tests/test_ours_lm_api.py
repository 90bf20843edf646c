"""``ikbench.solve_pose``: ours-lm's single-pose IK as a library call."""

from __future__ import annotations

import numpy as np
import pytest

import ikbench
from ikbench.core.errors import InputError
from ikbench.core.rotations import geodesic_angle

pytest.importorskip("numba")


@pytest.fixture(scope="module")
def panda():
    return ikbench.load_robot("panda")


def test_solve_pose_reaches_the_frame_within_tolerance_by_pinocchio(panda):
    """From a random start the answer's frame (Pinocchio's FK) is within 1 mm / 0.5 deg of
    the goal; from the answer itself it returns at once with that answer."""
    rng = np.random.default_rng(7)
    solved = 0
    for _ in range(10):
        goal = rng.uniform(panda.sample_lower, panda.sample_upper)
        T = panda.fk_transform(goal[None])[0]
        starts = rng.uniform(panda.sample_lower, panda.sample_upper, (8, panda.dof))
        q, ok = ikbench.solve_pose(panda, T, starts)
        assert q.shape == (panda.dof,) and isinstance(ok, bool)
        got = panda.fk_transform(q[None])[0]
        if ok:
            solved += 1
            assert np.linalg.norm(got[:3, 3] - T[:3, 3]) * 1000.0 < 1.0
            assert np.degrees(geodesic_angle(T[None, :3, :3], got[None, :3, :3]))[0] < 0.5
        q_again, ok_again = ikbench.solve_pose(panda, T, goal)
        assert ok_again
        np.testing.assert_allclose(q_again, goal, atol=1e-9)
    assert solved >= 9
    assert np.all((q >= panda.lower) & (q <= panda.upper))


def test_solve_pose_names_bad_input(panda):
    T = np.eye(4)
    with pytest.raises(InputError, match="T: shape"):
        ikbench.solve_pose(panda, T[:3], np.zeros(panda.dof))
    with pytest.raises(InputError, match="q0: shape"):
        ikbench.solve_pose(panda, T, np.zeros(panda.dof + 1))
    with pytest.raises(InputError, match="kind"):
        ikbench.solve_pose(panda, T, np.zeros(panda.dof), kind="twist")


def test_solve_pose_keeps_one_solver_per_tolerance(panda):
    """Another tolerance is another solver (its scale and success test), an array of the same
    tolerance finds the tuple's; the answer from its own pose is the pose either way."""
    from ikbench.methods.ours_lm import api

    goal = np.clip(np.zeros(panda.dof), panda.sample_lower, panda.sample_upper)
    T = panda.fk_transform(goal[None])[0]
    for tolerance in ((1.0, 0.5), np.array([1.0, 0.5]), (2.0, 1.0), [2.0, 1.0]):
        q, ok = ikbench.solve_pose(panda, T, goal, tolerance=tolerance)
        assert ok
        np.testing.assert_allclose(q, goal, atol=1e-9)
    assert set(api._SOLVERS[panda]) == {("pose", (1.0, 0.5)), ("pose", (2.0, 1.0))}
