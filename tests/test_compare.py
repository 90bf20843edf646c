"""``ikbench report DIR``: methods side by side, figures recomputed from the CSVs, claims."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from ikbench.cli import main
from ikbench.paper.baseline_claims import (
    BASELINE,
    BASELINE_WALK,
    OURS,
    check_claims,
    pointing_tradeoff_note,
)
from ikbench.paper.baseline_runs import (
    MethodRun,
    baseline_names,
    evaluate_runs,
    ikpy_table2_run,
    load_comparison,
    load_runs,
    table2_run,
)
from ikbench.paper.comparison import modes_table, table2_comparison, write_comparison_report
from ikbench.paper.values import paper_values
from ikbench.runtime.record import RunRecord
from tests.conftest import PAPER_START

TOUCH_1 = [33, 39, 25, 134, 102, 77, -168]


def _modes(result):
    """The report's modes table of a loaded comparison."""
    return modes_table(result.frame, result.runs, result.targets.steps, result.targets.is_paper)

#: The task each scheme solved, as the report labels its runs.
WALK = "walk from the touch pose: touch-pose-only task"
TRACK = "track from the start pose: the paper's task"


@pytest.fixture(scope="module")
def small_runs(tmp_path_factory):
    """ours (capped at 300 iterations) and the paper's baseline, sequential-ik-walk, on
    trajectory 1, n = 10, into sequential-ik/ (as ``ikbench reproduce`` names it)."""
    out = tmp_path_factory.mktemp("compare")
    common = ["--only", "1", "--steps", "10", "--output", str(out), "--quiet",
              "--no-animation"]
    assert main(["run", "--method", "ours", "--max-iterations", "300", *common]) == 0
    assert main(["run", "--method", BASELINE_WALK, "--name", BASELINE, *common]) == 0
    return out


@pytest.fixture(scope="module")
def mode_runs(small_runs, tmp_path_factory):
    """small_runs plus the other two orientation modes (--name), and folders of other
    commands that hold a run.json and trajectory CSVs too (decoys)."""
    import shutil

    out = tmp_path_factory.mktemp("modes")
    for name in (OURS, BASELINE):
        shutil.copytree(small_runs / name, out / name)
    common = ["--only", "1", "--steps", "10", "--output", str(out), "--quiet",
              "--no-animation"]
    for mode in ("position", "pointing"):
        assert main(["run", "--method", BASELINE_WALK, "--orientation", mode, "--name",
                     f"sequential-ik-{mode}", *common]) == 0
    for decoy in ("ablation", "batch", "sweep"):  # another command's folder, not a run
        shutil.copytree(out / "sequential-ik-position", out / decoy)
    shutil.copytree(out / BASELINE, out / "letters" / BASELINE)  # one level deeper
    (out / "notes").mkdir()  # a run.json that names no method
    (out / "notes" / "run.json").write_text('{"comment": "not a run"}')
    shutil.copy(out / BASELINE / "trajectory_1.csv", out / "notes")
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
            "median mean sq. jerk [deg^2]", "mean line distance [mm]"]
    defaults = dict.fromkeys(keys, 1.0)
    return pd.DataFrame([{"method": OURS, **defaults, "points missing the IK tolerance": np.nan,
                          "points solved": np.nan, **ours},
                         {"method": BASELINE, **defaults, "points missing the IK tolerance": 0,
                          "points solved": 350, **base}])


def _verdicts(summary):
    return list(check_claims(summary)["verdict"])


#: The summary columns the claims read, and their values (ours, sequential-ik) in a
#: comparison where every claim holds and in one where none does.
CLAIM_COLUMNS = ("median duration [s]", "mean pointing deviation [deg]", "max |p_0 - p^s| [deg]",
                 "median |p_0 - p^s| [deg]", "median mean sq. joint step [deg^2]",
                 "median mean sq. jerk [deg^2]")


