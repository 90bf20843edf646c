"""``Method.runtime()``: the backend that actually runs, as recorded beside every result."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from ikbench.methods.ours_exact import OursExact
from ikbench.methods.ours_lm import OursLM
from ikbench.methods.registry import available_methods


def test_ours_lm_names_the_solver_its_settings_choose():
    assert OursLM(backend="numpy").runtime() == {"backend": "numpy", "threads": 1}
    assert OursLM(device="cpu").runtime()["backend"] == "torch (cpu, float64)"
    auto = OursLM().runtime()
    expected = "numba" if importlib.util.find_spec("numba") else "numpy"
    assert auto["backend"] == expected
    # the pinocchio kinematics cannot run compiled: auto falls back to numpy
    assert OursLM(kinematics="pinocchio").runtime()["backend"] == "numpy"
    if expected == "numba":
        assert OursLM(threads=1).runtime() == {"backend": "numba", "threads": 1}


def test_ours_exact_names_its_solver_and_its_initial_solution():
    runtime = OursExact().runtime()
    assert runtime["backend"] == "numpy"
    assert runtime["initial_solution"] == OursLM().runtime()["backend"]


@pytest.mark.parametrize("name", sorted(available_methods()))
def test_every_method_names_a_backend(name):
    runtime = available_methods()[name]().runtime()
    assert isinstance(runtime["backend"], str) and runtime["backend"]


def test_ik_runs_the_compiled_single_pose_lm_where_numba_is_installed(robot):
    """``ikbench ik``'s ours-lm is the compiled solver with numba, the numpy reference
    without; both answer the same target within the tolerance."""
    from ikbench.methods.ours_lm.pose_solver import OursLMSolver

    solver = OursLMSolver(robot, "pose", (1.0, 0.5), 0.005)
    solver.prepare()
    expected = "numba" if importlib.util.find_spec("numba") else "numpy"
    assert solver.runtime() == {"backend": expected}
    pose = robot.sample_lower + 0.4 * (robot.sample_upper - robot.sample_lower)
    T = robot.fk_transform(pose)[0]
    start = robot.sample_lower + 0.45 * (robot.sample_upper - robot.sample_lower)
    out = solver.solve_within(start[None].repeat(3, 0), T[:3, 3], T[:3, :3], float("inf"))
    reached = robot.fk_transform(out.q)[0]
    assert out.ok and np.linalg.norm(reached[:3, 3] - T[:3, 3]) * 1000.0 < 1.0
