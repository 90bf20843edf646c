"""``Method.runtime()``: the backend that actually runs, as recorded beside every result."""

from __future__ import annotations

import importlib.util

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
