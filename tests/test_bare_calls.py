"""benchmarks/ours_lm_vs_bare.py (the ``bare-calls`` study): what its summary says is what its
own per-call times say, every method timed on the same targets and rounds, and bad options
refused in one line with nothing written."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "ours_lm_vs_bare.py"
_spec = importlib.util.spec_from_file_location("ours_lm_vs_bare", SCRIPT)
bare = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bare)


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("bare") / "bare_calls"
    assert bare.main(["--robot", "example-robot-data:ur5", "--robot", "panda", "--count", "12",
                      "--repeat", "2", "--output", str(out)]) == 0
    return out


def test_every_method_is_timed_on_the_same_targets_and_rounds(written):
    calls = pd.read_csv(written / "calls.csv")
    summary = pd.read_csv(written / "summary.csv")
    assert set(summary.robot) == {"example-robot-data:ur5", "panda"}
    # EAIK solves the 6R UR5 and not the 7R Panda: its rows only where it has a decomposition
    assert set(summary[summary.robot == "panda"].method) == {"ours-lm", "rtb-lm"}
    assert set(summary[summary.robot == "example-robot-data:ur5"].method) == {
        "ours-lm", "eaik", "eaik-adapter", "rtb-lm"}
    for (robot, method), group in calls.groupby(["robot", "method"]):
        assert sorted(zip(group.target, group["round"], strict=True)) == [
            (t, r) for t in range(12) for r in range(2)], (robot, method)
    assert (calls.time_us > 0).all()


def test_the_summary_is_recomputed_from_the_calls(written):
    calls = pd.read_csv(written / "calls.csv")
    summary = pd.read_csv(written / "summary.csv").set_index(["robot", "method"])
    per_target = calls.groupby(["robot", "method", "target"]).time_us.median()
    for (robot, method), row in summary.iterrows():
        medians = per_target.loc[(robot, method)]
        assert row.median_us == pytest.approx(float(np.median(medians)), rel=1e-12)
        for other in bare.RATIOS.get(method, ()):
            if (robot, other) not in summary.index:
                continue
            ratio = np.median(medians.to_numpy()) / np.median(
                per_target.loc[(robot, other)].to_numpy())
            assert row[f"ratio_to_{other}"] == pytest.approx(ratio, rel=1e-12)
            assert (row[f"ratio_to_{other}_ci95_low"] <= row[f"ratio_to_{other}"]
                    <= row[f"ratio_to_{other}_ci95_high"])
    # the analytic solver solves every reachable target: the judge sees it
    assert summary.loc[("example-robot-data:ur5", "eaik"), "success_pct"] == 100.0


def test_the_record_names_the_settings_and_the_provenance(written):
    record = json.loads((written / "bare_calls.json").read_text())
    assert record["settings"]["robots"] == ["example-robot-data:ur5", "panda"]
    assert record["settings"]["count"] == 12 and record["settings"]["seed"] == 201
    assert record["provenance"]["git_commit"]
    assert len(record["provenance"]["load_average"]) == 3
    assert record["provenance"]["packages"].get("eaik")


@pytest.mark.parametrize("args, named", [
    (["--seed", "1"], "--seed"),
    (["--seed", "101"], "--seed: 101"),
    (["--count", "1"], "--count"),
    (["--robot", "no-such-robot"], "no-such-robot"),
    (["--output", "{tmp}/summary.csv"], "--output"),
])
def test_bad_options_are_refused_in_one_line_with_nothing_written(args, named, tmp_path, capsys):
    out = tmp_path / "out"
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    argv = args if "--output" in args else [*args, "--output", str(out)]
    assert bare.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and named in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_an_analytic_branch_is_moved_by_whole_turns_into_the_limits():
    """Kinova's joint 2 is limited to 47-313 deg: EAIK's branch at -60 deg is the same frame
    at 300 deg, within them; an angle no whole turn brings in (20 deg) stays as it was."""
    from ikbench import load_robot

    robot = load_robot("example-robot-data:kinova")
    q = np.zeros(robot.dof)
    q[1], q[2] = np.radians(-60.0), np.radians(20.0)
    moved = bare._into_limits_by_turns(robot, q)
    assert np.degrees(moved[1]) == pytest.approx(300.0)
    assert moved[2] == q[2] and moved[0] == q[0]
