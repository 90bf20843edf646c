"""ours-lm's torch backend against the numpy solver: kinematics, Jacobians, the block solve,
whole solves in float64 and float32, batching, the CLI (on the CPU: CI has no GPU)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.kinematics.chain_torch import TorchChainKinematics, torch_chain_kinematics
from ikbench.core.losses import PAPER_WEIGHTS, TERMS, objective, parse_weights
from ikbench.core.robot import load_robot
from ikbench.core.task import line_task, line_tasks
from ikbench.methods.ours_lm import LMSettings, OursLM, Problem, evaluate, solve_batch
from ikbench.methods.ours_lm import torch_backend as tb
from ikbench.methods.ours_lm.linalg import solve_normal_equations
from ikbench.studies.batch import sample_touch_poses
from tests.conftest import central_differences

DATA = Path(__file__).parent / "data"
#: float64 losses of the torch backend agree with the numpy solver's to this (relative)
LOSS_RTOL = 1e-6
#: float32 solves reach the float64 losses to within this (relative)
FLOAT32_LOSS_RTOL = 1e-5
TORCH = LMSettings(device="cpu")
TORCH32 = LMSettings(device="cpu", dtype="float32")


@pytest.fixture(scope="module", autouse=True)
def one_torch_thread():
    """As the CLI runs it (--threads 1): on a busy 2-core machine more threads only wait."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def paper_tasks(robot, paper_targets):
    return line_tasks(robot, paper_targets)


@pytest.fixture(scope="module")
def random_tasks(robot, paper_targets):
    """200 reachable touch poses from the batch sampler (seed 3), n = 50."""
    touch, _ = sample_touch_poses(robot, paper_targets.start_pose, 200, seed=3)
    return [line_task(robot, paper_targets.start_pose, pose, 50, str(k))
            for k, pose in enumerate(touch)]


@pytest.fixture(scope="module")
def random_solves(robot, random_tasks):
    """numpy, torch float64 and torch float32 solves of the random batch."""
    return {name: solve_batch(robot, random_tasks, settings)
            for name, settings in (("numpy", LMSettings()), ("float64", TORCH),
                                   ("float32", TORCH32))}


# ----- kinematics ---------------------------------------------------------------------------
@pytest.mark.parametrize("robot_spec", ["nico", "unaligned"])
def test_torch_chain_equals_numpy_chain(robot, robot_spec):
    """Revolute, prismatic, continuous and unaligned axes: the same four outputs."""
    arm = robot if robot_spec == "nico" else load_robot(DATA / "unaligned_arm.urdf", "tool")
    poses = np.random.default_rng(1).uniform(arm.sample_lower, arm.sample_upper, (50, arm.dof))
    reference = arm.chain_kinematics()(poses)
    ours = TorchChainKinematics(arm)(torch.as_tensor(poses))
    for a, b in zip(reference, ours):
        np.testing.assert_allclose(b.numpy(), a, rtol=0, atol=1e-12)


def test_torch_jacobians_match_finite_differences(robot):
    kin = torch_chain_kinematics(robot, torch.float64)
    poses = np.random.default_rng(2).uniform(robot.lower, robot.upper,
                                             (5, robot.dof))
    _, _, j_point, j_dir = kin(torch.as_tensor(poses))
    for k, jacobian in ((0, j_point), (1, j_dir)):  # m/deg, 1/deg
        numeric = central_differences(lambda p, k=k: kin(torch.as_tensor(p), False)[k], poses, 1e-6)
        np.testing.assert_allclose(jacobian, numeric, atol=1e-8)


def test_torch_kinematics_are_cached_per_dtype_and_device(robot):
    a = torch_chain_kinematics(robot, torch.float32, "cpu")
    assert torch_chain_kinematics(robot, torch.float32, "cpu") is a
    assert torch_chain_kinematics(robot, torch.float64, "cpu") is not a
    point, _, _, _ = a(torch.zeros(2, robot.dof, dtype=torch.float32))
    assert point.dtype == torch.float32