@pytest.mark.parametrize("ours, base, verdict", [
    ((10.0, 10.0, 0.05, 1.0, 6.0, 0.1), (0.05, 60.0, 1.0, 20.0, 9.0, 0.15), "holds"),
    ((1.0, 10.0, 3.0, 1.0, 6.0, 0.1), (0.5, 0.3, 1.0, 100.0, 6.0, 10.0), "does not hold"),
])
def test_claims_thresholds(ours, base, verdict):
    summary = _summary(dict(zip(CLAIM_COLUMNS, ours)), dict(zip(CLAIM_COLUMNS, base)))
    assert _verdicts(summary) == [verdict] * 4


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
    with pytest.raises(SystemExit) as exit_info:  # refused by the parser (cli/values.py)
        main(["report", str(tmp_path / "missing")])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "argument DIR" in err and "not found" in err
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


def test_every_run_folder_side_by_side_and_claims_per_baseline_mode(mode_runs, capsys):
    assert main(["report", str(mode_runs)]) == 0
    capsys.readouterr()
    text = (mode_runs / "report.md").read_text()
    assert text.splitlines()[0] == ("# Comparison: ours, sequential-ik, sequential-ik-pointing, "
                                    "sequential-ik-position")
    for decoy in ("ablation", "batch", "sweep", "letters", "notes"):
        assert f"| {decoy} |" not in text and f"`{decoy}`" not in text
    claims = text.split("## The paper's claims")[1].split("\n## ")[0]
    headings = [line for line in claims.splitlines() if line.startswith("### ")]
    assert headings == [f"### `{name}` (sequential-ik-walk, --orientation {mode}; {WALK}) "
                        "against `ours`" for name, mode in
                        [("sequential-ik", "frame"), ("sequential-ik-pointing", "pointing"),
                         ("sequential-ik-position", "position")]]
    tables = claims.split("### ")[1:]
    for table, name in zip(tables, ["sequential-ik", "sequential-ik-pointing",
                                    "sequential-ik-position"]):
        assert table.count("| holds |") + table.count("| does not hold |") == 4
        assert f"ratio ours / {name} = " in table and table.startswith(f"`{name}` ")
        assert "Task solved: walk from the touch pose (touch-pose-only task: the start pose " \
            "is free)." in table
    modes = text.split("## The baseline's orientation modes")[1].split("\n## ")[0]
    rows = [line for line in modes.splitlines() if line.startswith("| ")][1:]
    assert [row.split(" | ")[0:4] for row in rows] == [
        ["| ours", "ours", "", "the paper's task (whole trajectory; start and touch poses in "
         "its loss)"],
        *[[f"| {name}", BASELINE_WALK, mode, "touch-pose-only (walk from the touch pose; the "
           "start pose is free)"] for name, mode in
          [("sequential-ik", "frame"), ("sequential-ik-pointing", "pointing"),
           ("sequential-ik-position", "position")]],
        ["| paper (ikpy, other URDF)", "", "", "touch-pose-only (the authors' walk from the "
         "touch pose)"]]
    assert f"## Beside the paper's Table 2: sequential-ik (sequential-ik-walk, --orientation " \
        f"frame; {WALK})" in text
    for name in ("sequential-ik-pointing", "sequential-ik-position"):
        assert f"| 1 | {name} |" in text  # side by side per trajectory


@pytest.fixture(scope="module")
def ikpy_runs(small_runs, tmp_path_factory):
    """ours, sequential-ik-walk and the authors' ikpy call (ikpy-walk into ikpy/, as
    ``ikbench reproduce`` names it; needs ikpy: the [libs] extra)."""
    import shutil

    from ikbench.methods.registry import method_status

    status = method_status()["ikpy-walk"]
    if not status.available:
        pytest.skip(f"ikpy-walk: {status.reason}")
    out = tmp_path_factory.mktemp("ikpy")
    for name in (OURS, BASELINE):
        shutil.copytree(small_runs / name, out / name)
    assert main(["run", "--method", "ikpy-walk", "--name", "ikpy", "--only", "1", "--steps",
                 "10", "--output", str(out), "--quiet", "--no-animation"]) == 0
    return out


