"""ikbench dataset: Parquet that pandas reads, metrics equal to the metrics module's from the
steps, deterministic shards, resumption, refusals (the Ray executor: test_executors.py)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.losses import PAPER_WEIGHTS, objective
from ikbench.core.metrics import trajectory_metrics
from ikbench.core.task import line_task
from ikbench.studies.dataset import shard_path
from ikbench.studies.dataset_shard import line_problem, line_tasks, shard_seed
from tests.conftest import one_line_error

pytest.importorskip("pyarrow", reason="datasets need pyarrow: pip install 'ikbench[scale]'")

COUNT, SEED, SHARD = 500, 7, 200
COMMAND = ["dataset", "--count", str(COUNT), "--seed", str(SEED), "--shard-size", str(SHARD),
           "--quiet"]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """``ikbench dataset --count 500 --seed 7`` in shards of 200 (3 shards)."""
    out = tmp_path_factory.mktemp("dataset")
    assert main([*COMMAND, "--output", str(out)]) == 0
    return out


def _read(out):
    return pd.read_parquet(out / "steps"), pd.read_parquet(out / "trajectories")


def test_pandas_reads_500_trajectories_of_51_steps(robot, dataset):
    steps, trajectories = _read(dataset)
    assert len(trajectories) == COUNT and trajectories["trajectory"].tolist() == list(range(500))
    assert len(steps) == COUNT * 51
    assert list(steps.columns) == ["trajectory", "step", *robot.joint_names, "x_mm", "y_mm",
                                   "z_mm", "dir_x", "dir_y", "dir_z"]
    assert (steps.groupby("trajectory")["step"].apply(list) == [list(range(51))] * 500).all()
    assert trajectories["converged"].all() and trajectories["within_limits"].all()
    manifest = json.loads((dataset / "dataset.json").read_text())
    assert manifest["count"] == COUNT and manifest["complete"]
    assert manifest["summary"]["trajectories"] == COUNT
    assert set(manifest["columns"]["trajectories"]) == set(trajectories.columns)


def test_metrics_equal_the_metrics_module_recomputed_from_the_steps(robot, dataset):
    steps, trajectories = _read(dataset)
    joints = list(robot.joint_names)
    for k in (0, 199, 200, 333, 499):          # every shard, its first and last rows
        row = trajectories.iloc[k]
        mine = steps[steps["trajectory"] == k].sort_values("step")
        poses = mine[joints].to_numpy(copy=True)
        task = line_task(robot, row[[f"start_{j}" for j in joints]].to_numpy(float),
                         row[[f"touch_{j}" for j in joints]].to_numpy(float), 50, str(k))
        expected = trajectory_metrics(robot, task, poses)
        for key, value in expected.items():
            assert row[key] == pytest.approx(value, rel=1e-9, abs=1e-9), key
        fk = robot.fk(poses)
        np.testing.assert_allclose(mine[["x_mm", "y_mm", "z_mm"]], fk.point_mm, atol=1e-9)
        np.testing.assert_allclose(mine[["dir_x", "dir_y", "dir_z"]], fk.direction, atol=1e-12)
        assert row["loss"] == pytest.approx(objective(robot, task, poses, PAPER_WEIGHTS)[0],
                                            rel=1e-9)
        np.testing.assert_allclose(row[["touch_x_mm", "touch_y_mm", "touch_z_mm"]].to_numpy(float),
                                   task.goal.end_point_mm, atol=1e-9)


def test_shards_are_seeded_by_seed_and_index(robot, paper_targets):
    assert shard_seed(7, 0) != shard_seed(7, 1) != shard_seed(8, 1)
    assert shard_seed(7, 1) == shard_seed(7, 1) and 0 <= shard_seed(2**63 - 1, 5) < 2**63
    touch = np.array([[33, 39, 25, 134, 102, 77, -168], [57, 33, 40, 134, 80, 36, -159.0]])
    tasks, _, _ = line_tasks(robot, paper_targets.start_pose, touch, 10, first=40)
    for task, pose in zip(tasks, touch):
        reference = line_task(robot, paper_targets.start_pose, pose, 10)
        np.testing.assert_allclose(task.goal.points_mm, reference.goal.points_mm, atol=1e-9)
        np.testing.assert_allclose(task.goal.directions, reference.goal.directions, atol=1e-12)
    assert [t.name for t in tasks] == ["40", "41"]


def test_resume_keeps_complete_shards_and_rebuilds_the_same_bytes(dataset, tmp_path, capsys):
    import shutil

    out = tmp_path / "resumed"
    shutil.copytree(dataset, out)
    shard_path(out, "trajectories", 1).unlink()              # as if killed between the files
    shard_path(out, "steps", 2).write_bytes(b"not parquet")  # damaged
    kept = shard_path(out, "steps", 0).stat().st_mtime_ns
    assert main([*COMMAND, "--output", str(out)]) == 0
    assert "1 shard(s) kept, 2 built" in capsys.readouterr().out
    assert shard_path(out, "steps", 0).stat().st_mtime_ns == kept
    for table in ("steps", "trajectories"):
        for shard in range(3):
            assert (shard_path(out, table, shard).read_bytes()
                    == shard_path(dataset, table, shard).read_bytes()), (table, shard)


def test_a_larger_count_extends_and_other_options_are_refused(dataset, tmp_path, capsys):
    import shutil

    out = tmp_path / "grown"
    shutil.copytree(dataset, out)
    assert main([*COMMAND[:2], "520", *COMMAND[3:], "--output", str(out)]) == 0
    assert "2 shard(s) kept, 1 built" in capsys.readouterr().out
    first = pd.read_parquet(shard_path(dataset, "trajectories", 2))
    grown = pd.read_parquet(shard_path(out, "trajectories", 2))
    pd.testing.assert_frame_equal(grown.iloc[:100].reset_index(drop=True), first)
    for change, message in ((["--seed", "8"], "different: seed"),
                            (["--count", "300"], "holds 520 trajectories; --count 300"),
                            (["--weights", "c0=100"], "different: weights")):
        args = [*COMMAND, "--output", str(out)]
        flag = args.index(change[0]) if change[0] in args else None
        if flag is None:
            args += change
        else:
            args[flag + 1] = change[1]
        assert main(args) == 2
        assert message in capsys.readouterr().err


def test_torch_backend_dataset_records_its_solver(tmp_path):
    out = tmp_path / "torch"
    assert main(["dataset", "--count", "12", "--steps", "10", "--device", "cpu", "--dtype",
                 "float32", "--output", str(out), "--quiet"]) == 0
    manifest = json.loads((out / "dataset.json").read_text())
    assert manifest["config"]["solver"] == {
        "backend": "torch", "device_type": "cpu", "dtype": "float32", "max_iterations": 200,
        "tolerance": 1e-9, "damping": 1e-3}
    assert pd.read_parquet(out / "trajectories")["converged"].all()


@pytest.mark.parametrize("args, message", [
    (["--count", "0"], "--count: 0 is out of range; give a number of trajectories from 1"),
    (["--shard-size", "0"], "--shard-size: 0 is out of range; give a number of trajectories"),
    (["--steps", "1"], "--steps: 1 is out of range; give a number of segments from 2 to 5000"),
    (["--seed", "-1"], "--seed: -1 is out of range; give a seed in [0, 2^63)"),
    (["--ray-address", "h:1"], "--ray-address h:1: give --executor ray with it"),
    (["--lm-tolerance", "-1"], "--lm-tolerance: -1.0 must be a positive number"),
    (["--dtype", "float32"], "--dtype float32: the numpy solver (no --device) computes in "
                             "float64"),
])
def test_bad_input_is_one_line_exit_2(tmp_path, capsys, args, message):
    assert message in one_line_error(capsys, ["dataset", "--output", str(tmp_path / "d"),
                                              *args])
    assert not (tmp_path / "d").exists()


def test_missing_pyarrow_names_the_extra(monkeypatch, tmp_path, capsys):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "pyarrow" else real(name, *a))
    assert main(["dataset", "--count", "5", "--output", str(tmp_path / "d")]) == 2
    assert capsys.readouterr().err == (
        "ikbench: error: ikbench dataset writes Parquet with pyarrow, which is not installed; "
        "pip install 'ikbench[scale]'\n")


def test_line_problem_equals_the_problem_of_line_tasks(robot, paper_targets):
    """The shard's array-built problem is the one Problem.from_tasks makes of its tasks."""
    from ikbench.methods.ours_lm import Problem, initial_poses

    touch = np.array([[33, 39, 25, 134, 102, 77, -168], [57, 33, 40, 134, 80, 36, -159.0]])
    weights = dict(PAPER_WEIGHTS)
    tasks, start_mm, touch_mm = line_tasks(robot, paper_targets.start_pose, touch, 12)
    problem, initial, start2, touch2 = line_problem(robot, paper_targets.start_pose,
                                                    touch, 12, weights)
    reference = Problem.from_tasks(robot, tasks, weights)
    for name in ("goal_points_cm", "goal_directions", "start_pose", "end_pose",
                 "weights", "lower_deg", "upper_deg"):
        assert np.array_equal(getattr(problem, name), getattr(reference, name)), name
    assert np.array_equal(initial, initial_poses(robot, tasks))
    assert np.array_equal(start2, start_mm) and np.array_equal(touch2, touch_mm)