# ----- one evaluation and one linear solve --------------------------------------------------
def test_evaluation_equals_numpy(robot, paper_tasks):
    weights = [PAPER_WEIGHTS, parse_weights("c0=100,c1=3,c6=0.5")] * 4
    tasks = [*paper_tasks, paper_tasks[0]]
    problem = Problem.from_tasks(robot, tasks, weights[:len(tasks)])
    poses = np.stack([np.linspace(t.required.start_pose, t.required.end_pose, t.goal.steps + 1)
                      for t in tasks])
    poses += np.random.default_rng(0).normal(0.0, 3.0, poses.shape)
    poses = np.clip(poses, robot.lower, robot.upper)
    reference = evaluate(robot.chain_kinematics(), problem, poses)
    ours = tb.evaluate(torch_chain_kinematics(robot), tb.TorchProblem.of(
        problem, torch.float64, "cpu"), torch.as_tensor(poses))
    for name in ("loss", "terms", "gradient", "diagonal", "coupling"):
        expected = getattr(reference, name)
        np.testing.assert_allclose(getattr(ours, name).numpy(), expected, rtol=1e-12,
                                   atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("method", ["cyclic", "thomas"])
@pytest.mark.parametrize("n_poses", [6, 7, 51])
def test_block_solve_equals_numpy_and_flags_an_indefinite_system(method, n_poses):
    rng = np.random.default_rng(4)
    b, k = 4, 7
    a = rng.normal(size=(b, n_poses, k, k))
    diagonal = a @ a.swapaxes(-1, -2) + 3 * np.eye(k)
    diagonal[3, 2] = -np.eye(k)                 # trajectory 3: not positive definite
    coupling = np.array([0.5, 1.0, 2.0, 1.0])
    rhs = rng.normal(size=(b, n_poses, k))
    free = rng.random((b, n_poses, k)) > 0.2
    expected, expected_ok = solve_normal_equations(diagonal, coupling, rhs, free)
    x, ok = tb.solve_normal_equations(*(torch.as_tensor(v) for v in
                                        (diagonal, coupling, rhs, free)), method=method)
    assert ok.tolist() == expected_ok.tolist() == [True, True, True, False]
    np.testing.assert_allclose(x.numpy(), expected, rtol=1e-9, atol=1e-10)
    assert not x[3].any()                       # no step where the solve failed


# ----- whole solves -------------------------------------------------------------------------
def test_paper_targets_float64_equal_numpy(robot, paper_tasks):
    reference = solve_batch(robot, paper_tasks)
    ours = solve_batch(robot, paper_tasks, TORCH)
    np.testing.assert_allclose(ours.loss, reference.loss, rtol=LOSS_RTOL)
    np.testing.assert_allclose(ours.terms, reference.terms, rtol=1e-5, atol=1e-9)
    assert ours.iterations.tolist() == reference.iterations.tolist()
    assert ours.converged.all() and robot.within_limits(ours.poses, tol_deg=0.0)
    for k, task in enumerate(paper_tasks):       # the loss is the objective of the poses
        assert ours.loss[k] == pytest.approx(objective(robot, task, ours.poses[k])[0],
                                             rel=1e-12)


def test_random_batch_float64_equals_numpy(robot, random_solves):
    reference, ours = random_solves["numpy"], random_solves["float64"]
    np.testing.assert_allclose(ours.loss, reference.loss, rtol=LOSS_RTOL)
    assert np.abs(ours.iterations - reference.iterations).max() <= 1
    assert np.mean(ours.iterations == reference.iterations) >= 0.99
    assert ours.converged.tolist() == reference.converged.tolist()


def test_random_batch_float32_converges_to_the_float64_losses(robot, random_solves):
    reference, ours = random_solves["numpy"], random_solves["float32"]
    assert ours.converged.all()
    np.testing.assert_allclose(ours.loss, reference.loss, rtol=FLOAT32_LOSS_RTOL)
    assert ours.loss.dtype == np.float64 and ours.poses.dtype == np.float64
    assert robot.within_limits(ours.poses, tol_deg=0.0)


def test_a_trajectory_does_not_depend_on_its_batch(robot, random_tasks):
    tasks = random_tasks[:6]
    weights = [PAPER_WEIGHTS, parse_weights("c0=100")] * 3
    batch = solve_batch(robot, tasks, TORCH, weights=weights)
    for k in (0, 3):
        alone = solve_batch(robot, [tasks[k]], TORCH, weights=weights[k])
        np.testing.assert_allclose(batch.poses[k], alone.poses[0], atol=1e-10)
        assert batch.iterations[k] == alone.iterations[0]


def test_letter_task_float64_equals_numpy(robot, paper_targets):
    from ikbench.core.task import build_tasks

    tasks = build_tasks(robot, paper_targets, "letter:L", 30)
    settings = {"weights": None, "max_iterations": 40}
    reference = solve_batch(robot, tasks, LMSettings(**settings))
    ours = solve_batch(robot, tasks, LMSettings(**settings, device="cpu"))
    np.testing.assert_allclose(ours.loss, reference.loss, rtol=LOSS_RTOL)
    assert ours.iterations.tolist() == reference.iterations.tolist()


# ----- settings and the command line ----------------------------------------------------------
@pytest.mark.parametrize("options, message", [
    ({"device": "gpu"}, "--device: 'gpu' is not cpu, cuda or cuda:N"),
    ({"dtype": "float32"}, "--dtype float32: the numpy solver (no --device) computes in "
                           "float64"),
    ({"dtype": "float16", "device": "cpu"}, "--dtype: 'float16' is not one of float64, float32"),
    ({"device": "cpu", "kinematics": "pinocchio"}, "--lm-kinematics pinocchio: the torch "
                                                   "backend"),
])
def test_settings_refuse_what_the_backend_cannot_do(options, message):
    with pytest.raises(InputError, match="^" + message.replace("(", r"\(").replace(")", r"\)")):
        OursLM(**options)


def test_run_cli_device_cpu_gives_the_numpy_losses(tmp_path):
    common = ["run", "--method", "ours-lm", "--only", "1,7", "--quiet"]
    assert main([*common, "--output", str(tmp_path / "numpy")]) == 0
    assert main([*common, "--device", "cpu", "--output", str(tmp_path / "torch")]) == 0
    reference = pd.read_csv(tmp_path / "numpy" / "ours-lm" / "table.csv")
    ours = pd.read_csv(tmp_path / "torch" / "ours-lm" / "table.csv")
    np.testing.assert_allclose(ours["loss"], reference["loss"], rtol=LOSS_RTOL)
    assert list(ours["trajectory"]) == [1, 7]


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")
def test_run_cli_device_cuda_without_cuda_is_one_line_exit_2(tmp_path, capsys):
    code = main(["run", "--method", "ours-lm", "--device", "cuda", "--output", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("ikbench: error: --device cuda: CUDA is not available here")
    assert err.count("\n") == 1 and not list(tmp_path.iterdir())


def test_float32_tolerance_floor():
    assert tb.stopping_tolerance(TORCH32) == tb.FLOAT32_TOLERANCE
    assert tb.stopping_tolerance(TORCH) == TORCH.tolerance
    assert set(TERMS) == set(PAPER_WEIGHTS)
