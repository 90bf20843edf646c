"""ours-lm: the residual form equals the objective, analytic Jacobians, batching, limits, CLI."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.kinematics.chain import ChainKinematics, pinocchio_kinematics
from ikbench.core.losses import PAPER_WEIGHTS, TERMS, objective, parse_weights
from ikbench.core.task import line_task
from ikbench.methods import get_method
from ikbench.methods.ours import AdamSettings, optimise
from ikbench.methods.ours_lm import (
    LMSettings,
    OursLM,
    Problem,
    evaluate,
    initial_poses,
    solve_batch,
)
from ikbench.methods.ours_lm.linalg import block_matvec, solve_normal_equations
from tests.conftest import PAPER_START, central_differences
from tests.test_kinematics import paper_fk_cm

TOUCH = {"1": [33, 39, 25, 134, 102, 77, -168], "3": [57, 33, 40, 134, 80, 36, -159],
         "7": [34, 17, 39, 107, 106, 78, -180]}


def _task(robot, key="1", n=10):
    return line_task(robot, PAPER_START, TOUCH[key], n, key)


def _random_poses(robot, task, seed=0, noise=4.0):
    rng = np.random.default_rng(seed)
    poses = np.linspace(task.required.start_pose, task.required.end_pose, task.goal.steps + 1)
    poses = poses + rng.normal(0.0, noise, poses.shape)
    return np.clip(poses, robot.lower, robot.upper)


def _dense_residuals(robot, task, poses, weights=PAPER_WEIGHTS):
    """The residual vector r (loss = |r|^2) written out directly, with the tests' own FK."""
    n_poses, dof = poses.shape
    fk = [paper_fk_cm(p) for p in poses]
    points, dirs = np.array([f[0] for f in fk]), np.array([f[1] for f in fk])
    goals, d = task.goal.points_mm / 10.0, task.goal.directions
    c = [weights[t] for t in TERMS]
    return np.concatenate([
        np.sqrt(c[0] / (3 * n_poses)) * (points - goals).ravel(),
        np.sqrt(c[1] / (2 * n_poses)) * (dirs - d).ravel(),
        np.sqrt(c[2]) * (poses[0] - task.required.start_pose),
        np.sqrt(c[3]) * (poses[-1] - task.required.end_pose),
        np.sqrt(c[4]) * (points[0] - goals[0]),
        np.sqrt(c[5]) * (points[-1] - goals[-1]),
        np.sqrt(c[6] / ((n_poses - 1) * dof)) * np.diff(poses, axis=0).ravel(),
    ])


@pytest.mark.parametrize("weights", [PAPER_WEIGHTS, parse_weights("c0=100,c1=3,c6=0.5")])
def test_loss_equals_objective_and_sum_of_squared_residuals(robot, weights):
    task = _task(robot, "3", n=8)
    poses = _random_poses(robot, task, seed=3)
    problem = Problem.from_tasks(robot, [task], weights)
    ev = evaluate(ChainKinematics(robot), problem, poses[None])
    expected, terms = objective(robot, task, poses, weights)
    assert ev.loss[0] == pytest.approx(expected, rel=1e-12)
    assert ev.terms[0] == pytest.approx([terms[t] for t in TERMS], rel=1e-10, abs=1e-14)
    r = _dense_residuals(robot, task, poses, weights)
    assert float(r @ r) == pytest.approx(expected, rel=1e-9)


def test_numpy_kinematics_match_pinocchio_frame_jacobian(robot):
    poses = np.random.default_rng(1).uniform(robot.lower, robot.upper,
                                             (20, robot.dof))
    ours = ChainKinematics(robot)(poses)
    reference = pinocchio_kinematics(robot, poses)
    for a, b in zip(ours, reference):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-11)


def test_jacobian_matches_finite_differences(robot):
    poses = np.random.default_rng(2).uniform(robot.lower, robot.upper,
                                             (5, robot.dof))
    kin = ChainKinematics(robot)
    _, _, j_point, j_dir = kin(poses)
    for k, jacobian in ((0, j_point), (1, j_dir)):  # m/deg, 1/deg
        numeric = central_differences(lambda p, k=k: kin(p, False)[k], poses, 1e-6)
        np.testing.assert_allclose(jacobian, numeric, atol=1e-8)


