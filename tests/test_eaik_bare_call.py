"""Issue 58 item 1: EAIK's branch choice in one compiled pass gives exactly what
``in_limit_turns`` and an argmin give; the bare library calls (``PoseSolver.bare_call``) and
their columns in ``ikbench ik``'s summary; the ground-truth table's two fixes (the nearest-branch
share of all successes, "no claims")."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from ikbench.core.robot import load_robot
from ikbench.core.robot_packages import robots_folder
from ikbench.render.ik_report import _truth, with_bare_calls
from ikbench.studies.ik import IKSettings, bare_call_times, sample_targets

needs_erd = pytest.mark.skipif(robots_folder("example-robot-data") is None,
                               reason="needs example_robot_data")


def _prepared(cls):
    """``cls``'s solver on UR5, prepared, and the robot."""
    robot = load_robot("example-robot-data:ur5")
    solver = cls(robot)
    solver.prepare()
    return robot, solver


def _cases(robot, count, seed):
    """(target frame (4, 4), the study's first initial configuration [rad]) per target."""
    targets = sample_targets(robot, IKSettings(count=count, seed=seed))
    for k in range(count):
        yield targets.T_target[k], robot.to_urdf(targets.initials(k, 1)[0])


def _reference(Q, drop, lower, upper, near, tol=1e-9):
    """The old answer: in_limit_turns on the exact solutions, then the argmin."""
    from ikbench.baselines.eaik_ik import in_limit_turns

    Q = Q[~drop]
    if not len(Q):
        return None, 0
    moved, inside = in_limit_turns(Q, lower, upper, near, tol=tol)
    found = moved[inside]
    if not len(found):
        return None, 0
    return found[np.argmin(np.linalg.norm(found - near, axis=1))], len(found)


def test_the_compiled_branch_choice_is_in_limit_turns_and_the_argmin_exactly():
    pytest.importorskip("numba")
    from ikbench.baselines.eaik_ik import nearest_in_limits

    rng = np.random.default_rng(7)
    cases = kept = 0
    for _ in range(3000):
        # more solutions than the work buffer's scratch rows (32) take the allocated path
        S, dof = int(rng.integers(1, 41)), int(rng.integers(1, 7))
        Q = rng.uniform(-math.pi, math.pi, (S, dof))
        if rng.random() < 0.2:  # exact duplicates: the first of equals, as argmin
            Q[-1] = Q[0]
        centre = rng.uniform(-2 * math.pi, 2 * math.pi, dof)
        half = rng.choice([0.3, 1.0, math.pi, 2 * math.pi, 3 * math.pi], dof)
        lower, upper = centre - half, centre + half
        free = rng.random(dof) < 0.15  # continuous joints: no limits
        lower[free], upper[free] = -np.inf, np.inf
        # a value exactly on a limit, where the tolerance decides
        Q[0, 0] = lower[0] + 2 * math.pi if np.isfinite(lower[0]) else Q[0, 0]
        drop = rng.random(S) < 0.2
        near = rng.uniform(-3 * math.pi, 3 * math.pi, dof)
        expected, count = _reference(Q, drop, lower, upper, near)
        out = np.full(dof, np.nan)
        found = nearest_in_limits(np.ascontiguousarray(Q), drop, lower, upper, near, out)
        assert found == count
        cases += 1
        if count:
            kept += 1
            np.testing.assert_array_equal(out, expected)  # bit for bit
        else:
            assert np.isnan(out).all()  # untouched
    assert kept > 500 and cases - kept > 100  # both outcomes exercised


@needs_erd
def test_eaik_solve_is_the_nearest_branch_and_its_bare_call_is_eaiks_ik():
    pytest.importorskip("eaik")
    from ikbench.baselines.eaik_ik import EaikSolver

    robot, solver = _prepared(EaikSolver)
    for T, q_init in _cases(robot, 40, 4):
        exact, _ = solver.solutions(T[:3, 3], T[:3, :3])
        expected, count = _reference(exact, np.zeros(len(exact), dtype=bool), solver.lower,
                                     solver.upper, q_init)
        out = solver.solve(q_init, T[:3, 3], T[:3, :3])
        assert out.ok and out.iterations == count
        np.testing.assert_array_equal(out.q, expected)
        answer = solver.bare_call(q_init, T[:3, 3], T[:3, :3])()
        np.testing.assert_array_equal(np.asarray(answer.Q).reshape(-1, robot.dof)[
            ~np.asarray(answer.is_LS, dtype=bool)], exact)


@needs_erd
def test_bare_call_times_measure_what_has_a_bare_call_and_say_what_it_is():
    pytest.importorskip("eaik")
    from ikbench.baselines.eaik_ik import EaikSolver
    from ikbench.schemes.single_pose import PoseOut, PoseSolver

    robot, solver = _prepared(EaikSolver)
    targets = sample_targets(robot, IKSettings(count=10, seed=2))
    timed = bare_call_times(solver, targets, 10)
    assert 0 < timed["bare_call_median_ms"] < 50
    assert timed["bare_call"] == ("EAIK's own `calculate_IK(T)` on the target frame "
                                  "assembled in advance.")

    class NoBareCall(PoseSolver):
        name = "none"

        def solve(self, q_init, point_m, rotation):
            return PoseOut(q_init, 0, None)

    assert bare_call_times(NoBareCall(robot), targets, 10) == {
        "bare_call_median_ms": None, "bare_call": None}


