"""ikbench.core.legibility: the observers' order on synthetic motions, the docs' worked example,
and the columns on NICO's and the Panda's comparisons."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from ikbench.core import legibility as L
from ikbench.core import metrics
from ikbench.core.legibility import LEGIBILITY_COLUMNS

REPO = Path(__file__).resolve().parents[1]
GOALS = np.array([[100.0, 30.0, 0.0], [100.0, -30.0, 0.0]])
TIMES = np.array([0.0, 1.0, 2.0])
STRAIGHT = np.array([[0.0, 0.0, 0.0], [50.0, 15.0, 0.0], [100.0, 30.0, 0.0]])
EXAGGERATED = np.array([[0.0, 0.0, 0.0], [50.0, 45.0, 0.0], [100.0, 30.0, 0.0]])


def _line(start, end, bulge, n=50):
    """n + 1 points from start to end, pushed ``bulge`` [mm] sideways (+y) by a sine arch."""
    s = np.linspace(0.0, 1.0, n + 1)[:, None]
    return (1 - s) * start + s * end + np.sin(np.pi * s) * np.array([0.0, bulge, 0.0])


def test_metrics_reexports_the_public_functions():
    assert metrics.position_legibility is L.position_legibility
    assert metrics.pointing_legibility is L.pointing_legibility
    assert metrics.predictability is L.predictability


def test_exaggerating_away_from_the_neighbour_is_more_legible_and_less_predictable():
    goals = np.array([[300.0, 40.0, 0.0], [300.0, -40.0, 0.0], [300.0, -120.0, 0.0]])
    times = L.constant_times_s(51, 2.0)
    straight = _line(np.zeros(3), goals[0], 0.0)
    exaggerated = _line(np.zeros(3), goals[0], 60.0)  # away from goal 1, its neighbour
    legible = [L.position_legibility(p, goals, 0, times) for p in (straight, exaggerated)]
    predictable = [L.predictability(p, times) for p in (straight, exaggerated)]
    assert legible[1] > legible[0] + 0.05
    assert predictable[0] == pytest.approx(1.0)
    assert predictable[1] < 0.9
    # exaggerating *towards* the neighbour is less legible than the straight line
    towards = _line(np.zeros(3), goals[0], -60.0)
    assert L.position_legibility(towards, goals, 0, times) < legible[0]


def test_pointing_at_the_goal_from_the_start_beats_turning_late():
    goals = np.array([[300.0, 60.0, 0.0], [300.0, -60.0, 0.0]])
    times = L.constant_times_s(51, 2.0)
    points = _line(np.zeros(3), goals[0], 0.0)
    at_goal = goals[0] - points
    at_goal[-1] = at_goal[-2]  # at the goal itself: the last direction
    early = at_goal / np.linalg.norm(at_goal, axis=1, keepdims=True)
    late = early.copy()
    late[:40] = (goals[1] - points[:40]) / np.linalg.norm(goals[1] - points[:40], axis=1,
                                                          keepdims=True)
    scores = [L.pointing_legibility(points, d, goals, 0, times) for d in (early, late)]
    assert scores[0] > 0.9 > 0.5 > scores[1]
    p_early = L.pointing_probabilities(points, early, goals)[:, 0]
    p_late = L.pointing_probabilities(points, late, goals)[:, 0]
    assert L.inferred_time_s(p_early, times) == 0.0
    assert L.inferred_time_s(p_late, times) == pytest.approx(times[40])


def _docs_example() -> dict[str, list[float]]:
    """The worked example's numbers as docs/legibility.md gives them."""
    text = (REPO / "docs" / "legibility.md").read_text(encoding="utf-8")
    block = text.split("## A worked example", 1)[1].split("```text", 1)[1].split("```", 1)[0]
    rows = {}
    for line in block.strip().splitlines():
        name = line.split()[0]
        rows[name] = [float(v) for v in re.findall(r"-?\d+(?:\.\d+)?", line)]
    return rows