def test_gradient_and_gauss_newton_matrix_match_finite_differences(robot):
    task = _task(robot, "1", n=6)
    poses = _random_poses(robot, task, seed=5)
    problem = Problem.from_tasks(robot, [task], PAPER_WEIGHTS)
    ev = evaluate(ChainKinematics(robot), problem, poses[None])
    h = 1e-4  # central differences: truncation ~h^2, rounding ~1e-16 * loss / h
    flat = poses.ravel()
    grad_fd = np.empty(flat.size)
    jac_fd = np.empty((_dense_residuals(robot, task, poses).size, flat.size))
    for k in range(flat.size):
        plus, minus = flat.copy(), flat.copy()
        plus[k] += h
        minus[k] -= h
        grad_fd[k] = (objective(robot, task, plus.reshape(poses.shape))[0]
                      - objective(robot, task, minus.reshape(poses.shape))[0]) / (2 * h)
        jac_fd[:, k] = (_dense_residuals(robot, task, plus.reshape(poses.shape))
                        - _dense_residuals(robot, task, minus.reshape(poses.shape))) / (2 * h)
    # dL/dp = 2 J^T r
    np.testing.assert_allclose(2 * ev.gradient[0].ravel(), grad_fd, rtol=1e-6, atol=1e-6)
    # the block-tridiagonal J^T J times any vector equals the dense one
    x = np.random.default_rng(0).normal(size=poses.shape)
    dense = jac_fd.T @ (jac_fd @ x.ravel())
    np.testing.assert_allclose(block_matvec(ev, x[None])[0].ravel(), dense, rtol=1e-5,
                               atol=1e-6)


@pytest.mark.parametrize("solver", ["banded", "thomas"])
def test_block_tridiagonal_solvers_equal_dense_solve(solver):
    rng = np.random.default_rng(4)
    b, n_poses, k = 3, 6, 7
    a = rng.normal(size=(b, n_poses, k, k))
    diagonal = a @ a.swapaxes(-1, -2) + 3 * np.eye(k)
    coupling = np.array([0.5, 1.0, 2.0])
    rhs = rng.normal(size=(b, n_poses, k))
    free = rng.random((b, n_poses, k)) > 0.2
    x, ok = solve_normal_equations(diagonal, coupling, rhs, free, solver)
    assert ok.all()
    for t in range(b):
        dense = np.zeros((n_poses * k, n_poses * k))
        for i in range(n_poses):
            dense[i * k:(i + 1) * k, i * k:(i + 1) * k] = diagonal[t, i]
            if i:
                dense[i * k:(i + 1) * k, (i - 1) * k:i * k] = -coupling[t] * np.eye(k)
                dense[(i - 1) * k:i * k, i * k:(i + 1) * k] = -coupling[t] * np.eye(k)
        f = free[t].ravel()
        expected = np.zeros(n_poses * k)
        expected[f] = np.linalg.solve(dense[np.ix_(f, f)], rhs[t].ravel()[f])
        np.testing.assert_allclose(x[t].ravel(), expected, rtol=1e-9, atol=1e-10)


def test_batched_equals_one_at_a_time(robot):
    tasks = [_task(robot, key, n=10) for key in TOUCH]
    batch = solve_batch(robot, tasks)
    for k, task in enumerate(tasks):
        single = solve_batch(robot, [task])
        np.testing.assert_allclose(batch.poses[k], single.poses[0], atol=1e-10)
        assert batch.loss[k] == pytest.approx(single.loss[0], rel=1e-12)
        assert batch.iterations[k] == single.iterations[0]


def test_per_task_weights_equal_separate_solves(robot):
    task = _task(robot, "1", n=10)
    strong = parse_weights("c0=100")
    both = solve_batch(robot, [task, task], weights=[PAPER_WEIGHTS, strong])
    alone = solve_batch(robot, [task], weights=strong)
    np.testing.assert_allclose(both.poses[1], alone.poses[0], atol=1e-10)
    assert both.loss[0] != pytest.approx(both.loss[1])