def test_ikpy_runs_are_baseline_runs_with_their_own_table2(ikpy_runs, tmp_path):
    import shutil

    assert main(["report", str(ikpy_runs)]) == 0
    text = (ikpy_runs / "report.md").read_text()
    claims = text.split("## The paper's claims")[1].split("\n## ")[0]
    assert [line for line in claims.splitlines() if line.startswith("### ")] == [
        f"### `sequential-ik` (sequential-ik-walk, --orientation frame; {WALK}) against `ours`",
        f"### `ikpy` (ikpy-walk, --ikpy-orientation position; {WALK}) against `ours`"]
    assert "`ikpy`, the authors' own library, solves" in claims
    assert f"## Beside the paper's Table 2: sequential-ik (sequential-ik-walk, --orientation " \
        f"frame; {WALK})" in text
    assert f"## Beside the paper's Table 2: ikpy (ikpy-walk, --ikpy-orientation position; " \
        f"{WALK}), the authors' call" in text
    assert "their library (ikpy) and their call" in text.split("the authors' call")[1]
    rows = _modes(load_comparison(ikpy_runs)).set_index("run")
    assert rows.loc["ikpy", "orientation"] == "position"
    assert rows.loc["ikpy", "method"] == "ikpy-walk"
    details = pd.read_csv(ikpy_runs / "ikpy" / "details.csv")
    missed = int(details["points_not_converged"].iloc[0])  # its answers checked by FK
    assert rows.loc["ikpy", "points missing the IK tolerance (of 10, per trajectory)"] == \
        ("none" if missed == 0 else str(missed))
    # ours and ikpy alone are a comparison too: ikpy is the baseline
    alone = tmp_path / "alone"
    for name in (OURS, "ikpy"):
        shutil.copytree(ikpy_runs / name, alone / name)
    assert load_comparison(alone).baselines == ["ikpy"]


def test_modes_table_figures_come_from_the_runs(mode_runs):
    result = load_comparison(mode_runs)
    table = _modes(result).set_index("run")
    frame = result.frame.set_index("method")
    for name in ("sequential-ik", "sequential-ik-pointing", "sequential-ik-position"):
        row = frame.loc[name]
        assert table.loc[name, "line distance, mean [mm]"] == \
            f"{row['line_distance_mean_mm']:.2f}"
        assert table.loc[name, "pointing deviation, mean [deg]"] == \
            f"{row['pointing_deviation_mean_deg']:.2f}"
        assert table.loc[name, "time per trajectory [ms]"] == f"{row['duration_s'] * 1000:.1f}"
        details = pd.read_csv(mode_runs / name / "details.csv")
        missed = int(details["points_not_converged"].iloc[0])
        assert table.loc[name, "points missing the IK tolerance (of 10, per trajectory)"] == \
            ("none" if missed == 0 else str(missed))
    # the paper's row: its trajectory-1 values, cm shown x 10
    assert table.loc["paper (ikpy, other URDF)", "line distance, mean [mm]"] == "28.4"
    assert table.loc["paper (ikpy, other URDF)", "pointing deviation, mean [deg]"] == "65"


def test_pointing_claim_shows_the_line_distance_and_missed_points():
    summary = _summary(
        {"mean pointing deviation [deg]": 11.9, "mean line distance [mm]": 3.2},
        {"mean pointing deviation [deg]": 0.26, "mean line distance [mm]": 32.9,
         "points missing the IK tolerance": 197, "points solved": 350})
    measured = check_claims(summary).set_index("paper's claim").loc[
        "its pointing deviation is much worse", "measured"]
    assert "mean line distance: ours 3.20 mm, sequential-ik 32.90 mm" in measured
    assert "sequential-ik: 197 of 350 points missed the IK tolerance" in measured
    note = pointing_tradeoff_note(summary)
    assert "gives up the position" in note and "32.90 mm against 3.20 mm" in note
    assert "197 of 350 points missed the IK tolerance" in note
    # pointing worse, or line followed: no note
    assert pointing_tradeoff_note(_summary(
        {"mean pointing deviation [deg]": 11.9, "mean line distance [mm]": 3.2},
        {"mean pointing deviation [deg]": 35.0, "mean line distance [mm]": 32.9})) == ""
    assert pointing_tradeoff_note(_summary(
        {"mean pointing deviation [deg]": 11.9, "mean line distance [mm]": 3.2},
        {"mean pointing deviation [deg]": 0.2, "mean line distance [mm]": 0.0})) == ""