def test_the_docs_worked_example_is_what_the_code_computes():
    """docs/legibility.md's example: P(G1) at each point, the legibility, the inferred time
    and the predictability of the straight and the exaggerated motion (also derived by hand
    there)."""
    rows = _docs_example()
    assert set(rows) == {"straight", "exaggerated"}
    assert L.length_scale_mm(GOALS) == pytest.approx(60.0)
    for name, points in (("straight", STRAIGHT), ("exaggerated", EXAGGERATED)):
        # P(G1) x3, G1's label 1 in "P(G1)" first, then legibility, inferred, predictability
        label, *p, legibility, inferred, predictable = rows[name]
        assert label == 1
        got = L.position_probabilities(points, GOALS, TIMES)[:, 0]
        np.testing.assert_allclose(got, p, atol=1e-6)
        assert L.position_legibility(points, GOALS, 0, TIMES) == pytest.approx(legibility,
                                                                               abs=1e-6)
        assert L.inferred_time_s(got, TIMES) == inferred
        assert L.predictability(points, TIMES) == pytest.approx(predictable, abs=1e-6)
    # the hand derivation: log-odds 1 and 3 at the middle point
    assert rows["straight"][2] == pytest.approx(1 / (1 + np.exp(-1)), abs=1e-6)
    assert rows["exaggerated"][2] == pytest.approx(1 / (1 + np.exp(-3)), abs=1e-6)


def test_a_minimum_jerk_line_has_dimensionless_jerk_720():
    times = np.linspace(0.0, 2.0, 4001)
    tau = times / 2.0
    x = 300.0 * (10 * tau ** 3 - 15 * tau ** 4 + 6 * tau ** 5)
    points = np.stack([x, 0 * x, 0 * x], axis=1)
    assert L.dimensionless_jerk(points, times) == pytest.approx(720.0, rel=0.01)
    # jerk of the profile at t = 0: 60 L / T^3
    assert L.peak_joint_jerk(points[:, :1], times) == pytest.approx(60 * 300 / 8, rel=0.01)


def test_the_inferred_time_needs_the_probability_to_stay_above():
    times = np.arange(5.0)
    assert L.inferred_time_s([0.2, 0.6, 0.4, 0.7, 0.9], times) == 3.0
    assert np.isnan(L.inferred_time_s([0.2, 0.6, 0.7, 0.9, 0.5], times))


def test_a_true_goal_outside_the_set_is_added():
    goals, index = L.true_goal_index(GOALS, [0.0, 0.0, 50.0])
    assert index == 2 and len(goals) == 3
    goals, index = L.true_goal_index(GOALS, GOALS[1] + 0.5)
    assert index == 1 and len(goals) == 2


def test_compare_writes_the_columns_and_figures_for_nico(tmp_path):
    from ikbench.studies.compare import COLUMNS, compare

    result = compare("sequential-ik", only="3", steps=10, repeat=1, warmup=0, sweep=False,
                     output=tmp_path, progress=False)
    assert COLUMNS[-len(LEGIBILITY_COLUMNS):] == LEGIBILITY_COLUMNS
    row = result.results.iloc[0]
    assert 0.0 < row["position_legibility"] < 1.0
    assert row["position_final_p"] == pytest.approx(1.0)
    assert 0.0 < row["pointing_legibility"] < 1.0
    assert row["predictability"] == pytest.approx(1.0, abs=1e-3)  # the straight line
    board = result.leaderboard
    assert list(board.columns[-len(LEGIBILITY_COLUMNS):]) == LEGIBILITY_COLUMNS  # no obstacles
    folder = tmp_path / "compare"
    assert (folder / "legibility.png").stat().st_size > 0
    assert (folder / "legibility_sequential-ik.png").stat().st_size > 0
    assert "position legibility" in (folder / "leaderboard.md").read_text()


