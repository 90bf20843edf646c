"""ours-lm's first-use set-up (``OursLMSolver.prepare_first_call``, what ``ikbench.solve_pose``
runs): each kernel layout loaded when a call first needs it, the answers those of the warmed
solver (``prepare``, what ``ikbench ik`` times) bit for bit."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

import ikbench
from ikbench.methods.ours_lm.pose_solver import OursLMSolver

pytest.importorskip("numba")

from ikbench.methods.ours_lm import single_pose_compiled  # noqa: E402


@pytest.fixture(scope="module")
def ur5():
    return ikbench.load_robot("example-robot-data:ur5")


def _targets(robot, count, seed):
    rng = np.random.default_rng(seed)
    goals = rng.uniform(robot.sample_lower, robot.sample_upper, (count, robot.dof))
    return robot.fk_transform(goals), rng


def _layouts(T):
    """The goal as callers hand it: the frame's column views, C-ordered copies, read-only
    views (copied by both paths) and a Fortran-ordered frame's views."""
    frozen = T.copy()
    frozen.flags.writeable = False
    fortran = np.asfortranarray(T)
    return [(T[:3, 3], T[:3, :3]),
            (np.ascontiguousarray(T[:3, 3]), np.ascontiguousarray(T[:3, :3])),
            (frozen[:3, 3], frozen[:3, :3]),
            (fortran[:3, 3], fortran[:3, :3])]


@pytest.mark.parametrize("kind", ["pose", "position"])
def test_first_use_answers_are_the_warmed_solvers_bit_for_bit(ur5, kind):
    """On UR5 targets, from one start, several, with and without a budget, and with every
    layout of the goal: pose, iterations, success and attempts equal exactly."""
    warm = OursLMSolver(ur5, kind, (1.0, 0.5))
    warm.prepare()
    lazy = OursLMSolver(ur5, kind, (1.0, 0.5))
    lazy.prepare_first_call()
    assert lazy._lazy and not warm._lazy
    frames, rng = _targets(ur5, 6, 63)
    compared = 0
    for T in frames:
        for rows, budget_s in ((1, math.inf), (4, math.inf), (4, 0.05)):
            starts = rng.uniform(ur5.sample_lower, ur5.sample_upper, (rows, ur5.dof))
            for point, rotation in _layouts(T):
                rot = None if kind == "position" else rotation
                a = warm.solve_within(starts, point, rot, budget_s)
                b = lazy.solve_within(starts, point, rot, budget_s)
                assert a.q.tobytes() == b.q.tobytes()
                assert (a.iterations, a.ok, a.attempts) == (b.iterations, b.ok, b.attempts)
                compared += 1
    assert compared == 6 * 3 * 4


def test_solve_pose_answers_are_the_warmed_solvers(ur5):
    """``ikbench.solve_pose`` (first-use set-up) answers as the warmed solver does."""
    warm = OursLMSolver(ur5, "pose", (1.0, 0.5))
    warm.prepare()
    frames, rng = _targets(ur5, 5, 64)
    for T in frames:
        q0 = rng.uniform(ur5.sample_lower, ur5.sample_upper, ur5.dof)
        q, ok = ikbench.solve_pose(ur5, T, q0)
        out = warm.solve_within(q0[None], T[:3, 3], T[:3, :3], math.inf)
        assert q.tobytes() == out.q.tobytes() and ok == bool(out.ok)


def test_load_layout_loads_only_the_warm_up_layouts():
    """A read-only view or integer starts are no layout of the warm-up: nothing is loaded
    and the caller copies; a frame's column views are one, loaded once."""
    dispatcher = single_pose_compiled.loaded_on_first_use(
        single_pose_compiled.kernels.solve_views)
    spec, T = np.zeros((8, single_pose_compiled.WIDTH)), np.eye(4)
    frozen = T.copy()
    frozen.flags.writeable = False
    before = set(dispatcher.overloads)
    assert not single_pose_compiled.load_layout(
        dispatcher, (spec, frozen[:3, 3], frozen[:3, :3], np.zeros((1, 6)), 0.0))
    assert not single_pose_compiled.load_layout(
        dispatcher, (spec, T[:3, 3], T[:3, :3], np.zeros((1, 6), dtype=np.int64), 0.0))
    assert set(dispatcher.overloads) == before
    args = (spec, T[:3, 3], T[:3, :3], np.zeros((1, 6)), 0.0)
    assert single_pose_compiled.load_layout(dispatcher, args)
    assert single_pose_compiled.load_layout(dispatcher, args)
    assert set(dispatcher.overloads) - before <= single_pose_compiled.view_layouts()
    assert len(set(dispatcher.overloads) - before) <= 1


CHILD = """
import json, numpy as np, ikbench
from numba.core.dispatcher import Dispatcher
from ikbench.methods.ours_lm import single_pose_compiled as m
robot = ikbench.load_robot("example-robot-data:ur5")
T = robot.fk_transform(np.full(robot.dof, 20.0)[None])[0]
q, ok = ikbench.solve_pose(robot, T, np.full(robot.dof, 25.0))
kernels = [v for v in vars(m.kernels).values() if isinstance(v, Dispatcher)]
lazy = m.loaded_on_first_use(m.kernels.solve_views)
import sys
from numba.np import arraymath, linalg
counts = {"ok": ok, "kernels": sum(len(k.overloads) for k in kernels),
          "lazy": len(lazy.overloads), "scipy_linalg": "scipy.linalg" in sys.modules,
          "blas": arraymath._HAVE_BLAS, "restored": arraymath.ensure_blas is linalg.ensure_blas}
import numba
a = np.arange(12.0).reshape(3, 4)
dot = numba.njit(lambda x, y: np.dot(x, y))(a, a.T)  # BLAS lowered in this process
counts["dot"] = bool(np.array_equal(dot, a @ a.T))
print(json.dumps(counts))
"""


def test_a_fresh_process_first_answer_loads_one_layout():
    """In a new process the first ``solve_pose`` answer loads one specialisation of
    ``solve_views`` and none of the warm-up's others (the kernels' own dispatchers hold
    none), without importing scipy.linalg (numba's BLAS probe skipped, its answer still
    True, its function restored); a BLAS kernel compiled after it in the same process
    answers right."""
    done = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                          timeout=600, check=True)
    counts = json.loads(done.stdout.strip().splitlines()[-1])
    assert counts == {"ok": True, "kernels": 0, "lazy": 1, "scipy_linalg": False,
                      "blas": True, "restored": True, "dot": True}


def test_the_first_call_study_answers_ours_lm_from_its_first_use_set_up(ur5):
    """``first_call`` (``ikbench ik --first-call``) of ours-lm in a fresh process: the three
    times and their sum, no error (its set-up is ``prepare_first_call``)."""
    from ikbench.studies.first_call import first_call

    T = ur5.fk_transform(np.full(ur5.dof, 20.0)[None])[0]
    out = first_call(ur5, "ours-lm", "pose", (1.0, 0.5), 0.01, T,
                     np.full((2, ur5.dof), 25.0))
    assert "error" not in out, out
    assert out["first_call_s"] == pytest.approx(out["import_s"] + out["setup_s"]
                                                + out["solve_s"])
