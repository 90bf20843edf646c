"""Loss-term ablation: variants, the joint-interpolation distance, the claim checks, and a
small end-to-end run whose numbers are re-derived from the written trajectories."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import pytest

from ikbench import methods
from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.losses import PAPER_WEIGHTS, TERMS, objective
from ikbench.core.metrics import trajectory_metrics
from ikbench.core.task import line_tasks
from ikbench.core.trajectory import read_trajectory_poses
from ikbench.paper.ablation_claims import check_claims
from ikbench.render.run_report import TABLE_COLUMNS
from ikbench.studies.ablation import (
    FULL,
    SUMMARY_METRICS,
    Variant,
    ablate,
    check_method,
    joint_interpolation_distance_deg,
    parse_drops,
)
from tests.conftest import fails_if_called, register_temporarily, unwritable_output_error


def test_parse_drops_full_first_then_each_spec():
    assert [v.name for v in parse_drops("L1")] == [FULL, "no-L1"]
    assert [v.name for v in parse_drops(["l5, L2", "L2,L5"])] == [FULL, "no-L2-L5"]
    every = parse_drops(["each", "L2,L3,L4,L5", "L1"])
    assert [v.name for v in every] == [FULL, *(f"no-{t}" for t in TERMS), "no-L2-L3-L4-L5"]
    assert Variant(("L1",)).weights(PAPER_WEIGHTS) == {**PAPER_WEIGHTS, "L1": 0.0}


@pytest.mark.parametrize("spec", ["L7", "L1,foo", "", "c1"])
def test_parse_drops_rejects_unknown_terms_listing_valid(spec):
    with pytest.raises(InputError, match="valid: L0, L1, L2, L3, L4, L5, L6; or each"):
        parse_drops(spec)


def test_parse_drops_rejects_dropping_everything():
    with pytest.raises(InputError, match="drops every term"):
        parse_drops(",".join(TERMS))


def test_cli_unknown_term_one_line_exit_2(capsys):
    assert main(["ablate", "--drop", "L1,L9", "--only", "1"]) == 2
    err = capsys.readouterr().err
    assert err == ("ikbench: error: --drop: unknown loss term(s) 'L9'; valid: L0, L1, L2, L3, "
                   "L4, L5, L6; or each\n")


def test_method_without_weights_rejected(monkeypatch, capsys):
    @dataclass
    class Tolerance:
        tolerance: float = methods.option(1.0, help="a tolerance")

    class NoWeights(methods.Method):
        name = "no-weights"
        Settings = Tolerance

    register_temporarily(monkeypatch, NoWeights)
    assert check_method("ours").name == "ours"
    with pytest.raises(InputError, match="'no-weights' has no loss weights to drop; methods "
                       "that have: .*ours"):
        check_method("no-weights")
    assert main(["ablate", "--drop", "L1", "--method", "no-weights"]) == 2
    assert "has no loss weights" in capsys.readouterr().err


def test_joint_interpolation_distance():
    start, end = np.array([0.0, 10.0, -5.0]), np.array([10.0, 30.0, 5.0])
    line = start + np.linspace(0, 1, 6)[:, None] * (end - start)
    assert joint_interpolation_distance_deg(line, start, end) == 0.0
    bumped = line.copy()
    bumped[2, 1] += 3.0   # one pose off by 3 deg in one joint, another by -6 in two joints
    bumped[4, [0, 2]] -= 6.0
    assert joint_interpolation_distance_deg(bumped, start, end) == pytest.approx(9.0 / 6)


def _synthetic(**overrides) -> pd.DataFrame:
    """Two trajectories per variant; every figure 1.0 unless overridden per variant."""
    rows = []
    for variant in [FULL, "no-L0", "no-L1", "no-L6", "no-L2-L3-L4-L5"]:
        for trajectory in ("1", "2"):
            row = {"variant": variant, "trajectory": trajectory, "dropped": "",
                   **{c: 1.0 for c in SUMMARY_METRICS}}
            row.update(overrides.get(variant, {}))
            rows.append(row)
    return pd.DataFrame(rows)


def _verdicts(table) -> list[str]:
    return [c["verdict"] for c in check_claims(table)]


def test_claims_hold_when_the_figures_say_so():
    table = _synthetic(**{
        "no-L0": {"line_distance_mean_mm": 12.0, "joint_interpolation_distance_deg": 0.3},
        "no-L6": {"mean_sq_jerk_deg2": 50.0, "velocity_sign_changes": 2.5},
        "no-L1": {"pointing_deviation_mean_deg": 1.5},
        "no-L2-L3-L4-L5": {"line_distance_mean_mm": 1.2, "end_point_error_mm": 40.0},
    })
    assert _verdicts(table) == ["holds"] * 6
    claims = check_claims(table)
    assert "full 1° → no-L1 1.5° (×1.5), higher on 2 of 2 trajectories" in claims[2]["evidence"]
    assert "end point error [mm]: full 1 mm → no-L2-L3-L4-L5 40 mm (×40)" in claims[5]["evidence"]


def test_claims_do_not_hold_when_nothing_changes_or_too_much():
    table = _synthetic(**{"no-L1": {"pointing_deviation_mean_deg": 30.0},
                          "no-L2-L3-L4-L5": {"pointing_deviation_mean_deg": 2.0}})
    assert _verdicts(table) == ["does not hold"] * 6


def test_claims_not_tested_without_their_variant():
    table = _synthetic()
    assert _verdicts(table[table.variant.isin([FULL, "no-L1"])]) == [
        "not tested", "not tested", "does not hold", "not tested", "not tested", "not tested"]


@pytest.fixture(scope="module")
def small_ablation(tmp_path_factory):
    """--drop L1 on trajectory 2 with n = 10 and a 40-iteration cap (loss stays above 10)."""
    out = tmp_path_factory.mktemp("ablation")
    table = ablate(["L1"], "ours", only="2", steps=10, output=out, options={"max_iterations": 40},
                   progress=False)
    return out / "ablation", table


def test_small_ablation_writes_every_output(small_ablation):
    root, table = small_ablation
    for name in ["table.csv", "summary.csv", "run.json", "report.md", "metrics.png",
                 "trajectories_3d.png", "joints.png", "full/trajectory_2.csv",
                 "no-L1/trajectory_2.csv"]:
        assert (root / name).stat().st_size > 0, name
    written = pd.read_csv(root / "table.csv", dtype={"trajectory": str})
    assert list(written["variant"]) == [FULL, "no-L1"]
    assert set(TABLE_COLUMNS) <= set(written.columns)
    assert list(written["iterations"]) == [40, 40]
    assert written["hit_cap"].tolist() == [True, True]
    report = (root / "report.md").read_text()
    assert "Dropping L1 moderately affects the pointing. | **" in report
    assert report.count("**not tested**") == 5


def test_small_ablation_numbers_come_from_the_written_trajectories(small_ablation, robot,
                                                                     paper_targets):
    root, table = small_ablation
    task = line_tasks(robot, paper_targets.select("2").with_steps(10))[0]
    for _, row in table.iterrows():
        poses = read_trajectory_poses(root / row["variant"] / "trajectory_2.csv", robot)
        expected = trajectory_metrics(robot, task, poses)
        for column in ["line_distance_mean_mm", "pointing_deviation_mean_deg",
                       "end_pose_error_deg", "mean_sq_jerk_deg2", "velocity_sign_changes"]:
            assert row[column] == pytest.approx(expected[column], rel=1e-12), column
        assert row["joint_interpolation_distance_deg"] == pytest.approx(
            joint_interpolation_distance_deg(poses, task.required.start_pose,
                                             task.required.end_pose))
        assert row["paper_loss"] == pytest.approx(objective(robot, task, poses)[0], rel=1e-12)


def test_small_ablation_really_drops_the_term(small_ablation, robot, paper_targets):
    """The solver's loss is the ablated objective at its poses, not the full one."""
    root, table = small_ablation
    task = line_tasks(robot, paper_targets.select("2").with_steps(10))[0]
    no_l1 = table.set_index("variant").loc["no-L1"]
    poses = read_trajectory_poses(root / "no-L1" / "trajectory_2.csv", robot)
    full_loss, terms = objective(robot, task, poses)
    ablated = full_loss - PAPER_WEIGHTS["L1"] * terms["L1"]
    assert terms["L1"] > 1e-3
    assert no_l1["loss"] == pytest.approx(ablated, rel=1e-4)
    assert no_l1["paper_loss"] == pytest.approx(full_loss, rel=1e-12)
    full = table.set_index("variant").loc[FULL]
    assert full["loss"] == pytest.approx(full["paper_loss"], rel=1e-4)