def test_limits_respected_and_kkt_at_the_bound(robot):
    # with n = 50, r_arm_x runs into its upper limit 70 in the middle of trajectory 1
    task = _task(robot, "1", n=50)
    result = solve_batch(robot, [task])
    poses = result.poses[0]
    assert robot.within_limits(poses, tol_deg=0.0)
    at_upper = poses >= robot.upper
    assert at_upper[:, 2].sum() >= 2 and result.converged[0]
    problem = Problem.from_tasks(robot, [task], PAPER_WEIGHTS)
    gradient = evaluate(ChainKinematics(robot), problem, poses[None]).gradient[0]
    assert np.all(gradient[at_upper] < 0)            # the loss would fall beyond the limit
    assert np.max(np.abs(gradient[~at_upper])) < 1e-4 * np.max(np.abs(gradient[at_upper]))


def test_kinematics_and_linear_solver_options_agree(robot):
    task = _task(robot, "3", n=8)
    reference = solve_batch(robot, [task])
    for settings in (LMSettings(kinematics="pinocchio"), LMSettings(linear_solver="thomas")):
        other = solve_batch(robot, [task], settings)
        assert other.loss[0] == pytest.approx(reference.loss[0], rel=1e-9)


def test_lm_reaches_a_loss_no_higher_than_adam(robot):
    task = _task(robot, "1", n=10)
    adam = optimise(robot, task, AdamSettings(max_iterations=150, dtype="float64",
                                              init="interpolation"))
    solution = OursLM().solve(robot, task)
    lm_loss, _ = objective(robot, task, solution.poses)
    adam_loss, _ = objective(robot, task, adam.poses)
    assert solution.loss == pytest.approx(lm_loss, rel=1e-12)
    assert lm_loss <= adam_loss
    assert solution.converged and solution.iterations < 50
    initial, _ = objective(robot, task, initial_poses(robot, [task])[0])
    assert lm_loss < initial


def test_method_registered_and_options_validated():
    assert get_method("ours-lm") is OursLM
    with pytest.raises(InputError, match="--lm-tolerance"):
        OursLM(tolerance=-1.0)
    with pytest.raises(InputError, match="--lm-max-iterations"):
        OursLM(max_iterations=0)
    with pytest.raises(InputError, match="weights"):
        OursLM(weights="c9=1")


def test_run_cli_with_ours_lm(tmp_path, capsys, robot):
    code = main(["run", "--method", "ours-lm", "--only", "3", "--steps", "10", "--weights",
                 "c0=2", "--output", str(tmp_path), "--quiet"])
    assert code == 0
    assert (tmp_path / "ours-lm" / "trajectory_3.csv").is_file()
    assert "written to" in capsys.readouterr().out