def test_the_manifest_names_the_cpu_backend(tmp_path):
    from ikbench.methods.ours_lm.devices import numba_installed

    out = tmp_path / "d"
    assert main(["dataset", "--count", "3", "--steps", "6", "--lm-backend", "numpy",
                 "--quiet", "--output", str(out)]) == 0
    manifest = json.loads((out / "dataset.json").read_text())
    assert manifest["config"]["solver"]["backend"] == "numpy"
    if numba_installed():  # the default: the fastest installed, recorded as such
        assert main(["dataset", "--count", "3", "--steps", "6", "--quiet", "--output",
                     str(tmp_path / "e")]) == 0
        manifest = json.loads((tmp_path / "e" / "dataset.json").read_text())
        assert manifest["config"]["solver"]["backend"] == "numba"
        # a dataset made by numpy is not resumed by numba (the numbers differ by rounding)
        assert main(["dataset", "--count", "3", "--steps", "6", "--quiet", "--output",
                     str(out)]) == 2


def test_the_pipeline_gives_the_shards_build_shard_gives(robot, paper_targets):
    from dataclasses import replace

    from ikbench.core.losses import parse_weights
    from ikbench.methods.ours_lm import LMSettings
    from ikbench.studies.batch import WorkspaceFilter
    from ikbench.studies.dataset import dataset_config, plan
    from ikbench.studies.dataset_shard import build_shard, pipelined

    settings = replace(LMSettings(), weights=parse_weights(None))
    workspace = WorkspaceFilter.of(robot)
    config = dataset_config(robot, paper_targets.start_pose, 8, 3, 4, workspace, settings)
    specs = plan(11, config, robot, paper_targets.start_pose, settings, workspace)
    piped = list(pipelined(specs))
    assert len(piped) == 3
    for spec, result in zip(specs, piped):
        alone = build_shard(spec)
        assert result.steps.equals(alone.steps)
        assert result.trajectories.equals(alone.trajectories)