def test_goals_override_the_goal_set(tmp_path):
    """--goals with a file of one touch pose: the true goal (another) is added, two goals."""
    import json

    import pandas as pd

    from ikbench.cli import main

    spec = json.loads((REPO / "urdf" / "nico_right_arm.targets.json").read_text())
    spec["targets"] = {"1": spec["targets"]["1"]}
    goals = tmp_path / "goals.json"
    goals.write_text(json.dumps(spec))
    code = main(["compare", "--methods", "sequential-ik", "--only", "3", "--steps", "10",
                 "--repeat", "1", "--goals", str(goals), "--output", str(tmp_path), "--quiet"])
    assert code == 0
    from ikbench.studies.compare import compare

    two = pd.read_csv(tmp_path / "compare" / "results.csv")["pointing_legibility"].iloc[0]
    seven = compare("sequential-ik", only="3", steps=10, repeat=1, warmup=0, sweep=False,
                    output=None, progress=False).results["pointing_legibility"].iloc[0]
    # fewer rivals: the observer is surer of the true goal
    assert two > seven


def test_a_run_report_gains_the_legibility_section(tmp_path):
    """ikbench run (line shape): details.csv has the columns, report.md the section; with
    --only the goal set is still every touch point of the targets (the CLI's default)."""
    import pandas as pd

    from ikbench.cli import main

    code = main(["run", "--method", "sequential-ik", "--only", "3", "--steps", "10",
                 "--no-animation", "--output", str(tmp_path), "--quiet"])
    assert code == 0
    details = pd.read_csv(tmp_path / "sequential-ik" / "details.csv")
    assert set(LEGIBILITY_COLUMNS) <= set(details.columns)
    assert details["position_final_p"].iloc[0] == pytest.approx(1.0)
    # seven goals: the observer starts at chance, so legibility is well below 1
    assert details["position_legibility"].iloc[0] < 0.9
    assert "## Legibility" in (tmp_path / "sequential-ik" / "report.md").read_text()


def test_a_straight_constant_speed_line_never_falls_below_its_prior_share():
    """C + V_G(Q, tau) = V_G(S) for the goal the line heads to and >= for the others, so its
    P(G*) stays >= 1/K at every point (random goal sets, seeded)."""
    rng = np.random.default_rng(48)
    times = L.constant_times_s(31, 2.0)
    for _ in range(20):
        goals = rng.uniform(-300.0, 300.0, size=(5, 3)) + np.array([400.0, 0.0, 0.0])
        true = int(rng.integers(5))
        points = _line(np.zeros(3), goals[true], 0.0, n=30)
        p = L.position_probabilities(points, goals, times)[:, true]
        assert np.all(p >= 1 / 5 - 1e-12)
        assert p[-1] == pytest.approx(1.0)


def test_without_the_time_scaling_the_observer_reads_distance_alone():
    """``time_scaled=False`` (the ``position_legibility_unscaled`` column): log-odds
    (|G2 - Q|^2 - |G1 - Q|^2) / s^2, 0.5 at the straight motion's middle point (4525 - 2725
    over 3600) and 1 at its end (3600 over 3600) instead of certainty."""
    p = L.position_probabilities(STRAIGHT, GOALS, TIMES, time_scaled=False)[:, 0]
    np.testing.assert_allclose(p, [0.5, 1 / (1 + np.exp(-0.5)), 1 / (1 + np.exp(-1))],
                               atol=1e-12)
    scaled = L.position_legibility(STRAIGHT, GOALS, 0, TIMES)
    unscaled = L.position_legibility(STRAIGHT, GOALS, 0, TIMES, time_scaled=False)
    assert unscaled < scaled
    directions = np.tile([1.0, 0.0, 0.0], (3, 1))
    row = L.legibility_metrics(STRAIGHT, directions, np.zeros((3, 2)), GOALS, 0, TIMES)
    assert row["position_legibility_unscaled"] == pytest.approx(unscaled)
    assert list(row) == LEGIBILITY_COLUMNS
