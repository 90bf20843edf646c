"""Executors: validation, order, and results on a local Ray equal to the local executor's
(sweep, batch, dataset). One local Ray session for the module."""

from __future__ import annotations

import importlib.util
import logging
import math

import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.runtime.executors import LocalExecutor, check_executor, get_executor, split
from ikbench.studies.batch import check_seed, run_batch
from ikbench.studies.dataset import shard_path


def test_split_is_contiguous_ordered_and_balanced():
    assert split(10, 3) == [range(0, 3), range(3, 6), range(6, 10)]
    assert split(2, 8) == [range(0, 1), range(1, 2)]
    assert split(5, 1) == [range(0, 5)]


def test_local_executor_maps_in_order():
    assert list(LocalExecutor().map(math.sqrt, [9, 4, 1])) == [3.0, 2.0, 1.0]


@pytest.mark.parametrize("name, address, message", [
    ("dask", None, "--executor: 'dask' is not one of local, ray"),
    ("local", "10.0.0.1:6379", "--ray-address 10.0.0.1:6379: give --executor ray with it"),
])
def test_bad_executor_options(name, address, message):
    with pytest.raises(InputError, match="^" + message):
        check_executor(name, address)


def test_missing_ray_names_the_extra(monkeypatch, tmp_path, capsys):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "ray" else real(name, *a))
    assert main(["sweep", "--weight", "c0=1,10", "--executor", "ray",
                 "--output", str(tmp_path)]) == 2
    assert capsys.readouterr().err == ("ikbench: error: --executor ray: Ray is not installed; "
                                       "pip install 'ikbench[scale]'\n")


# ----- on a local Ray -------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ray_session():
    ray = pytest.importorskip("ray", reason="Ray is not installed (pip install "
                              "'ikbench[scale]')")
    ray.init(address="local", num_cpus=2, include_dashboard=False,
             logging_level=logging.WARNING)
    yield get_executor("ray")
    ray.shutdown()


def test_ray_maps_in_order_beyond_its_window(ray_session):
    assert ray_session.workers == 2
    assert list(ray_session.map(math.sqrt, [float(k * k) for k in range(9)])) == list(
        map(float, range(9)))


def test_ray_task_errors_come_back_as_themselves(ray_session):
    with pytest.raises(InputError, match=r"^--seed: -1 must be an integer in \[0, 2\^63\)"):
        list(ray_session.map(check_seed, [1, -1, 2]))


def test_sweep_on_ray_writes_the_same_csv(ray_session, tmp_path):
    args = ["sweep", "--weight", "c0=1,100", "--only", "1,3", "--steps", "20", "--quiet"]
    assert main([*args, "--output", str(tmp_path / "local")]) == 0
    assert main([*args, "--executor", "ray", "--output", str(tmp_path / "ray")]) == 0
    for name in ("sweep.csv", "sweep_trajectories.csv"):
        assert (tmp_path / "ray" / name).read_bytes() == (tmp_path / "local" / name).read_bytes()


def test_batch_on_ray_gives_the_same_trajectories(ray_session):
    options = {"seed": 5, "steps": 20, "weights": ["paper"], "progress": False}
    local = run_batch(30, **options)
    distributed = run_batch(30, **options, executor=ray_session)
    pd.testing.assert_frame_equal(distributed.trajectories, local.trajectories)
    assert distributed.record["executor"] == "ray" and distributed.record["workers"] == 2


def test_dataset_on_ray_writes_the_same_files(ray_session, tmp_path):
    pytest.importorskip("pyarrow")
    args = ["dataset", "--count", "50", "--shard-size", "20", "--steps", "20", "--seed", "3",
            "--quiet"]
    assert main([*args, "--output", str(tmp_path / "local")]) == 0
    assert main([*args, "--executor", "ray", "--output", str(tmp_path / "ray")]) == 0
    for table in ("steps", "trajectories"):
        for shard in range(3):
            assert (shard_path(tmp_path / "ray", table, shard).read_bytes()
                    == shard_path(tmp_path / "local", table, shard).read_bytes())


def test_compare_on_ray_gives_the_local_numbers(ray_session, tmp_path):
    from ikbench.studies.compare import compare

    common = {"only": "1,3", "steps": 6, "repeat": 1, "progress": False}
    local = compare(["ours-lm", "sequential-ik"], output=tmp_path / "local", **common)
    remote = compare(["ours-lm", "sequential-ik"], output=tmp_path / "ray",
                     executor=ray_session, **common)
    numbers = [c for c in local.results.columns if not c.startswith("time_")]
    pd.testing.assert_frame_equal(local.results[numbers], remote.results[numbers])
