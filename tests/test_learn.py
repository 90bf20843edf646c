"""``ikbench learn`` and its Python API (ikbench/learned/train.py, model.py): tiny NICO
datasets made once for the module, a few epochs each."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("pyarrow")

from ikbench.cli import main  # noqa: E402
from ikbench.core.errors import InputError  # noqa: E402
from ikbench.learned import train as learn  # noqa: E402

COUNT, STEPS = 64, 10


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    from ikbench.studies.dataset import build_dataset

    folder = tmp_path_factory.mktemp("learn") / "nico"
    build_dataset(COUNT, seed=3, steps=STEPS, shard_size=32, output=folder, progress=False)
    return folder


@pytest.fixture(scope="module")
def pose_model(dataset, tmp_path_factory) -> Path:
    """A pose model trained long enough (on this tiny set, seconds) to beat an untrained one."""
    out = tmp_path_factory.mktemp("models") / "pose.pt"
    return learn.train(dataset, "pose", out, epochs=15, seed=1, batch_size=256,
                       progress=False)


def _payload(path: Path) -> dict:
    return torch.load(path, map_location="cpu", weights_only=True)


def _cli(args: list[str], capsys) -> tuple[int, list[str]]:
    try:
        code = main(["learn", *map(str, args)])
    except SystemExit as exc:  # argparse's refusals
        code = exc.code
    return code, capsys.readouterr().err.strip().splitlines()


# ----- what the model file records --------------------------------------------------------------
def test_the_model_file_records_its_provenance_and_cost(pose_model, dataset):
    p = _payload(pose_model)
    manifest = json.loads((dataset / "dataset.json").read_text())
    assert p["kind"] == "pose"
    assert p["robot"]["name"] == "nico_right_arm" and p["robot"]["dof"] == 7
    assert p["robot"]["joints"] == manifest["config"]["robot"]["joints"]
    assert p["dataset"]["sha256"] == hashlib.sha256(
        (dataset / "dataset.json").read_bytes()).hexdigest()
    assert p["dataset"]["path"] == str(dataset.resolve())
    assert (p["dataset"]["seed"], p["dataset"]["count"]) == (3, COUNT)
    assert isinstance(p["git_commit"], str) and isinstance(p["git_clean"], bool)
    samples = p["samples"]
    assert samples["train"] + samples["held_out"] == COUNT * (STEPS + 1)
    assert samples["train_trajectories"] + samples["held_out_trajectories"] == COUNT
    assert p["epochs"] == 15 and len(p["history"]) == 15
    assert p["training_cpu_min"] > 0 and p["training_wall_min"] > 0
    assert p["torch_version"] == str(torch.__version__)
    assert p["hyper"]["batch_size"] == 256 and p["hyper"]["components"] >= 2
    err = p["held_out_error"]
    for key in ("position_mm_median", "position_mm_p95", "rotation_deg_median",
                "rotation_deg_p95", "best_of_k_position_mm_median"):
        assert np.isfinite(err[key]) and err[key] >= 0, key
    assert err["position_mm_p95"] >= err["position_mm_median"]
    assert err["best_of_k_position_mm_median"] <= err["position_mm_p95"]
    assert 0 < p["model_query_ms"] < 1000  # a safety net, not a timing claim


def test_the_held_out_split_is_by_trajectory(pose_model, dataset):
    data = learn.read_dataset(dataset)
    train_ids, held_ids = learn.split(data.trajectory_ids, 0.1, seed=1)
    assert not set(train_ids) & set(held_ids)
    assert set(train_ids) | set(held_ids) == set(data.trajectory_ids)
    assert len(held_ids) == round(0.1 * COUNT)
    model = learn.load_model(pose_model)
    assert sorted(model.held_out_trajectories.tolist()) == sorted(held_ids.tolist())
    # every pose of a held-out trajectory is held out: the sample counts say so
    p = _payload(pose_model)
    assert p["samples"]["held_out"] == len(held_ids) * (STEPS + 1)
    # another seed, another split
    assert not np.array_equal(learn.split(data.trajectory_ids, 0.1, seed=2)[1], held_ids)


# ----- the pose model's API ---------------------------------------------------------------------
def _held_out_frames(model, dataset) -> tuple[np.ndarray, np.ndarray]:
    data = learn.read_dataset(dataset)
    rows = np.flatnonzero(np.isin(data.trajectory_ids, model.held_out_trajectories))
    q = data.poses[rows].reshape(-1, data.robot.dof)
    return data.robot.fk_transform(q), q


def test_propose_gives_configurations_within_the_limits(pose_model, dataset):
    model = learn.load_model(pose_model, kind="pose")
    robot = model.robot
    T, _ = _held_out_frames(model, dataset)
    k = model.meta["hyper"]["components"]
    q = model.propose(T[0], count=k + 5, seed=4)
    assert q.shape == (k + 5, robot.dof)
    assert robot.within_limits(q)
    assert np.array_equal(q, model.propose(T[0], count=k + 5, seed=4))      # seeded
    assert not np.array_equal(q[k:], model.propose(T[0], count=k + 5, seed=5)[k:])
    assert np.array_equal(q[:k], model.propose(T[0], count=k + 5, seed=5)[:k])  # the means
    assert model.propose(T[:3], count=2).shape == (3, 2, robot.dof)
    assert model.propose(T[0]).shape == (1, robot.dof)


def test_the_trained_model_beats_an_untrained_one_on_held_out_frames(pose_model, dataset):
    model = learn.load_model(pose_model)
    T, _ = _held_out_frames(model, dataset)
    trained_mm, trained_deg = model.error(T, model.propose(T, 1)[:, 0])
    untrained = learn.load_model(pose_model)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(0)
        for module in untrained.net.modules():
            if hasattr(module, "reset_parameters"):
                module.reset_parameters()
    raw_mm, raw_deg = untrained.error(T, untrained.propose(T, 1)[:, 0])
    assert np.median(trained_mm) < 0.7 * np.median(raw_mm)
    assert np.median(trained_deg) < np.median(raw_deg)
    # the recorded figures are the model's own on its held-out frames
    recorded = model.meta["held_out_error"]["position_mm_median"]
    assert recorded == pytest.approx(np.median(trained_mm), rel=1e-3)


def test_resume_ends_with_the_weights_of_an_uninterrupted_run(dataset, tmp_path):
    whole = learn.train(dataset, "pose", tmp_path / "whole.pt", epochs=3, seed=5,
                        batch_size=128, progress=False)
    part = learn.train(dataset, "pose", tmp_path / "part.pt", epochs=1, seed=5,
                       batch_size=128, progress=False)
    assert (tmp_path / "part.pt.checkpoint").is_file()
    resumed = learn.train(dataset, "pose", part, epochs=3, seed=5, batch_size=128,
                          resume=True, progress=False)
    a, b = _payload(whole), _payload(resumed)
    assert a["state_dict"].keys() == b["state_dict"].keys()
    for key in a["state_dict"]:
        assert torch.equal(a["state_dict"][key], b["state_dict"][key]), key
    assert a["history"] == b["history"] and b["epochs"] == 3
    # each run is recorded with its commit and its epochs, the resumed one as two runs
    assert [(r["first_epoch"], r["last_epoch"]) for r in a["runs"]] == [(1, 3)]
    assert [(r["first_epoch"], r["last_epoch"]) for r in b["runs"]] == [(1, 1), (2, 3)]
    assert all(r["git_commit"] == b["git_commit"] for r in b["runs"])
    # and a different seed gives different weights (the comparison can fail)
    other = _payload(learn.train(dataset, "pose", tmp_path / "other.pt", epochs=1, seed=6,
                                 batch_size=128, progress=False))
    key = next(iter(other["state_dict"]))
    assert not torch.equal(other["state_dict"][key], _payload(part)["state_dict"][key])


# ----- the trajectory model ---------------------------------------------------------------------
def test_the_trajectory_model_predicts_whole_trajectories(dataset, tmp_path):
    path = learn.train(dataset, "trajectory", tmp_path / "traj.pt", epochs=3, seed=1,
                       progress=False)
    model = learn.load_model(path, kind="trajectory")
    data = learn.read_dataset(dataset)
    start, goal = data.poses[0, 0], data.touch_mm[0]
    q = model.predict(start, goal)
    assert q.shape == (STEPS + 1, model.robot.dof)
    assert np.array_equal(q[0], start) and model.robot.within_limits(q)
    assert model.predict(data.poses[:4, 0], data.touch_mm[:4]).shape == (4, STEPS + 1, 7)
    k = model.meta["hyper"]["components"]
    candidates = model.candidates(start, goal)
    assert candidates.shape == (k, STEPS + 1, 7) and np.array_equal(candidates[0], q)
    assert model.robot.within_limits(candidates)
    err = model.meta["held_out_error"]
    assert err["samples"] > 0 and np.isfinite(err["line_distance_mean_mm_median"])
    assert np.isfinite(err["end_point_error_mm_p95"])
    with pytest.raises(InputError, match="needs a pose model"):
        model.propose(np.eye(4), 1)


# ----- refusals ---------------------------------------------------------------------------------
def test_load_model_refuses_another_robot_or_kind(pose_model, tmp_path):
    with pytest.raises(InputError, match="not a trajectory model"):
        learn.load_model(pose_model, kind="trajectory")
    with pytest.raises(InputError,
                       match=r"is of robot 'nico_right_arm' \(URDF [0-9a-f]+\), not 'panda'"):
        learn.load_model(pose_model, robot="panda")
    junk = tmp_path / "junk.pt"
    junk.write_text("not a model")
    with pytest.raises(InputError, match="not a model file"):
        learn.load_model(junk)
    with pytest.raises(InputError, match="not found"):
        learn.load_model(tmp_path / "missing.pt")


def _empty_dataset(dataset: Path, folder: Path) -> Path:
    """A dataset folder whose manifest says complete but whose tables hold no trajectory."""
    folder.mkdir()
    manifest = json.loads((dataset / "dataset.json").read_text())
    (folder / "dataset.json").write_text(json.dumps({**manifest, "count": 0}))
    return folder


def test_bad_input_is_one_line_and_exit_2_with_nothing_written(dataset, pose_model, tmp_path,
                                                               capsys):
    out = tmp_path / "out" / "m.pt"
    not_a_dataset = tmp_path / "empty"
    not_a_dataset.mkdir()
    unfinished = tmp_path / "unfinished"
    shutil.copytree(dataset, unfinished)
    manifest = json.loads((unfinished / "dataset.json").read_text())
    (unfinished / "dataset.json").write_text(json.dumps({**manifest, "complete": False}))
    cases = [
        ([tmp_path / "missing", "--kind", "pose", "--output", out], "DATASET"),
        ([not_a_dataset, "--kind", "pose", "--output", out], "holds no dataset.json"),
        ([_empty_dataset(dataset, tmp_path / "zero"), "--kind", "pose", "--output", out],
         "holds no trajectories"),
        ([unfinished, "--kind", "pose", "--output", out], "is not complete"),
        ([dataset, "--kind", "pose", "--output", out, "--robot", "panda"],
         "--robot: the dataset is of robot 'nico_right_arm'"),
        ([dataset, "--kind", "pose", "--output", out, "--resume"], "--resume: no checkpoint"),
        ([dataset, "--kind", "trajectory", "--output", pose_model, "--resume", "--seed", "1",
          "--batch-size", "256"], "--resume: "),
        ([dataset, "--kind", "pose", "--output", tmp_path], "--output: cannot write"),
        ([dataset, "--kind", "pose", "--output", out, "--holdout", "0.001"], "--holdout"),
        ([dataset, "--kind", "pose", "--output", pose_model, "--resume", "--seed", "1",
          "--batch-size", "256", "--epochs", "14"], "--epochs: 14 is fewer than the 15"),
    ]
    checkpoint = learn.checkpoint_path(pose_model)
    before = checkpoint.read_bytes()
    for args, expected in cases:
        code, lines = _cli(args, capsys)
        assert code == 2, (args, lines)
        assert len(lines) == 1 and lines[0].startswith("ikbench: error: "), (args, lines)
        assert expected in lines[0], (args, lines)
    assert "(different: kind)" in _cli(cases[6][0], capsys)[1][0]
    assert not (tmp_path / "out").exists()
    assert checkpoint.read_bytes() == before


def test_the_command_trains_and_says_what_it_wrote(dataset, tmp_path, capsys):
    out = tmp_path / "m.pt"
    code = main(["learn", str(dataset), "--kind", "pose", "--output", str(out), "--epochs",
                 "2", "--quiet"])
    text = capsys.readouterr().out
    assert code == 0 and out.is_file() and learn.checkpoint_path(out).is_file()
    assert "pose model of nico_right_arm" in text and "CPU-min" in text
    assert _payload(out)["epochs"] == 2
