"""ours-lm's numba backend equals the numpy solver (losses, poses, iterations), backend choice,
threads, and the base install without numba (no timed assertions)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.losses import PAPER_WEIGHTS, parse_weights, resolve_weights
from ikbench.core.robot import load_robot
from ikbench.core.targets import load_targets
from ikbench.core.task import line_tasks
from ikbench.methods.ours_lm import LMSettings, OursLM, compiling, cpu_backend, solve_batch
from ikbench.methods.ours_lm import devices as devices_module
from ikbench.studies.batch import sample_touch_poses
from ikbench.studies.dataset_shard import line_tasks as sampled_line_tasks

pytest.importorskip("numba")

RTOL = 1e-6


def _both(robot, tasks, weights=None, **kwargs):
    weights = dict(PAPER_WEIGHTS) if weights is None else weights
    numpy = solve_batch(robot, tasks, LMSettings(backend="numpy", **kwargs), weights=weights)
    numba = solve_batch(robot, tasks, LMSettings(backend="numba", **kwargs), weights=weights)
    return numpy, numba


def _assert_equal(numpy, numba, rtol=RTOL):
    rel = np.abs(numba.loss - numpy.loss) / np.abs(numpy.loss)
    assert rel.max() < rtol
    assert np.allclose(numba.terms, numpy.terms, rtol=1e-5, atol=1e-9)
    assert np.array_equal(numba.converged, numpy.converged)
    assert np.abs(numba.iterations - numpy.iterations).max() <= 1
    assert np.abs(numba.poses - numpy.poses).max() < 1e-4


def _sampled(robot, count, steps, seed=0):
    targets = load_targets(None, robot)
    touch, _ = sample_touch_poses(robot, targets.start_pose, count, seed=seed)
    tasks, _, _ = sampled_line_tasks(robot, targets.start_pose, touch, steps)
    return tasks


def test_the_paper_seven_equal_numpy(robot):
    tasks = line_tasks(robot, load_targets(None, robot))
    numpy, numba = _both(robot, tasks)
    _assert_equal(numpy, numba)
    assert numba.converged.all()
    assert np.array_equal(numba.iterations, numpy.iterations)


def test_sampled_touch_poses_equal_numpy(robot):
    """A small batch of the sampler's lines (the benchmark's batch of 1000 is the same kind)."""
    tasks = _sampled(robot, 60, 30)
    numpy, numba = _both(robot, tasks)
    _assert_equal(numpy, numba)
    lower, upper = robot.lower, robot.upper
    assert ((numba.poses >= lower) & (numba.poses <= upper)).all()


def test_joint_limits_active_and_odd_weights_equal_numpy(robot):
    """Weights that pull poses onto their bounds (the active set), and every term on."""
    tasks = _sampled(robot, 12, 12, seed=3)
    weights = parse_weights("c0=5,c1=200,c2=1,c3=1,c4=3,c5=3,c6=0.01")
    numpy, numba = _both(robot, tasks, weights=weights, max_iterations=40)
    _assert_equal(numpy, numba)
    at_bound = np.isclose(numpy.poses, robot.lower) \
        | np.isclose(numpy.poses, robot.upper)
    assert at_bound.any()


def test_per_task_weights_and_reference_pose_tasks(robot):
    """Letters start from a reference pose and have their own weights (c2 = c3 = 0)."""
    from ikbench.core.letters import PAPER_START_POSE_DEG
    from ikbench.core.task import letter_task

    tasks = [letter_task(robot, c, PAPER_START_POSE_DEG, steps=20) for c in "LO"]
    weights = [resolve_weights(None, t) for t in tasks]
    numpy, numba = _both(robot, tasks, weights=weights)
    _assert_equal(numpy, numba)


def test_an_eight_joint_robot_with_a_prismatic_joint():
    robot = load_robot("fetch")
    tasks = line_tasks(robot, load_targets(None, robot).with_steps(15))
    numpy, numba = _both(robot, tasks)
    _assert_equal(numpy, numba)


def test_thread_count_one_per_sixteen_trajectories_at_most_threads():
    from ikbench.methods.ours_lm.compiled import PER_THREAD, max_threads, thread_count

    assert thread_count(7) == 1 and thread_count(1) == 1
    assert thread_count(2 * PER_THREAD, 1) == 1
    assert thread_count(10_000, 2) == min(2, max_threads())
    assert thread_count(10_000) == max_threads()


def test_threads_and_batching_do_not_change_the_numbers(robot):
    tasks = _sampled(robot, 40, 8, seed=5)
    w = dict(PAPER_WEIGHTS)
    one = solve_batch(robot, tasks, LMSettings(backend="numba", threads=1), weights=w)
    two = solve_batch(robot, tasks, LMSettings(backend="numba", threads=2), weights=w)
    alone = solve_batch(robot, tasks[33:34], LMSettings(backend="numba"), weights=w)
    assert np.array_equal(one.poses, two.poses)
    assert np.array_equal(one.loss, two.loss) and np.array_equal(one.iterations, two.iterations)
    assert np.array_equal(alone.poses[0], one.poses[33])


def test_initial_poses_and_iteration_cap(robot):
    tasks = _sampled(robot, 4, 10, seed=2)
    rng = np.random.default_rng(0)
    initial = np.linspace(tasks[0].required.start_pose, tasks[0].required.end_pose, 11)[None] \
        + rng.normal(0.0, 3.0, (4, 11, robot.dof))
    w = dict(PAPER_WEIGHTS)
    numpy = solve_batch(robot, tasks, LMSettings(backend="numpy", max_iterations=3),
                        weights=w, initial=initial)
    numba = solve_batch(robot, tasks, LMSettings(backend="numba", max_iterations=3),
                        weights=w, initial=initial)
    assert (numba.iterations == 3).all() and not numba.converged.any()
    assert np.allclose(numba.loss, numpy.loss, rtol=RTOL)


def test_ours_lm_method_runs_the_backend_it_is_given(robot):
    tasks = line_tasks(robot, load_targets(None, robot))[:2]
    by_numpy = OursLM(backend="numpy").solve_many(robot, tasks)
    method = OursLM(backend="numba", threads=1)
    method.prepare(robot)
    by_numba = method.solve_many(robot, tasks)
    for a, b in zip(by_numpy, by_numba):
        assert abs(a.loss - b.loss) <= RTOL * a.loss and b.converged


def test_auto_is_numba_when_installed_else_numpy(monkeypatch):
    assert cpu_backend(LMSettings()) == "numba"
    assert cpu_backend(LMSettings(backend="numpy")) == "numpy"
    assert cpu_backend(LMSettings(linear_solver="thomas")) == "numpy"
    assert cpu_backend(LMSettings(kinematics="pinocchio")) == "numpy"
    monkeypatch.setattr(devices_module, "numba_installed", lambda: False)
    monkeypatch.setattr(devices_module, "numba_unavailable", lambda: "numba is not installed")
    assert cpu_backend(LMSettings()) == "numpy"
    with pytest.raises(InputError, match=r"numba is not installed; pip install -c constr"):
        LMSettings(backend="numba")


@pytest.mark.parametrize("kwargs, message", [
    ({"backend": "numba", "device": "cpu"}, "--lm-backend numba: runs on the CPU"),
    ({"backend": "numba", "kinematics": "pinocchio"}, "--lm-kinematics pinocchio: the numba"),
    ({"backend": "numba", "linear_solver": "thomas"}, "--lm-linear-solver thomas: the numba"),
    ({"backend": "jax"}, "--lm-backend: 'jax' is not one of auto, numpy, numba"),
    ({"threads": 0}, "--lm-threads: 0 must be an integer >= 1"),
])
def test_bad_settings_are_one_line_errors(kwargs, message):
    with pytest.raises(InputError, match=message):
        LMSettings(**kwargs)


def test_cli_flags(tmp_path, capsys):
    assert main(["run", "--method", "ours-lm", "--lm-backend", "fortran",
                 "--output", str(tmp_path / "r")]) == 2
    assert "fortran" in capsys.readouterr().err


def test_base_install_without_numba_falls_back_to_numpy():
    """numba made unimportable: the default settings run the numpy solver."""
    code = (
        "import sys; sys.modules['numba'] = None\n"
        "from ikbench.core.robot import load_robot\n"
        "from ikbench.core.targets import load_targets\n"
        "from ikbench.core.task import line_tasks\n"
        "from ikbench.methods.ours_lm import LMSettings, cpu_backend, solve_batch\n"
        "robot = load_robot()\n"
        "tasks = line_tasks(robot, load_targets(None, robot).with_steps(8))[:2]\n"
        "assert cpu_backend(LMSettings()) == 'numpy'\n"
        "r = solve_batch(robot, tasks)\n"
        "r = solve_batch(robot, tasks)\n"
        "assert r.converged.all() and 'ikbench.methods.ours_lm.compiled' not in sys.modules\n"
        "from ikbench.methods.ours_lm import OursLM\n"
        "print(OursLM().runtime())\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == ("{'backend': 'numpy', 'threads': 1, "
                                  "'numba': 'numba is not installed'}")
    said = [line for line in out.stderr.splitlines() if "numba" in line]  # once per process
    assert said == ["ours-lm runs its numpy reference, not the compiled solver: numba cannot "
                    "import (numba is not installed); pip install -c constraints.txt -e ."]


def test_compiled_forward_kinematics_equal_the_numpy_chain(robot):
    from ikbench.methods.ours_lm.compiled import forward

    rng = np.random.default_rng(0)
    poses = rng.uniform(robot.lower, robot.upper, (301, robot.dof))
    point_m, direction, _, _ = robot.chain_kinematics()(poses, False)
    mine_point, mine_direction = forward(robot, poses, threads=2)
    np.testing.assert_allclose(mine_point, point_m, rtol=0, atol=1e-14)
    np.testing.assert_allclose(mine_direction, direction, rtol=0, atol=1e-13)


def test_solve_problem_equals_solve_batch_on_both_cpu_backends(robot):
    from ikbench.methods.ours_lm import Problem, initial_poses, solve_problem

    tasks = _sampled(robot, 5, 10, seed=4)
    w = dict(PAPER_WEIGHTS)
    problem, initial = Problem.from_tasks(robot, tasks, w), initial_poses(robot, tasks)
    for backend in ("numpy", "numba"):
        settings = LMSettings(backend=backend)
        a = solve_batch(robot, tasks, settings, weights=w)
        b = solve_problem(robot, problem, initial, settings)
        assert np.array_equal(a.poses, b.poses) and np.array_equal(a.loss, b.loss)


def test_the_compiled_sine_and_cosine_are_within_an_ulp_of_numpy():
    from numba import njit

    from ikbench.methods.ours_lm.compiled import _sin_cos

    @njit
    def both(angles, s, c):
        for i in range(len(angles)):
            s[i], c[i] = _sin_cos(angles[i])

    rng = np.random.default_rng(1)
    angles = np.concatenate([rng.uniform(-20.0, 20.0, 20000), np.pi / 4 * np.arange(-16, 17),
                             [0.0, 1e-300, -1e-8]])
    s, c = np.empty_like(angles), np.empty_like(angles)
    both(angles, s, c)
    assert np.abs(s - np.sin(angles)).max() <= 2.3e-16
    assert np.abs(c - np.cos(angles)).max() <= 2.3e-16


def test_compiling_is_said_once_when_the_cache_is_empty(tmp_path):
    """An empty numba cache: one progress line before the kernels compile, once per process
    (nothing is compiled here: the check reads numba's cache index only)."""
    code = ("from ikbench.methods.ours_lm import compiled, path_search\n"
            "from ikbench.methods.ours_lm.compiling import say_if_compiling\n"
            "print(say_if_compiling(path_search), say_if_compiling(compiled))\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "True"]
    assert [line for line in out.stderr.splitlines() if "compiling" in line] == [
        compiling.COMPILING]


def test_compiling_is_not_said_when_the_kernels_are_loaded(robot):
    from ikbench.methods.ours_lm import compiled

    compiled.warm_up(robot)
    assert not compiling.say_if_compiling(compiled)