@pytest.mark.parametrize("spec", ["each,L1", "L1, EACH"])
def test_each_inside_a_list_says_it_must_be_its_own_value(spec):
    with pytest.raises(InputError, match=r"'each' must be its own --drop value \(e\.g\. --drop "
                       r"each --drop L2,L3\); a list names terms among L0, L1"):
        parse_drops(spec)


def test_cli_rejects_options_of_other_methods(capsys):
    assert main(["ablate", "--drop", "L1", "--method", "ours", "--lm-linear-solver", "thomas",
                 "--only", "1"]) == 2
    err = capsys.readouterr().err
    assert err == ("ikbench: error: --lm-linear-solver is an option of --method ours-lm, not "
                   "of --method ours\n")


def test_unwritable_output_fails_before_any_solve(tmp_path, monkeypatch, capsys):
    import ikbench.studies.ablation as ablation

    fails_if_called(monkeypatch, ablation, "solve_tasks")
    assert "cannot write" in unwritable_output_error(capsys, tmp_path,
                                                     ["ablate", "--drop", "L1", "--only", "1"])
    out = tmp_path / "fresh"
    (tmp_path / "fresh").mkdir()
    (out / "ablation").write_text("")  # the ablation folder's name taken by a file
    assert main(["ablate", "--drop", "L1", "--only", "1", "--output", str(out)]) == 2
    assert "is a file, not a directory" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["ablation"]


def test_a_smaller_ablation_removes_stale_variants_and_trajectories(tmp_path):
    common = {"steps": 4, "output": tmp_path, "options": {"max_iterations": 3},
              "progress": False}
    ablate(["L1", "L2,L5"], "ours", only="1,2", **common)
    root = tmp_path / "ablation"
    (root / "no-L2-L5" / "notes.txt").write_text("mine")  # kept, and so is its folder
    (root / "no-L3").mkdir()  # a variant-named folder of an even older run: emptied, removed
    (root / "no-L3" / "trajectory_1.csv").write_text("old")
    (root / "plots").mkdir()  # not a variant name: untouched
    (root / "plots" / "trajectory_1.csv").write_text("mine")
    ablate(["L1"], "ours", only="2", **common)
    assert sorted(p.relative_to(root).as_posix() for p in root.rglob("trajectory_*.csv")) == [
        "full/trajectory_2.csv", "no-L1/trajectory_2.csv", "plots/trajectory_1.csv"]
    assert not (root / "no-L3").exists()
    assert sorted(p.name for p in (root / "no-L2-L5").iterdir()) == ["notes.txt"]
    table = pd.read_csv(root / "table.csv", dtype={"trajectory": str})
    assert list(zip(table["variant"], table["trajectory"])) == [("full", "2"), ("no-L1", "2")]
