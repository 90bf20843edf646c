"""One run record: run.json written and read by :mod:`ikbench.runtime.record`, old files too;
a run folder written whole; compare's in-memory verdicts equal what its files recompute to."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import ikbench
from ikbench.core.contract import contract_for, judge
from ikbench.core.errors import InputError
from ikbench.core.metrics import contract_metrics
from ikbench.core.task import line_tasks
from ikbench.core.trajectory import read_trajectory_poses, write_trajectory_csv
from ikbench.render.leaderboard import render
from ikbench.runtime.record import (
    LAYOUTS,
    RunFolder,
    RunRecord,
    TrajectoryFile,
    files_written_by,
    robot_from_record,
)
from ikbench.studies.compare import (
    CONTRACT_METRICS,
    CompareSpec,
    compare,
    run_comparison,
)

RESULTS = Path(__file__).resolve().parents[1] / "results"
#: Every run.json committed under results/, by kind (the format a user's files have).
RECORDS = sorted(RESULTS.rglob("run.json"))
#: run.json files written before the robot, files and failures were recorded: copies of the
#: letters runs as results/letters held them until their regeneration (a user's old folders).
OLD = set((Path(__file__).resolve().parent / "data" / "old_records").glob("*/run.json"))


def test_results_hold_a_run_json_of_every_kind():
    kinds = {RunRecord.from_dict(json.loads(p.read_text())).kind for p in RECORDS}
    assert kinds == set(LAYOUTS)


@pytest.mark.parametrize("path", [p for p in RECORDS if p not in OLD],
                         ids=lambda p: str(p.relative_to(RESULTS)))
def test_a_run_json_reads_back_to_the_same_keys_values_and_order(path):
    text = path.read_text()
    record = RunRecord.from_dict(json.loads(text))
    assert list(record.to_dict().items()) == list(json.loads(text).items())
    assert not record.absent
    assert record.to_json() == text  # the writers' own text, byte for byte


@pytest.mark.parametrize("path", sorted(OLD), ids=lambda p: "/".join(p.parts[-3:-1]))
def test_an_old_run_json_reads_with_defaults_and_says_what_it_lacks(path):
    record = RunRecord.from_dict(json.loads(path.read_text()))
    assert record.kind == "run" and record.method == "ours" and record.robot is None
    assert {"robot", "files", "size_mm"} <= record.absent
    assert record.trajectories and record.files is None and record.failed == []
    assert robot_from_record(record).name == "nico_right_arm"  # before robots: NICO
    expected = {"table.csv", "run.json", *(f"trajectory_{t}.csv" for t in record.trajectories)}
    assert expected <= files_written_by(path.parent)


def test_a_bad_run_json_is_a_one_line_error_and_writes_nothing_off(tmp_path):
    (tmp_path / "run.json").write_text("[1, 2]")
    with pytest.raises(InputError, match=r"^view: .*run.json is not a JSON object$"):
        RunFolder(tmp_path).read_record("view")
    (tmp_path / "run.json").write_text("{")
    with pytest.raises(InputError, match=r"^report: cannot read .*run.json: "):
        RunFolder(tmp_path).read_record("report")
    assert files_written_by(tmp_path) == set()  # unreadable: nothing counts as the run's


def test_obstacles_of_a_record_are_shared_or_per_trajectory():
    cube = {"type": "sphere", "name": "ball", "center_mm": [0.0, 200.0, 700.0],
            "radius_mm": 50.0}
    shared, own = RunRecord(obstacles=[cube]).trajectory_obstacles(["1", "2"])
    assert len(shared) == 1 and own["1"] == own["2"] == shared
    shared, own = RunRecord(obstacles={"2": [cube]}).trajectory_obstacles(["1", "2"])
    assert shared == () and own["1"] == () and len(own["2"]) == 1
    shared, _ = RunRecord(kind="compare", obstacles={"source": "f.json", "items": [cube]}
                          ).trajectory_obstacles(["1"])
    assert len(shared) == 1
    with pytest.raises(InputError, match="^here: expected a list of obstacles"):
        RunRecord(obstacles="cube").trajectory_obstacles(["1"], "here")  # type: ignore[arg-type]


def test_a_trajectory_file_is_the_written_csv_and_its_poses_as_read(tmp_path, robot):
    rng = np.random.default_rng(0)
    start = np.array([-24.92, 81.45, 46.55, 94.37, -59.03, 28.0, 45.67])
    poses = start + rng.normal(0, 1e-3, (5, robot.dof))  # digits beyond what the file keeps
    file = TrajectoryFile.of(robot, "7", poses, 2.0)
    written = write_trajectory_csv(tmp_path / file.file, robot, poses, 2.0)
    assert written.read_text() == file.text
    read = read_trajectory_poses(written, robot)
    assert np.array_equal(file.poses, read)  # bit for bit what a reader gets
    assert not np.array_equal(file.poses, poses)  # not the unrounded poses
    lines = file.text.splitlines()
    cells = lines[2].split(",")
    lines[2] = ",".join([*cells[:2], "1e9", *cells[3:]])  # step 1, the first joint
    with pytest.raises(InputError, match="^trajectory_7.csv: line 3 \\(step 1\\)"):
        read_trajectory_poses(io.StringIO("\n".join(lines)), robot, "trajectory_7.csv")


def test_a_run_folder_is_written_whole_and_reads_back(tmp_path, robot):
    table = ikbench.run("ours-lm", only="1,3", steps=6, output=tmp_path, progress=False,
                        animation=False, name="lm")
    folder = RunFolder(tmp_path / "lm")
    record = folder.read_record()
    assert record.kind == "run" and record.method == "ours-lm" and record.name == "lm"
    assert record.trajectories == ["1", "3"] and record.steps == 6
    assert sorted(p.name for p in folder.path.iterdir()) == record.files
    assert folder.files_written() == set(record.files)
    assert robot_from_record(record).joint_names == robot.joint_names
    written = folder.read_table()
    pd.testing.assert_frame_equal(written, table.astype(written.dtypes.to_dict()),
                                  check_exact=False, rtol=1e-9)
    in_memory = ikbench.run("ours-lm", only="1,3", steps=6, output=None, progress=False)
    columns = [c for c in table.columns if "duration" not in c]
    pd.testing.assert_frame_equal(in_memory[columns], table[columns])


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    """ours-lm and sequential-ik compared on trajectories 1 and 3 (n = 6), written."""
    out = tmp_path_factory.mktemp("compare")
    result = compare(["ours-lm", "sequential-ik"], only="1,3", steps=6, repeat=1, warmup=0,
                     output=out, progress=False, sweep=False)
    return out / "compare", result


def test_compare_judges_in_memory_what_its_written_files_recompute_to(compared, robot,
                                                                       paper_targets):
    root, result = compared
    contract = contract_for(robot)
    touch = contract.with_track("touch")
    tasks = {t.name: t for t in line_tasks(robot, paper_targets.select("1,3").with_steps(6),
                                           contract)}
    verdicts = result.results.set_index(["method", "trajectory"])
    assert len(verdicts) == 4
    for (method, trajectory), row in verdicts.iterrows():
        poses = RunFolder(root / method).read_poses(trajectory, robot)
        figures = contract_metrics(robot, tasks[trajectory], poses, contract)
        for column in CONTRACT_METRICS:
            assert row[column] == figures[column], (method, trajectory, column)  # exact
        paper, touched = judge(contract, figures), judge(touch, figures)
        for name, ok in paper.items():
            assert row[f"ok_{name}"] == ok
        honours = not str(row["status"]).startswith("does not honour")
        assert bool(row["success"]) == (honours and all(paper.values()))
        assert bool(row["success_touch"]) == all(touched.values())
    written = pd.read_csv(root / "results.csv", dtype={"trajectory": str})
    assert written["success"].tolist() == result.results["success"].tolist()


def test_compare_spec_runs_without_writing_and_judges_alike(compared, robot, paper_targets):
    root, result = compared
    contract = contract_for(robot)
    targets = paper_targets.select("1,3").with_steps(6)
    spec = CompareSpec(["ours-lm", "sequential-ik"], robot, targets,
                       line_tasks(robot, targets, contract), contract, "ours-lm", repeat=1,
                       warmup=0, sweep=False, progress=False)
    again = run_comparison(spec)
    assert "total_wall_time_s" not in again.record  # nothing written, no total time
    judged = [c for c in result.results.columns if c.startswith(("ok_", "success"))
              or c in CONTRACT_METRICS]
    pd.testing.assert_frame_equal(again.results[judged], result.results[judged])
    record = RunFolder(root).read_record()
    assert record.kind == "compare" and record.methods == ["ours-lm", "sequential-ik"]
    assert record.study["repeat"] == 1 and record.total_wall_time_s is not None


def test_the_compare_report_renders_again_from_the_folder(compared):
    root, _ = compared
    before = (root / "leaderboard.md").read_text()
    (root / "leaderboard.md").unlink()
    render(root)
    assert (root / "leaderboard.md").read_text() == before