def test_claims_table_names_the_baseline_run():
    summary = _summary({}, {}).replace({"method": {BASELINE: "sequential-ik-position"}})
    claims = check_claims(summary, "sequential-ik-position")
    assert "ratio ours / sequential-ik-position" in claims["measured"].iloc[0]
    assert not any("sequential-ik " in m for m in claims["measured"])


@pytest.mark.parametrize("name, message", [
    ("../out", "--name: '../out' is not allowed"),
    (".résumé", "--name: '.résumé' is not allowed"),
    ("", "argument --name: '' is empty"),
    ("ablation", "--name: 'ablation' is the folder of another command"),
])
def test_bad_name_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, name, message):
    try:  # the parser refuses some names itself (cli/values.py), the study the others
        code = main(["run", "--method", "sequential-ik", "--only", "1", "--steps", "4",
                     "--output", str(tmp_path / "out"), "--name", name, "--quiet"])
    except SystemExit as exit_info:
        code = exit_info.code
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err
    assert not (tmp_path / "out").exists()


def test_a_run_name_of_unicode_letters_is_taken(tmp_path, capsys):
    """Issue 64: ``--name résumé`` was refused as not letters; a separator or a leading dot
    still is (above)."""
    assert main(["run", "--method", "sequential-ik", "--only", "1", "--steps", "4",
                 "--output", str(tmp_path), "--name", "résumé", "--quiet",
                 "--no-animation"]) == 0
    record = json.loads((tmp_path / "résumé" / "run.json").read_text())
    assert record["name"] == "résumé"


def test_run_name_sets_the_folder_and_run_json(tmp_path):
    from ikbench.studies.run import run

    table = run("sequential-ik", only="7", steps=4, output=tmp_path, progress=False,
                options={"orientation": "position"}, name="position-mode")
    folder = tmp_path / "position-mode"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["position-mode"]
    record = json.loads((folder / "run.json").read_text())
    assert record["method"] == "sequential-ik" and record["name"] == "position-mode"
    assert list(table["method"]) == ["sequential-ik"]
    assert (folder / "report.md").read_text().startswith(
        "# position-mode (sequential-ik): ")


@pytest.fixture(scope="module")
def scheme_runs(small_runs, tmp_path_factory):
    """ours, the paper's baseline walk (sequential-ik-walk) and a sequential-ik track run
    (its default scheme: the paper's task) into the folder named sequential-ik."""
    import shutil

    from ikbench.studies.run import run

    out = tmp_path_factory.mktemp("schemes")
    shutil.copytree(small_runs / OURS, out / OURS)
    for method in (BASELINE_WALK, BASELINE):  # the track takes the folder sequential-ik
        run(method, only="1", steps=10, output=out, progress=False, animation=False)
    return out