@needs_erd
def test_rtb_bare_call_is_the_call_its_solve_makes():
    pytest.importorskip("roboticstoolbox")
    from ikbench.baselines.rtb import RtbLMSolver

    robot, solver = _prepared(RtbLMSolver)
    for T, q_init in _cases(robot, 5, 2):
        out = solver.solve(q_init, T[:3, 3], T[:3, :3])
        bare = solver.bare_call(q_init, T[:3, 3], T[:3, :3])()
        assert (bool(bare.success), int(bare.iterations)) == (out.ok, out.iterations)
        if out.ok:  # (a failed search hands back a random configuration)
            np.testing.assert_array_equal(np.asarray(bare.q, dtype=float), out.q)


def test_summary_gets_the_library_call_its_glue_and_the_eaik_ratio():
    summary = pd.DataFrame({"method": ["eaik", "rtb-lm", "ikpy"],
                            "time_median_ms": [0.02, 0.3, 1.0]})
    methods = {"eaik": {"bare_call_median_ms": 0.005}, "rtb-lm": {"bare_call_median_ms": 0.2},
               "ikpy": {"bare_call_median_ms": None}}
    out = with_bare_calls(summary, methods).set_index("method")
    assert list(summary.columns) == ["method", "time_median_ms"]  # not changed in place
    np.testing.assert_allclose(out["bare_call_median_ms"], [0.005, 0.2, np.nan])
    np.testing.assert_allclose(out["glue_median_ms"], [0.015, 0.1, np.nan])
    np.testing.assert_allclose(out["x_eaik_call"], [4.0, 60.0, 200.0])
    without = with_bare_calls(summary.iloc[1:], {"rtb-lm": {"bare_call_median_ms": 0.2}})
    assert without["x_eaik_call"].isna().all()


def test_nearest_branch_share_is_of_all_successes_and_no_claims_says_so():
    # four successes: two on the nearest branch, one on another, one on no branch; a failure
    g = pd.DataFrame({"library_ok": [None] * 5, "success": [True, True, True, True, False],
                      "on_nearest_branch": [1.0, 1.0, 0.0, np.nan, np.nan],
                      "branch_excess_deg": [0.0, 0.0, 30.0, np.nan, np.nan],
                      "time_s": [0.001] * 5})
    truth = _truth(g, g[g["success"]], g.iloc[:0])
    assert truth["on_nearest_branch_pct"] == pytest.approx(50.0)
    assert truth["claims"] == 0
    no_branches = g.assign(on_nearest_branch=np.nan)
    assert np.isnan(_truth(no_branches, no_branches[g["success"]],
                           g.iloc[:0])["on_nearest_branch_pct"])


def test_the_silent_failure_table_says_no_claims_for_a_method_that_makes_none():
    from types import SimpleNamespace

    from ikbench.render.ik_report import ground_truth_section

    result = SimpleNamespace(targets=SimpleNamespace(branches=None, reachable=None),
                             auto_rows=8)
    summary = pd.DataFrame({"attempts_rule": ["8", "8"], "method": ["ikpy", "rtb-lm"],
                            "claims": [0, 10], "claimed_rejected": [0, 1],
                            "denied_holding": [0, 2]})
    text = "\n".join(ground_truth_section(result, summary))
    assert "| ikpy | no claims | no claims |" in text
    assert "| rtb-lm | 1 of 10 | 2 of 10 |" in text


@needs_erd
def test_ik_writes_the_library_call_columns_and_says_what_the_call_is(tmp_path):
    pytest.importorskip("eaik")
    import json

    from ikbench.studies.ik import run_ik, write

    robot = load_robot("example-robot-data:ur5")
    result = run_ik(robot, IKSettings(count=8, seed=1, attempts=(1,)), methods="eaik",
                    progress=False)
    folder = write(result, tmp_path)
    summary = pd.read_csv(folder / "summary.csv")
    assert summary["bare_call_median_ms"].iloc[0] > 0
    assert summary["x_eaik_call"].iloc[0] == pytest.approx(
        summary["time_median_ms"].iloc[0] / summary["bare_call_median_ms"].iloc[0], rel=1e-4)
    board = (folder / "leaderboard.md").read_text()
    assert "library call [ms] | x_eaik_call |" in board and "**Library call**" in board
    facts = json.loads((folder / "run.json").read_text())["methods"]["eaik"]
    assert facts["bare_call"].startswith("EAIK's own") and facts["bare_call_median_ms"] > 0


def test_the_spread_and_first_call_columns_stay_the_last():
    summary = pd.DataFrame({"method": ["eaik"], "time_median_ms": [0.02], "runs": [2],
                            "time_median_ms_max": [0.03], "first_call_ms": [5.0]})
    out = with_bare_calls(summary, {"eaik": {"bare_call_median_ms": 0.01}})
    assert list(out.columns) == ["method", "time_median_ms", "bare_call_median_ms",
                                 "glue_median_ms", "x_eaik_call", "runs",
                                 "time_median_ms_max", "first_call_ms"]