def test_the_spec_refuses_before_running_and_run_leaves_the_final_manifest_to_write(
        robot, paper_targets, tmp_path):
    """DatasetSpec.validate is where the values are checked (the shard maximum, which only
    the CLI checked before, included); run(spec) writes the shards and a first manifest
    (incomplete), DatasetReport.write the final one."""
    from ikbench.core.errors import InputError
    from ikbench.methods.ours_lm import LMSettings
    from ikbench.studies.dataset import MAX_SHARDS, DatasetSpec, run

    with pytest.raises(InputError, match="more than the maximum"):
        DatasetSpec(MAX_SHARDS + 1, robot, paper_targets, shard_size=1,
                    output=tmp_path / "big").validate()
    assert not (tmp_path / "big").exists()
    spec = DatasetSpec(3, robot, paper_targets, steps=6, shard_size=2,
                       lm_settings=LMSettings(backend="numpy"), output=tmp_path / "d",
                       progress=False)
    spec.validate()
    report = run(spec)
    assert len(pd.read_parquet(tmp_path / "d" / "trajectories")) == 3
    assert json.loads((tmp_path / "d" / "dataset.json").read_text())["complete"] is False
    assert report.write(spec.output) == tmp_path / "d"
    written = json.loads((tmp_path / "d" / "dataset.json").read_text())
    assert written["complete"] is True and written["summary"]["trajectories"] == 3