def test_report_states_the_task_each_baseline_run_solved(scheme_runs):
    result = load_comparison(scheme_runs)
    runs = result.runs
    assert json.loads((scheme_runs / BASELINE / "run.json").read_text())["settings"][
        "settings"]["scheme"] == "track"
    assert (runs[BASELINE].scheme, runs[BASELINE_WALK].scheme) == ("track", "walk")
    assert result.baselines == [BASELINE_WALK, BASELINE]  # the walk (Table 2's scheme) first
    assert table2_run(runs) == BASELINE_WALK and ikpy_table2_run(runs) is None
    path = write_comparison_report(scheme_runs)
    text = path.read_text()
    claims = text.split("## The paper's claims")[1].split("\n## ")[0]
    assert [line for line in claims.splitlines() if line.startswith("### ")] == [
        f"### `{BASELINE_WALK}` (--orientation frame; {WALK}) against `ours`",
        f"### `{BASELINE}` (--orientation pointing; {TRACK}) against `ours`"]
    walk, track = claims.split("\n### ")[1:]
    assert "Task solved: walk from the touch pose (touch-pose-only task: the start pose is " \
        "free)." in walk
    assert "Task solved: track from the start pose (the paper's task: start and touch poses " \
        "fixed)." in track
    # the start-pose claim: checked with numbers on both, and says what it is about
    walk_row = next(line for line in walk.splitlines() if "start pose varies" in line)
    track_row = next(line for line in track.splitlines() if "start pose varies" in line)
    assert "a property of the walk" in walk_row and walk_row.endswith("| holds |")
    assert "by construction" in track_row and track_row.endswith("| does not hold |")
    start = result.summary.set_index("method").loc[BASELINE, "median |p_0 - p^s| [deg]"]
    assert f"{BASELINE} median {start:.2f}" in track_row
    note = next(line for line in track.splitlines()
                if line.startswith("The start-pose claim is about the walk"))
    assert "the walks from the touch pose (touch-pose-only task" in note
    assert "the tracks from the start pose (the paper's task" in note
    # the modes table: a column for the task solved
    rows = _modes(result).set_index("run")["task solved"]
    assert rows[BASELINE_WALK].startswith("touch-pose-only")
    assert rows[BASELINE].startswith("the paper's task")
    # Table 2 is the walk, and says so
    assert (f"## Beside the paper's Table 2: {BASELINE_WALK} (--orientation frame; {WALK})"
            in text)
    assert "the task the paper's baseline solved for its Table 2" in text
    # the track run's own report says which task it solved beside Table 2
    own = (scheme_runs / BASELINE / "report.md").read_text()
    assert "Task solved: track from the start pose (the paper's task" in own
    assert "not comparable with the paper's column" in own


def test_scheme_of_a_run_and_old_folders_are_walks():
    def made(name, method, **settings):
        return MethodRun(name, RunRecord.from_dict(
            {"method": method, "settings": {"settings": settings}}), {}, {})

    runs = {r.name: r for r in [
        made("ours", "ours", init="random"),
        made("ikpy", "ikpy", orientation="position"),  # before the schemes: a walk
        made("ikpy-track", "ikpy", scheme="track", orientation="position"),
        made("ikpy-pointing", "ikpy-walk", scheme="walk", orientation="pointing"),
        made("sequential-ik", "sequential-ik", orientation="frame"),  # old: a walk
        made("seq-track", "sequential-ik", scheme="track", orientation="frame"),
    ]}
    assert runs["ours"].scheme is None and runs["ours"].label == "ours"
    assert runs["ikpy"].scheme == "walk" and runs["seq-track"].scheme == "track"
    assert runs["ikpy-pointing"].family == "ikpy" and runs["ikpy-pointing"].is_baseline
    assert runs["sequential-ik"].label == f"sequential-ik (--orientation frame; {WALK})"
    assert runs["ikpy-track"].label == (f"ikpy-track (ikpy, --ikpy-orientation position; "
                                        f"{TRACK})")
    assert baseline_names(runs) == ["sequential-ik", "seq-track", "ikpy", "ikpy-pointing",
                                    "ikpy-track"]
    assert table2_run(runs) == "sequential-ik" and ikpy_table2_run(runs) == "ikpy"
    del runs["sequential-ik"], runs["ikpy"]
    assert table2_run(runs) == "ikpy-pointing"  # a walk before any track
    assert ikpy_table2_run(runs) is None  # the authors' call is a walk in position mode


def test_start_pose_claim_names_the_scheme():
    walk = check_claims(_summary({}, {}), scheme="walk")["paper's claim"].iloc[2]
    track = check_claims(_summary({}, {}), scheme="track")["paper's claim"].iloc[2]
    assert walk.startswith("its start pose varies, while ours is constant (a property of "
                           "the walk") and "touch-pose-only" in walk
    assert "the paper's task" in track and "by construction" in track
    assert check_claims(_summary({}, {}))["paper's claim"].iloc[2] == \
        "its start pose varies, while ours is constant"