def test_run_cli_bad_option_one_line_exit_2(tmp_path):
    exe = [sys.executable, "-m", "ikbench.cli", "run", "--method", "ours-lm",
           "--lm-tolerance", "-3", "--output", str(tmp_path)]
    proc = subprocess.run(exe, capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip() == "ikbench: error: --lm-tolerance: -3.0 must be a positive number"


# ----- shapes: letters, polylines, splines (no start/end pose) ----------------------------------
def test_letter_starts_at_the_reference_pose_with_the_letter_weights(robot):
    from ikbench.core.letters import LETTER_WEIGHTS, PAPER_START_POSE_DEG
    from ikbench.core.task import letter_task

    task = letter_task(robot, "P", PAPER_START_POSE_DEG, steps=20)
    start = initial_poses(robot, [task])[0]
    expected = np.clip(PAPER_START_POSE_DEG, robot.lower, robot.upper)
    np.testing.assert_allclose(start, np.repeat(expected[None], 21, axis=0))
    assert OursLM().settings_for(task).weights == LETTER_WEIGHTS
    assert OursLM(weights="c0=100").settings_for(task).weights == {**LETTER_WEIGHTS,
                                                                   "L0": 100.0}
    full = {"L0": 2.0, "L1": 0, "L2": 0, "L3": 0, "L4": 0, "L5": 0, "L6": 1.0}
    assert OursLM(weights=full).settings_for(task).weights == full   # a dict is complete
    line = _task(robot, "1", n=20)
    assert OursLM(weights="c0=100").settings_for(line).weights == parse_weights("c0=100")

    solution = OursLM().solve(robot, task)
    loss, _ = objective(robot, task, solution.poses, LETTER_WEIGHTS)
    assert solution.loss == pytest.approx(loss, rel=1e-9)
    assert solution.info["weights"] == "c0=1,c1=50,c2=0,c3=0,c4=0,c5=0,c6=1"
    assert solution.converged and robot.within_limits(solution.poses, tol_deg=0.0)
    assert loss < 0.5 * objective(robot, task, start, LETTER_WEIGHTS)[0]
    # the paper's weights would add the start/end point terms (c4, c5): another optimum
    paper, _ = objective(robot, task, solution.poses, PAPER_WEIGHTS)
    assert paper > loss


def test_letter_loss_no_higher_than_adam_and_c0_draws_closer(robot):
    from ikbench.core.letters import LETTER_WEIGHTS, PAPER_START_POSE_DEG
    from ikbench.core.metrics import shape_metrics
    from ikbench.core.task import letter_task
    from ikbench.methods.ours import Ours

    task = letter_task(robot, "L", PAPER_START_POSE_DEG, steps=12)
    adam = Ours(stop="none", max_iterations=300, dtype="float64").solve(robot, task)
    lm = OursLM().solve(robot, task)
    assert lm.loss <= objective(robot, task, adam.poses, LETTER_WEIGHTS)[0]
    close = OursLM(weights="c0=100").solve(robot, task)
    assert close.info["weights"] == "c0=100,c1=50,c2=0,c3=0,c4=0,c5=0,c6=1"
    near = shape_metrics(robot, task, close.poses)["point_error_mean_mm"]
    assert near < 0.2 * shape_metrics(robot, task, lm.poses)["point_error_mean_mm"]


def test_line_and_letter_in_one_batch_each_with_its_own_weights(robot):
    from ikbench.core.letters import PAPER_START_POSE_DEG
    from ikbench.core.task import letter_task

    line, letter = _task(robot, "3", n=12), letter_task(robot, "V", PAPER_START_POSE_DEG, 12)
    method = OursLM(weights="c0=10")
    both = method.solve_many(robot, [line, letter])
    for task, solution in zip((line, letter), both):
        alone = solve_batch(robot, [task], weights=method.settings_for(task).weights)
        np.testing.assert_allclose(solution.poses, alone.poses[0], atol=1e-10)
    assert both[0].info["weights"] == "c0=10,c1=50,c2=5,c3=100,c4=10,c5=200,c6=1"
    assert both[1].info["weights"] == "c0=10,c1=50,c2=0,c3=0,c4=0,c5=0,c6=1"


def test_polyline_starts_at_its_reference_pose_and_a_bare_task_is_refused(robot, tmp_path):
    from dataclasses import replace

    from ikbench.core.task import file_task

    tip = robot.fk(PAPER_START).point_mm[0]
    path = tmp_path / "zig.csv"
    path.write_text("\n".join(",".join(f"{v:.3f}" for v in tip + offset) for offset in
                          ([0, 0, 0], [0, -40, 30], [0, -80, 0])) + "\n")
    task = file_task("polyline", path, 10, reference_pose=PAPER_START)
    np.testing.assert_allclose(initial_poses(robot, [task])[0, 5], PAPER_START)
    solution = OursLM().solve(robot, task)
    assert solution.loss == pytest.approx(objective(robot, task, solution.poses)[0],
                                          rel=1e-9)
    with pytest.raises(InputError, match="'zig': ours-lm needs a start and an end pose or a "
                                         "reference pose"):
        initial_poses(robot, [replace(task, hints=replace(task.hints, reference_pose=None))])


def test_letters_cli_with_ours_lm(tmp_path, capsys):
    import pandas as pd

    assert main(["letters", "P", "--method", "ours-lm", "--steps", "20", "--weights", "c0=100",
                 "--output", str(tmp_path), "--quiet"]) == 0
    details = pd.read_csv(tmp_path / "ours-lm" / "details.csv")
    assert details["weights"].tolist() == ["c0=100,c1=50,c2=0,c3=0,c4=0,c5=0,c6=1"]
    table = pd.read_csv(tmp_path / "ours-lm" / "table.csv")
    assert table["point_error_mean_mm"].iloc[0] < 1.0
