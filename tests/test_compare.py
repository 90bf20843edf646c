"""``ikbench report DIR``: methods side by side, figures recomputed from the CSVs, claims."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.compare import (
    BASELINE,
    OURS,
    check_claims,
    evaluate_runs,
    load_runs,
    table2_comparison,
    write_comparison_report,
)
from ikbench.report import paper_values
from tests.conftest import PAPER_START

TOUCH_1 = [33, 39, 25, 134, 102, 77, -168]


@pytest.fixture(scope="module")
def small_runs(tmp_path_factory):
    """ours (capped at 300 iterations) and sequential-ik on trajectory 1, n = 10."""
    out = tmp_path_factory.mktemp("compare")
    common = ["--only", "1", "--steps", "10", "--output", str(out), "--quiet"]
    assert main(["run", "--method", "ours", "--max-iterations", "300", *common]) == 0
    assert main(["run", "--method", "sequential-ik", *common]) == 0
    return out


def test_report_writes_claims_table2_and_figure(small_runs, capsys):
    assert main(["report", str(small_runs)]) == 0
    assert "report.md" in capsys.readouterr().out
    text = (small_runs / "report.md").read_text()
    claims = text.split("## The paper's claims")[1].split("\n## ")[0]
    for claim in ("much faster", "pointing deviation is much worse", "start pose varies",
                  "fluency is comparable"):
        row = next(line for line in claims.splitlines() if claim in line)
        assert row.rstrip().endswith(("| holds |", "| does not hold |"))
    assert "Beside the paper's Table 2" in text and "ikpy" in text and "different" in text
    assert "paper line distance [mm]" in text and "n = 10" in text
    for method in (OURS, BASELINE):
        assert f"| 1 | {method} |" in text  # side by side per trajectory
    png = (small_runs / "pointing_deviation_per_step.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


def test_write_comparison_report_returns_the_path(small_runs):
    path = write_comparison_report(small_runs)
    assert path == small_runs / "report.md" and path.is_file()


def test_figures_come_from_the_csvs_not_from_table_csv(small_runs, robot, tmp_path):
    # tamper with the baseline's table.csv: the report must still show the CSV's figures
    table_path = small_runs / BASELINE / "table.csv"
    original = table_path.read_text()
    table = pd.read_csv(table_path)
    table["line_distance_mean_mm"] = 999.0
    table["pointing_deviation_mean_deg"] = 999.0
    table.to_csv(table_path, index=False)
    try:
        runs, tasks, _ = load_runs(small_runs)
        frame = evaluate_runs(runs, tasks).set_index("method")
    finally:
        table_path.write_text(original)
    # independent: the fingertip columns of the CSV and the line through FK(start), FK(touch)
    csv = pd.read_csv(small_runs / BASELINE / "trajectory_1.csv")
    points = csv[["x_mm", "y_mm", "z_mm"]].to_numpy()
    p_s, p_e = robot.fk(np.array([PAPER_START, TOUCH_1]), backend="torch").point_mm
    axis = (p_e - p_s) / np.linalg.norm(p_e - p_s)
    rel = points - p_s
    distance = np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)
    directions = csv[["dir_x", "dir_y", "dir_z"]].to_numpy()
    deviation = np.degrees(np.arccos(np.clip(directions @ axis, -1, 1)))
    row = frame.loc[BASELINE]
    assert row["line_distance_mean_mm"] == pytest.approx(distance.mean(), abs=1e-6)
    assert row["pointing_deviation_mean_deg"] == pytest.approx(deviation.mean(), abs=1e-4)
    assert row["start_point_error_mm"] == pytest.approx(np.linalg.norm(points[0] - p_s),
                                                        abs=1e-6)


def _summary(ours: dict, base: dict) -> pd.DataFrame:
    keys = ["median duration [s]", "mean pointing deviation [deg]", "max |p_0 - p^s| [deg]",
            "median |p_0 - p^s| [deg]", "start pose spread [deg]", "start point spread [mm]",
            "max |P_0 - P_s| [mm]", "median mean sq. joint step [deg^2]",
            "median mean sq. jerk [deg^2]"]
    defaults = dict.fromkeys(keys, 1.0)
    return pd.DataFrame([{"method": OURS, **defaults, **ours},
                         {"method": BASELINE, **defaults, **base}])


def _verdicts(summary):
    return list(check_claims(summary)["verdict"])


def test_claims_thresholds():
    holds = _summary(
        {"median duration [s]": 10.0, "mean pointing deviation [deg]": 10.0,
         "max |p_0 - p^s| [deg]": 0.05, "median mean sq. joint step [deg^2]": 6.0,
         "median mean sq. jerk [deg^2]": 0.1},
        {"median duration [s]": 0.05, "mean pointing deviation [deg]": 60.0,
         "median |p_0 - p^s| [deg]": 20.0, "median mean sq. joint step [deg^2]": 9.0,
         "median mean sq. jerk [deg^2]": 0.15})
    assert _verdicts(holds) == ["holds"] * 4
    fails = _summary(
        {"median duration [s]": 1.0, "mean pointing deviation [deg]": 10.0,
         "max |p_0 - p^s| [deg]": 3.0, "median mean sq. joint step [deg^2]": 6.0,
         "median mean sq. jerk [deg^2]": 0.1},
        {"median duration [s]": 0.5, "mean pointing deviation [deg]": 0.3,
         "median |p_0 - p^s| [deg]": 100.0, "median mean sq. joint step [deg^2]": 6.0,
         "median mean sq. jerk [deg^2]": 10.0})
    assert _verdicts(fails) == ["does not hold"] * 4


def test_table2_paper_columns_are_the_printed_values_times_ten():
    table = pd.DataFrame([{"trajectory": "3", "line_distance_mean_mm": 1.0,
                           "line_distance_std_mm": 0.5, "pointing_deviation_mean_deg": 2.0,
                           "pointing_deviation_std_deg": 1.0, "start_point_error_mm": 4.0}])
    row = table2_comparison(table).iloc[0]
    printed = paper_values()["table2"]["3"]
    assert printed["line_distance_mean_printed"] == 1.39
    assert row["paper line distance [mm]"] == "13.9 ± 5.4"
    assert row["paper start point variation [mm]"] == "69"
    assert row["paper pointing deviation [deg]"] == "63 ± 33.2"
    assert row["line distance [mm]"] == "1.00 ± 0.50"


def test_bad_dir_is_one_line_exit_2(tmp_path, capsys):
    assert main(["report", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not a directory" in err
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "ours or sequential-ik" in err


def test_dir_with_only_one_method_names_the_missing_one(small_runs, tmp_path, capsys):
    import shutil

    shutil.copytree(small_runs / OURS, tmp_path / OURS)
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no sequential-ik results" in err and "ours" in err


def test_runs_on_different_steps_are_refused(small_runs, tmp_path, capsys):
    import shutil

    shutil.copytree(small_runs / OURS, tmp_path / OURS)
    assert main(["run", "--method", "sequential-ik", "--only", "1", "--steps", "12",
                 "--output", str(tmp_path), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "different targets, steps or start poses" in err
