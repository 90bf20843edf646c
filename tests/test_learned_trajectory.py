"""Learned starts for whole trajectories (ikbench/learned/starts.py, ``ikbench run
--init-model``) and the trajectory half of the learned-start study
(ikbench/studies/learned_trajectory.py), on a tiny NICO dataset."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("pyarrow")

import pandas as pd  # noqa: E402

from ikbench.cli import main  # noqa: E402
from ikbench.core.errors import InputError  # noqa: E402
from ikbench.core.robot import load_robot  # noqa: E402
from ikbench.core.targets import load_targets  # noqa: E402
from ikbench.core.task import letter_task, line_tasks  # noqa: E402
from ikbench.learned import train as learn  # noqa: E402
from ikbench.learned.starts import LearnedStart, learned_start, resample  # noqa: E402
from ikbench.methods.registry import get_method  # noqa: E402
from ikbench.studies import learned_trajectory as study  # noqa: E402
from ikbench.studies import regeneration as regen  # noqa: E402

#: A dataset of another n than the paper's 50: the start is resampled.
COUNT, STEPS = 48, 10


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> dict[str, Path]:
    from ikbench.studies.dataset import build_dataset

    folder = tmp_path_factory.mktemp("learned-trajectory")
    build_dataset(COUNT, seed=5, steps=STEPS, shard_size=24, output=folder / "data",
                  progress=False)
    return {kind: learn.train(folder / "data", kind, folder / f"{kind}.pt", epochs=3, seed=2,
                              progress=False) for kind in ("trajectory", "pose")}


@pytest.fixture(scope="module")
def nico():
    robot = load_robot("nico_right_arm")
    return robot, line_tasks(robot, load_targets(None, robot))


def test_resample_keeps_the_ends_and_is_linear_in_time():
    poses = np.array([[0.0, 10.0], [2.0, 10.0], [4.0, 30.0]])
    out = resample(poses, 4)
    assert out.shape == (5, 2)
    assert np.array_equal(out[[0, -1]], poses[[0, -1]])
    assert np.allclose(out[:, 0], [0, 1, 2, 3, 4]) and np.allclose(out[:, 1], [10, 10, 10, 20, 30])
    assert np.array_equal(resample(poses, 2), poses)


def test_the_learned_start_runs_from_the_start_pose_onto_the_touch_pose(models, nico):
    robot, tasks = nico
    model = learn.load_model(models["trajectory"], robot, kind="trajectory")
    task = tasks[0]
    q = learned_start(model, task)
    n = len(task.goal.points_mm) - 1
    assert q.shape == (n + 1, robot.dof) and robot.within_limits(q)
    assert np.allclose(q[0], task.required.start_pose)
    assert np.allclose(q[-1], task.required.end_pose)
    # the rows between are the model's prediction (resampled to n), bent by the linear ramp
    raw = resample(model.predict(task.required.start_pose, task.goal.end_point_mm), n)
    ramp = np.linspace(0, 1, n + 1)[:, None] * (task.required.end_pose - raw[-1])
    assert np.allclose(q, np.clip(raw + ramp, robot.lower, robot.upper))
    assert not np.allclose(raw[-1], task.required.end_pose)  # the bend did something


def test_a_method_refines_the_learned_start_and_says_so(models, nico):
    robot, tasks = nico
    task = tasks[1]
    solver = LearnedStart(get_method("ours-lm")(), models["trajectory"])
    solver.check_tasks(robot, [task])
    solution = solver.solve(robot, task)
    assert solver.name == "ours-lm-learned" and not solver.capabilities.batched
    assert solution.info["initial"] == "learned"
    assert 0 < solution.info["refine_s"] <= solution.duration_s
    assert solution.info["model_query_s"] > 0
    model = solver.model(robot)
    alone = get_method("ours-lm")().solve_from(robot, task, learned_start(model, task))
    assert np.array_equal(solution.poses, alone.poses)  # the refinement of that very start


def test_what_cannot_take_a_learned_start_is_refused(models, nico):
    robot, tasks = nico
    with pytest.raises(InputError, match="--method ours cannot start from given poses; "
                                         "methods that can: .*ours-lm"):
        LearnedStart(get_method("ours")(), models["trajectory"])
    with pytest.raises(InputError, match="is a pose model, not a trajectory model"):
        LearnedStart(get_method("ours-lm")(), models["pose"]).check_tasks(robot, tasks)
    letter = letter_task(robot, "P", tasks[0].required.start_pose)
    with pytest.raises(InputError, match="needs a line task"):
        LearnedStart(get_method("ours-lm")(), models["trajectory"]).check_tasks(robot,
                                                                               [letter])


def _run(args: list[str], capsys) -> tuple[int, str]:
    try:
        code = main(["run", *map(str, args)])
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err.strip()


def test_ikbench_run_init_model_writes_the_learned_run(models, tmp_path, capsys):
    code, _ = _run(["--method", "ours-lm", "--init-model", models["trajectory"], "--only", "1,2",
                    "--output", tmp_path, "--no-animation", "--quiet"], capsys)
    assert code == 0
    record = json.loads((tmp_path / "ours-lm-learned" / "run.json").read_text())
    assert record["method"] == "ours-lm-learned"
    assert record["runtime"]["initial"] == "learned trajectory model"
    details = pd.read_csv(tmp_path / "ours-lm-learned" / "details.csv")
    assert len(details) == 2


@pytest.mark.parametrize("args, message", [
    (["--method", "ours"], "--method ours cannot start from given poses"),
    (["--method", "ours-lm", "--shape", "letter:P"], "learned lines; --shape letter:P"),
    (["--method", "ours-lm", "--robot", "panda"], "not 'panda'"),
])
def test_ikbench_run_refuses_a_bad_init_model_in_one_line(models, tmp_path, capsys, args,
                                                          message):
    code, err = _run([*args, "--init-model", models["trajectory"], "--output", tmp_path,
                      "--no-animation", "--quiet"], capsys)
    assert code == 2 and len(err.splitlines()) == 1 and message in err
    assert not any(tmp_path.iterdir())


def test_ikbench_run_refuses_a_pose_model(models, tmp_path, capsys):
    code, err = _run(["--method", "ours-exact", "--init-model", models["pose"], "--output",
                      tmp_path, "--no-animation", "--quiet"], capsys)
    assert code == 2 and "is a pose model, not a trajectory model" in err
    assert not any(tmp_path.iterdir())


def test_the_study_writes_its_tables_with_the_model_columns_where_they_belong(tmp_path):
    code = study.main(["--output", str(tmp_path), "--trajectories", "30", "--epochs", "2",
                       "--repeats", "1", "--quiet"])
    assert code == 0
    table = pd.read_csv(tmp_path / "trajectories.csv")
    assert list(table.columns) == study.COLUMNS
    assert len(table) == 7 * len(study.METHODS) * len(study.STARTS)
    assert set(table["target"].astype(str)) == {str(k) for k in range(1, 8)}
    learned, usual = table[table["start"] == "learned"], table[table["start"] == "usual"]
    model_columns = ["model_query_ms", "raw_line_distance_mean_mm",
                     "raw_pointing_deviation_mean_deg", "start_line_distance_mean_mm",
                     "training_samples", "training_cpu_min"]
    assert learned[model_columns].notna().all().all()
    assert usual[model_columns].isna().all().all()
    assert (usual["refine_median_ms"] == usual["time_median_ms"]).all()
    assert (learned["refine_median_ms"] < learned["time_median_ms"]).all()
    assert (table["nearest_training_goal_mm"] > 0).all()
    # ours-exact meets the contract from its usual start on the paper's targets
    exact = usual[usual["method"] == "ours-exact"]
    assert exact["success"].all()
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert list(summary.columns) == study.SUMMARY_COLUMNS and len(summary) == 4
    for _, row in summary.iterrows():
        part = table[(table["method"] == row["method"]) & (table["start"] == row["start"])]
        assert row["success_count"] == part["success"].sum()
        if row["start"] == "learned":
            other = table[(table["method"] == row["method"]) & (table["start"] == "usual")]
            ratios = (part.set_index("target")["time_median_ms"]
                      / other.set_index("target")["time_median_ms"])
            assert row["time_ratio_to_usual_median"] == pytest.approx(ratios.median())
    record = json.loads((tmp_path / "learned.json").read_text())
    assert record["settings"]["dataset_seed"] not in (1, 4)
    assert record["settings"]["train_seed"] not in (1, 4)
    assert record["model"]["exclusion"]["closest_training_touch_pose_max_joint_diff"] > 0
    assert len(record["model"]["model_sha256"]) == 64
    assert str(tmp_path) not in (tmp_path / "learned.json").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["learned.json", "summary.csv",
                                                          "trajectories.csv"]


def test_the_study_refuses_a_size_below_one(tmp_path, capsys):
    assert study.main(["--output", str(tmp_path), "--repeats", "0"]) == 2
    assert "--repeats: 0 must be an integer >= 1" in capsys.readouterr().err


def test_the_plan_has_the_learned_trajectory_entry_and_its_script():
    entry = next(s for s in regen.STUDIES if s.name == "learned-trajectory")
    entry.validate()
    assert entry.writes == ("learned_trajectory",)
    assert (regen.REPO / entry.script).is_file()
    assert entry.arguments(regen.REPO / "results")[-1].endswith("results/learned_trajectory")
