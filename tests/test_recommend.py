"""``ikbench recommend``: the intervals (Wilson, bootstrap, Kendall tau) against known values,
the verdict's rules on made-up tables (ties called ties, "best" only outside the intervals),
bad input through the CLI, and one short run whose files agree with their own verdict."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

import ikbench
from ikbench.cli import main
from ikbench.core.intervals import bootstrap_quantiles, kendall_tau, wilson
from ikbench.core.robot_packages import robots_folder
from ikbench.methods.registry import solver_status
from ikbench.studies.recommend import paired
from ikbench.studies.verdict import FAILED, MISSES, RECOMMENDED, WITHIN, decide, dominates

needs_erd = pytest.mark.skipif(robots_folder("example-robot-data") is None,
                               reason="needs example_robot_data")
ROBOT = "example-robot-data:ur5"
#: Fast to set up and to start in a fresh process (the short run's panel).
FAST = [m for m in ("eaik", "trac-ik", "ours-lm") if solver_status()[m].cls is not None]
MINUTES = 0.3


def test_wilson_matches_the_textbook_values():
    low, high = wilson(0, 10)
    assert low == 0.0 and high == pytest.approx(0.2775, abs=1e-4)
    low, high = wilson(10, 10)
    assert low == pytest.approx(0.7225, abs=1e-4) and high == 1.0
    low, high = wilson(50, 100)
    assert (low, high) == pytest.approx((0.4038, 0.5962), abs=1e-4)


def test_bootstrap_is_seeded_and_holds_the_estimate():
    x = np.random.default_rng(3).lognormal(size=400)
    a = bootstrap_quantiles(x, (0.5, 0.99), seed=7)
    assert np.array_equal(a, bootstrap_quantiles(x, (0.5, 0.99), seed=7))
    assert a[0, 0] == pytest.approx(np.median(x))
    assert np.all(a[:, 1] <= a[:, 0]) and np.all(a[:, 0] <= a[:, 2])
    assert a[1, 2] - a[1, 1] > a[0, 2] - a[0, 1]  # the tail is known less well


def test_kendall_tau_of_equal_and_reversed_rankings():
    assert kendall_tau(["a", "b", "c"], ["a", "b", "c"]) == pytest.approx(1.0)
    assert kendall_tau(["a", "b", "c"], ["c", "b", "a"]) == pytest.approx(-1.0)


def _row(method, success, s_lo, s_hi, p50, t_lo, t_hi, p99=1.0, budget=WITHIN):
    """A method's row of the per-method table, its one seed's statistics the pooled ones."""
    stats = {"success_pct": success, "success_low_pct": s_lo, "success_high_pct": s_hi,
             "p50_ms": p50, "p50_low_ms": t_lo, "p50_high_ms": t_hi, "p99_ms": p99,
             "p99_low_ms": p99 * 0.9, "p99_high_ms": p99 * 1.1, "budget": budget}
    return {"method": method, "library": "x", "deterministic": True, "status": "ok", **stats,
            **{f"{k}_seed1": v for k, v in stats.items()}}


def test_overlapping_intervals_are_called_a_tie_and_never_best():
    summary = pd.DataFrame([_row("a", 95, 93, 97, 1.0, 0.9, 1.1),
                            _row("b", 94, 92, 96, 1.05, 0.95, 1.15)])
    v = decide(summary, 5.0, "pose", "arm", 100, [1])
    assert v.recommended == "a" and v.tied == ["b"]
    assert "best" not in v.text and "tied with it" in v.text


def test_a_lead_outside_the_intervals_is_called_best():
    summary = pd.DataFrame([_row("a", 99, 98, 99.6, 1.0, 0.9, 1.1),
                            _row("b", 80, 77, 83, 0.5, 0.45, 0.55)])
    v = decide(summary, 5.0, "pose", "arm", 100, [1])
    assert v.recommended == "a" and not v.tied
    assert "a is the best on success" in v.text
    assert "b is 2.0x faster per call at the median but succeeds less often" in v.text


def test_as_reliable_and_faster_wins_and_a_method_over_budget_is_named():
    summary = pd.DataFrame([_row("slow", 99, 98, 99.6, 2.0, 1.9, 2.1),
                            _row("fast", 98.8, 97.8, 99.5, 0.2, 0.19, 0.21),
                            _row("sure", 100, 99.8, 100, 3.0, 2.9, 3.1, p99=40, budget=MISSES),
                            _row("broken", 0, 0, 3, np.nan, np.nan, np.nan, budget=FAILED)])
    v = decide(summary, 5.0, "pose", "arm", 100, [1])
    assert v.recommended == "fast"  # "slow" is dominated: as reliable, clearly slower
    assert "fast is as reliable as slow (intervals overlap) and 10.0x faster" in v.text
    assert "sure succeeds more often" in v.text and "misses the 5 ms budget" in v.text
    assert "the reasons are in the table): broken" in v.text
    assert v.table.loc[v.table["method"] == "fast", "role"].item() == RECOMMENDED
    # the ranking is the verdict's criterion: the recommended method is its first
    assert v.table["method"].iloc[0] == "fast" and v.table["rank_seed1"].iloc[0] == 1


def test_no_success_anywhere_gives_no_recommendation():
    summary = pd.DataFrame([_row("a", 0, 0, 3, 1.0, 0.9, 1.1), _row("b", 0, 0, 3, 2.0, 1.9, 2.1)])
    v = decide(summary, 5.0, "path", "arm", 10, [1])
    assert v.recommended is None and "no method succeeded on any of the paths" in v.text
    assert "use **" not in v.text


def test_no_method_within_the_budget_gives_no_recommendation():
    summary = pd.DataFrame([_row("a", 99, 98, 99.6, 2.0, 1.9, 2.1, p99=40, budget=MISSES)])
    v = decide(summary, 5.0, "pose", "arm", 100, [1])
    assert v.recommended is None and "no method meets the budget" in v.text


@needs_erd
@pytest.mark.parametrize("args, message", [
    (["--robot", "no_such_robot"], "no_such_robot"),
    (["--robot", ROBOT, "--end-frame", "not_a_link"], "not_a_link"),
    (["--robot", ROBOT, "--minutes", "0"], "--minutes"),
    (["--robot", ROBOT, "--budget-ms", "0"], "--budget-ms"),
    (["--robot", ROBOT, "--budget-ms", "inf"], "--budget-ms"),
    (["--robot", ROBOT, "--task", "paths"], "--task"),
    (["--robot", ROBOT, "--methods", "nope"], "nope"),
])
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, args, message):
    try:
        code = main(["recommend", "--output", str(tmp_path), "--quiet", *args])
    except SystemExit as exit_info:
        code = exit_info.code
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "recommend").exists()


def test_the_api_exports_recommend():
    assert ikbench.recommend.__module__ == "ikbench.studies.recommend"
    assert "recommend" in ikbench.__all__ and "Recommendation" in ikbench.__all__


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    """One short run through the CLI (a robot by package name, three fast methods)."""
    out = tmp_path_factory.mktemp("recommend")
    code = main(["recommend", "--robot", ROBOT, "--methods", ",".join(FAST), "--minutes",
                 str(MINUTES), "--budget-ms", "5", "--output", str(out), "--quiet"])
    assert code == 0
    return out / "recommend" / "ur5"


def _check_agreement(folder, budget_ms):
    """The recommended method is within the budget at p99 and no candidate dominates it on
    success and median time (intervals compared); "best" only where the success lead is
    outside the intervals; the candidates called tied are exactly those the paired
    comparison over the same targets finds tied on success and on time."""
    table = pd.read_csv(folder / "recommend.csv").fillna({"role": ""})
    verdict = (folder / "recommend.md").read_text().split("\n\n")[1]
    rec = table[table["role"] == RECOMMENDED]
    if rec.empty:
        assert "no method meets the budget" in verdict or "no method succeeded" in verdict
        return
    r = rec.iloc[0]
    assert f"use **{r['method']}**" in verdict
    assert r["p99_high_ms"] <= budget_ms or "straddles" in verdict
    others = table[(table["method"] != r["method"]) & (table["budget"] == r["budget"])]
    for _, o in others.iterrows():
        assert not dominates(o, r), (o["method"], r["method"])
    if re.search(r"\bbest\b", verdict):
        assert all(r["success_low_pct"] > o["success_high_pct"] for _, o in others.iterrows())
    rows = pd.read_csv(folder / "results.csv")
    for _, o in table.iterrows():  # a tie is a paired tie on both criteria, and only that
        if o["method"] == r["method"] or o["budget"] != r["budget"]:
            continue
        pair = paired(rows, r["method"], o["method"])
        tie = pair["success"] == pair["faster"] == "tie"
        assert (o["role"] == "tied") == tie, (o["method"], pair)


def _interval(row, name):
    unit = "pct" if name == "success" else "ms"
    return row[f"{name}_low_{unit}"], row[f"{name}_high_{unit}"]


@needs_erd
def test_the_files_are_written_and_the_command_reproduces_them(short_run):
    for name in ("recommend.md", "recommend.csv", "results.csv", "pareto.png", "CITATIONS.bib",
                 "run.json"):
        assert (short_run / name).is_file(), name
    md = (short_run / "recommend.md").read_text()
    assert "`ikbench recommend --robot example-robot-data:ur5" in md and "Machine:" in md
    assert "@inproceedings{beeson2015tracik" in (short_run / "CITATIONS.bib").read_text()
    table = pd.read_csv(short_run / "recommend.csv")
    assert set(table["method"]) == set(FAST)
    assert (table["targets"] >= 3 * 10).all()  # 3 seeds x at least the minimum


@needs_erd
def test_the_verdict_agrees_with_its_own_table(short_run):
    _check_agreement(short_run, 5.0)


@needs_erd
def test_the_run_records_its_plan_and_wall_time(short_run):
    """The sample is sized from --minutes (the plan and the wall time are recorded; whether a
    run fits its minutes is measured on a quiet machine, not asserted here: no timed
    assertion in a unit test)."""
    import json

    record = json.loads((short_run / "run.json").read_text())
    assert record["wall_s"] > 0 and record["plan"]["targets_per_seed"] >= 10


@needs_erd
def test_path_task_places_paths_and_judges_them_by_validity(tmp_path):
    """--task path: circles and lines placed from FK poses, solved by frame methods, the
    verdict agreeing with its table, within the minutes."""
    import json

    minutes = 0.3
    code = main(["recommend", "--robot", ROBOT, "--task", "path", "--methods",
                 "rtb-lm,sequential-ik", "--minutes", str(minutes), "--output", str(tmp_path),
                 "--quiet"])
    assert code == 0
    folder = tmp_path / "recommend" / "ur5"
    rows = pd.read_csv(folder / "results.csv")
    assert set(rows["method"]) == {"rtb-lm", "sequential-ik"}
    assert rows["path"].str.startswith(("circle", "line")).all()
    assert rows["seed"].nunique() == 3
    _check_agreement(folder, 1000.0)  # the default budget per path
    assert json.loads((folder / "run.json").read_text())["wall_s"] > 0
    from ikbench.studies.recommend import recheck

    verdict = (folder / "recommend.md").read_text().split("\n\n")[1]
    assert recheck(folder).decision.text == verdict  # paths paired by seed and path too


def test_placed_paths_start_at_a_reachable_pose_and_hold_its_orientation():
    from ikbench.core.robot import load_robot
    from ikbench.studies.recommend_path import SEGMENTS, place_paths

    robot = load_robot("panda")
    circle, line = place_paths(robot, 5, 2)
    for task in (circle, line):
        T = robot.fk_transform(task.hints.reference_pose[None])[0]
        assert np.allclose(task.goal.points_mm[0], T[:3, 3] * 1000.0)
        assert np.allclose(task.goal.rotations, T[:3, :3])
        assert len(task.goal.points_mm) == SEGMENTS + 1
    assert np.allclose(circle.goal.points_mm[0], circle.goal.points_mm[-1])  # closed
    steps = np.diff(line.goal.points_mm, axis=0)
    assert np.allclose(steps, steps[0])  # straight, evenly spaced


def test_a_path_method_that_cannot_set_up_is_a_row_with_its_reason(monkeypatch):
    """A library that fails in its own set-up (MuJoCo refusing a model, say) gives rows
    that say so; the run goes on (it stopped the whole run with a traceback)."""
    from ikbench.core.robot import load_robot
    from ikbench.studies import recommend_path

    def broken(method, robot, tasks, progress=None):
        raise ValueError("Error: inertia must satisfy A + B >= C")

    monkeypatch.setattr(recommend_path, "solve_tasks", broken)
    robot = load_robot("panda")
    tasks = recommend_path.place_paths(robot, 5, 2)
    rows = recommend_path.solve_paths(robot, "sequential-ik", tasks, 1)
    assert len(rows) == len(tasks)
    assert rows["failure"].str.startswith("cannot run (prepare: ValueError: Error: inertia").all()


@needs_erd
def test_the_verdict_rechecks_from_its_own_results_csv(short_run):
    """Issue 58: the success counts, their Wilson intervals (scipy's), the verdict and the
    paired comparison recomputed from results.csv alone agree with the folder's files."""
    _assert_rechecks(short_run)


@pytest.mark.parametrize("robot", ["ur5", "panda"])
def test_the_committed_recommendations_recheck_from_their_csv(robot):
    """Issue 58: the committed results/recommend/<robot>/ (a study of the reproduce plan)
    re-checks from its own results.csv: an auditor needs nothing but the repository."""
    from pathlib import Path

    _assert_rechecks(Path(__file__).parents[1] / "results" / "recommend" / robot)


def _assert_rechecks(short_run) -> None:
    import json

    from scipy.stats import binomtest

    from ikbench.studies.recommend import recheck

    again = recheck(short_run)
    table = pd.read_csv(short_run / "recommend.csv").set_index("method")
    record = json.loads((short_run / "run.json").read_text())
    for _, c in again.counts.iterrows():
        row = table.loc[c["method"]]
        assert (row["successes"], row["targets"]) == (c["successes"], c["targets"])
        ci = binomtest(int(c["successes"]), int(c["targets"])).proportion_ci(method="wilson")
        if row["budget"] == FAILED:  # cannot run: no rate, no interval
            assert np.isnan(row["success_low_pct"]) and np.isnan(row["success_pct"])
            continue
        assert row["success_low_pct"] == pytest.approx(100 * ci.low, abs=1e-3)
        assert row["success_high_pct"] == pytest.approx(100 * ci.high, abs=1e-3)
    assert again.decision.recommended == record["recommended"]
    assert again.decision.tied == record["tied"]
    verdict = (short_run / "recommend.md").read_text().split("\n\n")[1]
    assert again.decision.text == verdict
    assert again.paired == pytest.approx(record["paired"], nan_ok=True)


def _rows(method, success, time_s, seed=1):
    return pd.DataFrame({"method": method, "seed": seed, "target": range(len(success)),
                         "success": success, "failure": "", "time_s": time_s,
                         "joint_distance_deg": 1.0})


def test_paired_comparison_calls_a_tie_a_tie_and_a_difference_a_difference():
    from ikbench.studies.recommend import paired

    rng = np.random.default_rng(0)
    t = rng.lognormal(size=60) * 1e-3
    same = np.ones(60, bool)
    b_success = same.copy()
    b_success[:3] = False  # a ahead on 3 targets, b on 2: a tie
    a_success = same.copy()
    a_success[3:5] = False
    rows = pd.concat([_rows("a", a_success, t), _rows("b", b_success, t * rng.lognormal(
        0, 0.05, 60))])
    p = paired(rows, "a", "b")
    assert (p["first_only"], p["second_only"], p["targets"]) == (3, 2, 60)
    assert p["success"] == "tie" and p["sign_test_p"] == pytest.approx(1.0)
    assert p["faster"] == "tie" and p["time_ratio_low"] <= 1 <= p["time_ratio_high"]
    # a alone on 20 targets: p = 2 * 0.5 ** 20; b twice as slow on every target
    b_success = same.copy()
    b_success[:20] = False
    rows = pd.concat([_rows("a", same, t), _rows("b", b_success, 2 * t)])
    p = paired(rows, "a", "b")
    assert p["sign_test_p"] == pytest.approx(2 * 0.5 ** 20) and p["success"] == "a"
    assert p["time_ratio"] == pytest.approx(2.0) and p["faster"] == "a"


def test_a_method_that_cannot_run_shows_its_reason_not_a_rate():
    """Issue 64: eaik on a 7-joint arm is "cannot run: <reason>", never "0.0 [0.0, 11.4]"."""
    from types import SimpleNamespace

    from ikbench.render.recommend_report import table_lines
    from ikbench.studies.recommend import verdict_of

    t = np.full(30, 1e-3)
    why = "prepare: ValueError: EAIK cannot solve this 7-joint chain"
    broken = _rows("eaik", np.zeros(30, bool), np.nan).assign(failure=why)
    rows = pd.concat([_rows("a", np.ones(30, bool), t), _rows("b", np.ones(30, bool), 2 * t),
                      broken]).assign(recommend_task="pose", recommend_robot="arm",
                                      recommend_budget_ms=5.0)
    decision, pair = verdict_of(rows, {}, 30)
    row = decision.table.set_index("method").loc["eaik"]
    assert row["budget"] == FAILED and np.isnan(row["success_high_pct"])
    assert pair["first"] == decision.recommended and "eaik" not in (pair["first"],
                                                                    pair["second"])
    result = SimpleNamespace(table=decision.table.assign(first_call_s=np.nan,
                                                         first_call_note=""),
                             settings=SimpleNamespace(seeds=[1]))
    line = next(x for x in table_lines(result) if x.startswith("| eaik"))
    assert f"cannot run: {why}" in line and "0.0 [" not in line
    assert "Paired over the same 30 targets" in decision.text


def test_durations_print_three_significant_digits_in_their_unit():
    from ikbench.render.recommend_report import duration

    assert [duration(x) for x in (4.56e-5, 0.0123, 2.5, np.nan)] == [
        "45.6 us", "12.3 ms", "2.5 s", "-"]


class _Clock:
    """A fake perf_counter: time passes only when the fakes say so."""

    def __init__(self):
        self.now = 1000.0

    def perf_counter(self):
        return self.now

    def advance(self, seconds):
        self.now += seconds


@pytest.mark.parametrize("minutes", [2.0, 5.0, 1.0])
def test_a_cold_compile_counts_in_the_minutes(monkeypatch, minutes):
    """Issue 64: a method whose first set-up compiles for 60 s (ours-lm on a cold numba
    cache) has that time counted: the pilot's cost per target is its calls' (not 0), the
    sample fits what is left, and the run ends within --minutes plus its margin; when the
    smallest sample cannot fit (1 minute), the plan says by how much it passes. A fake clock,
    no timed assertion."""
    from types import SimpleNamespace

    from ikbench.studies import recommend as rec

    clock = _Clock()
    monkeypatch.setattr(rec, "time", clock)
    cost_s, compile_s, setup_s = {"compiles": 0.2, "quick": 5e-4}, {"compiles": 60.0}, 0.05
    prepared: set[str] = set()

    class Solver:
        def __init__(self, name):
            self.name = name

        def prepare(self):
            clock.advance(setup_s + (0 if self.name in prepared else
                                     compile_s.get(self.name, 0.0)))
            prepared.add(self.name)

    status = {n: SimpleNamespace(cls=lambda *a, n=n: Solver(n)) for n in cost_s}
    monkeypatch.setattr(rec, "solver_status", lambda: status)

    def run_ik(robot, ik, names, progress=False):
        (name,) = names
        Solver(name).prepare()
        clock.advance(ik.count * cost_s[name])
        table = pd.DataFrame({"method": name, "target": range(ik.count), "success": True,
                              "failure": "", "time_s": 0.8 * cost_s[name],
                              "joint_distance_deg": 1.0})
        return SimpleNamespace(table=table, methods={name: {"library": "x",
                                                            "deterministic": True}})

    def first_call(*args, timeout_s, **kwargs):
        clock.advance(min(3.0, timeout_s))
        return {"first_call_s": 3.0}

    monkeypatch.setattr(rec, "run_ik", run_ik)
    monkeypatch.setattr(rec, "first_call", first_call)
    monkeypatch.setattr(rec, "sample_targets", lambda robot, ik: SimpleNamespace(
        T_target=[None], initials=lambda i, k: None))
    spec = rec.RecommendSpec(SimpleNamespace(name="arm"), rec.RecommendSettings(
        minutes=minutes), tuple(cost_s), progress=False)
    start = clock.now
    result = rec.run(spec)
    plan = result.plan
    assert plan.compile_s["compiles"] == pytest.approx(60.0)
    for name, c in cost_s.items():  # the pilot's set-up share aside
        assert c - 1e-9 <= plan.cost_s[name] <= c + setup_s / rec.PILOT_TARGETS + 1e-9
    spent = clock.now - start + rec.WRITE_RESERVE_S  # the writing is given its reserve
    assert plan.margin_s == rec.margin_s(minutes)
    assert spent <= minutes * 60 + plan.margin_s + plan.overrun_s + 1e-6
    if minutes >= 2:
        assert plan.overrun_s == 0 and plan.targets_per_seed > rec.MIN_TARGETS
    else:
        assert plan.targets_per_seed == rec.MIN_TARGETS and plan.overrun_s > 0
