"""``ikbench ik --init learned --model MODEL`` (ikbench/studies/ik.py): a tiny NICO dataset and
pose model made once for the module (seconds), the learned starts against random ones, the
record of the model, and the refusals through the CLI."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("pyarrow")

from ikbench.cli import main  # noqa: E402
from ikbench.core.errors import InputError  # noqa: E402
from ikbench.core.robot import load_robot  # noqa: E402
from ikbench.learned import train as learn  # noqa: E402
from ikbench.studies import ik  # noqa: E402

COUNT, STEPS = 96, 10


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    from ikbench.studies.dataset import build_dataset

    folder = tmp_path_factory.mktemp("learned_init") / "nico"
    build_dataset(COUNT, seed=3, steps=STEPS, shard_size=48, output=folder, progress=False)
    return folder


@pytest.fixture(scope="module")
def pose_model(dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("models") / "pose.pt"
    return learn.train(dataset, "pose", out, epochs=25, seed=5, batch_size=256,
                       progress=False)


@pytest.fixture(scope="module")
def trajectory_model(dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("models") / "trajectory.pt"
    return learn.train(dataset, "trajectory", out, epochs=1, seed=5, batch_size=256,
                       progress=False)


def _targets(init: str, model=None, count: int = 60):
    robot = load_robot()
    settings = ik.IKSettings(count=count, seed=1, init=init,
                             model=None if model is None else str(model))
    return robot, ik.sample_targets(robot, settings)


def test_learned_starts_are_closer_to_the_targets_than_random_ones(pose_model):
    robot, learned = _targets("learned", pose_model)
    _, random = _targets("random")
    np.testing.assert_array_equal(learned.q_target, random.q_target)  # the same targets
    np.testing.assert_array_equal(learned.T_target, random.T_target)
    scale = (robot.sample_upper - robot.sample_lower)
    far = lambda q: np.linalg.norm((q - learned.q_target) / scale, axis=1)  # noqa: E731
    assert np.median(far(learned.q_init)) < 0.8 * np.median(far(random.q_init))
    model = ik.init_model(robot, str(pose_model))
    pos_learned, _ = model.error(learned.T_target, learned.q_init)
    pos_random, _ = model.error(random.T_target, random.q_init)
    assert np.median(pos_learned) < 0.8 * np.median(pos_random)


def test_the_sequence_is_the_models_proposals_then_the_usual_draws(pose_model):
    robot, learned = _targets("learned", pose_model)
    _, random = _targets("random")
    model = ik.init_model(robot, str(pose_model))
    k = model.meta["hyper"]["components"]
    rows = learned.initials(3, k + 4)
    np.testing.assert_allclose(rows[:k], model.propose(learned.T_target[3], k))
    np.testing.assert_array_equal(rows[k:], random.initials(3, k + 4)[k:])  # past K: as ever
    np.testing.assert_array_equal(learned.initials(3, 1)[0], learned.q_init[3])
    assert np.all(rows >= robot.lower - 1e-12) and np.all(rows <= robot.upper + 1e-12)
    facts = learned.init_model
    assert facts["training_samples"] == model.meta["samples"]["train"]
    assert facts["training_cpu_min"] == model.meta["training_cpu_min"] > 0
    assert facts["model_query_ms"] > 0 and facts["components"] == k
    assert facts["model_file"] == str(pose_model.resolve())


def test_a_run_records_the_model_in_run_json_and_summary(pose_model, tmp_path, capsys):
    code = main(["ik", "--count", "6", "--methods", "ours-lm", "--attempts", "1",
                 "--init", "learned", "--model", str(pose_model), "--output", str(tmp_path),
                 "--quiet"])
    assert code == 0
    folder = tmp_path / "ik" / "nico_right_arm"
    record = json.loads((folder / "run.json").read_text())
    assert record["settings"]["init"] == "learned"
    assert record["settings"]["model"] == str(pose_model)
    meta = torch.load(pose_model, map_location="cpu", weights_only=True)
    assert record["init_model"]["training_samples"] == meta["samples"]["train"]
    summary = pd.read_csv(folder / "summary.csv")
    for column in ("model_query_ms", "model_error_mm", "training_samples",
                   "training_cpu_min"):
        assert summary[column].notna().all(), column
    assert (summary["training_samples"] == meta["samples"]["train"]).all()
    results = pd.read_csv(folder / "results.csv")
    assert set(results["init"]) == {"learned"}


def _refused(args, capsys) -> list[str]:
    try:
        code = main(["ik", "--count", "4", "--methods", "ours-lm", "--quiet", *args])
    except SystemExit as exc:
        code = exc.code
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 2, captured
    assert len(lines) == 1 and "Traceback" not in captured.err, lines
    return lines


def test_learned_without_a_model_is_refused(capsys, tmp_path):
    (line,) = _refused(["--init", "learned", "--output", str(tmp_path)], capsys)
    assert "--model" in line


def test_a_model_without_init_learned_is_refused(pose_model, capsys, tmp_path):
    (line,) = _refused(["--model", str(pose_model), "--output", str(tmp_path)], capsys)
    assert "--model" in line and "--init learned" in line


def test_a_model_of_another_robot_is_refused(pose_model, capsys, tmp_path):
    (line,) = _refused(["--robot", "example-robot-data:panda", "--init", "learned",
                        "--model", str(pose_model), "--output", str(tmp_path)], capsys)
    assert "--model" in line and "nico" in line


def test_a_trajectory_model_is_refused(trajectory_model, capsys, tmp_path):
    (line,) = _refused(["--init", "learned", "--model", str(trajectory_model),
                        "--output", str(tmp_path)], capsys)
    assert "trajectory" in line


def test_a_missing_model_file_is_refused(capsys, tmp_path):
    (line,) = _refused(["--init", "learned", "--model", str(tmp_path / "none.pt"),
                        "--output", str(tmp_path)], capsys)
    assert "--model" in line and "not found" in line


def test_the_settings_refuse_the_pairs_in_python():
    with pytest.raises(InputError, match="--model"):
        ik.IKSettings(init="learned")
    with pytest.raises(InputError, match="--init learned"):
        ik.IKSettings(init="random", model="x.pt")