@needs_erd
@pytest.mark.parametrize("name", ["trac-ik", "ikpy"])
def test_trac_ik_and_ikpy_bare_calls_answer_the_target(name):
    from ikbench.methods.registry import solver_status

    status = solver_status().get(name)
    if status is None or not status.cls.available():
        pytest.skip(f"{name} is not installed")
    robot, solver = _prepared(status.cls)
    fk = robot.pinocchio_fk()
    for T, q_init in _cases(robot, 3, 2):
        out = np.asarray(solver.bare_call(q_init, T[:3, 3], T[:3, :3])(), dtype=float)
        q = out[1:] if name == "trac-ik" else out[solver.active]  # (status, q...) / all links
        if name == "trac-ik" and out[0] < 0:
            continue
        assert q.shape == (robot.dof,)
        if name == "ikpy":  # deterministic: the answer solve gives
            np.testing.assert_array_equal(q, solver.solve(q_init, T[:3, 3], T[:3, :3]).q)
        else:  # TRAC-IK's claimed success holds
            assert np.linalg.norm(fk.placement(q).translation - T[:3, 3]) < 1e-4


@needs_erd
def test_eaik_compiles_in_prepare_not_in_a_timed_call():
    pytest.importorskip("eaik")
    from ikbench.baselines.eaik_ik import EaikSolver

    robot, solver = _prepared(EaikSolver)
    kernels = (solver._nearest, solver._frame_into)
    compiled = [list(kernel.signatures) for kernel in kernels]
    converted = []
    solver._solve_converted = lambda *args: converted.append(args)  # the slow path, counted
    targets = sample_targets(robot, IKSettings(count=2, seed=1))
    T = targets.T_target[1]  # as the study passes it: views of the frame, a row of starts
    starts = np.ascontiguousarray(robot.to_urdf(targets.initials(1, 3)))
    assert solver.solve_within(starts, T[:3, 3], T[:3, :3], 1.0).ok
    solver.solve(starts[0], np.ascontiguousarray(T[:3, 3]), np.ascontiguousarray(T[:3, :3]))
    far = T.copy()
    far[:3, 3] *= 100.0  # out of reach: EAIK's least-squares answers only
    assert not solver.solve_within(starts, far[:3, 3], far[:3, :3], 1.0).ok
    assert converted == []  # every call ran a specialisation loaded in prepare
    # the branch pass is called at its compiled entry point, not through the dispatcher
    assert solver._branch_pass is not solver._nearest and callable(solver._branch_pass)
    assert [list(kernel.signatures) for kernel in kernels] == compiled


def test_eaik_answers_inputs_of_another_dtype_or_layout_as_float64_without_compiling():
    pytest.importorskip("eaik")
    from ikbench.baselines.eaik_ik import EaikSolver

    robot, solver = _prepared(EaikSolver)
    compiled = [list(kernel.signatures) for kernel in (solver._nearest, solver._frame_into)]
    T = sample_targets(robot, IKSettings(count=3, seed=1)).T_target[2]
    q0 = np.zeros(robot.dof)
    plain = solver.solve(q0, np.ascontiguousarray(T[:3, 3]), np.ascontiguousarray(T[:3, :3]))
    odd = solver.solve(q0.astype(np.float32), T[:3, 3].astype(np.float32),
                       np.asfortranarray(T[:3, :3]))
    assert plain.ok and odd.ok
    # float32 inputs move the frame by ~1e-7 relative, so the answer by as little
    assert np.abs(odd.q - plain.q).max() < 1e-4
    assert [list(k.signatures) for k in (solver._nearest, solver._frame_into)] == compiled


@needs_erd
def test_eaik_prepared_call_answers_as_solve_within_each_with_its_own_inputs():
    pytest.importorskip("eaik")
    from ikbench.baselines.eaik_ik import EaikSolver
    from ikbench.studies.ik import goal_arrays

    robot, solver = _prepared(EaikSolver)
    cases = list(_cases(robot, 30, 5))
    far = cases[0][0].copy()
    far[:3, 3] *= 100.0  # out of reach: EAIK says no
    cases.append((far, cases[0][1]))
    # every call prepared before any runs: each keeps its own frame and start
    calls = [solver.prepared_call(q_init[None], *goal_arrays(T), math.inf)
             for T, q_init in cases]
    for (T, q_init), call in zip(cases, calls):
        expected = solver.solve_within(np.ascontiguousarray(q_init[None]), *goal_arrays(T),
                                       math.inf)
        got = call()
        assert (got.ok, got.iterations, got.attempts) == (expected.ok, expected.iterations,
                                                          expected.attempts)
        np.testing.assert_array_equal(got.q, expected.q)
    assert not calls[-1]().ok and sum(call().ok for call in calls) == 30
    with pytest.raises(ValueError, match="expected starts"):
        solver.prepared_call(np.zeros((1, 5)), *goal_arrays(cases[0][0]), math.inf)
